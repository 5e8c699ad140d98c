"""`bbzide ide [X.bzz]`: open the browser IDE (also what plain `bbzide` does).

    bbzide ide [X.bzz] [--world W] [--robots N] [--seed K] [--host H] [--port P] [--token T]
               [--no-browser]
    bbzide ide S.toml [--seed K] ...   a scenario file: its world, options, robots and script
    bbzide ide ... --scenarios DIR     links /?scenario=NAME may open DIR/NAME.toml as well as
                                       the lessons and examples (bbzide.ui.scenario_links)
    bbzide replay X.rrd [--host H] [--port P] [--token T] [--no-browser]

Without a script the IDE opens the world's example. A script with a scenario file of its
own beside it (`examples/kilobot/aggregation.bzz` and `aggregation.toml`) opens in that
scenario's world, options and robots, unless `--world` or `--robots` is given. The example
is copied once to a scratch file in the user's data directory
(`~/.local/share/bbzide/scratch/`), because the editor saves every change and the shipped
example must stay as it is. The server listens on 127.0.0.1 unless
`--host` says otherwise, prints its URL and, unless `--no-browser`, opens it. Everything that
can be wrong with the arguments (address, seed, a script that is a folder or not UTF-8) is an
`IdeError` raised before a server starts.

A scenario file (bbzide/worlds/scenario.py) pins the world, its options, the robots (count,
positions, labels) and the script the editor opens; the IDE edits one script, so a scenario
whose groups run different scripts is refused (run it with `bbzide run`). Changing the world or
the robot count in the IDE leaves the scenario behind (the world's defaults apply again).
"""

from __future__ import annotations

import argparse
import os
import socket
import time
import webbrowser
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bbzide.diagnostics import UserError
from bbzide.ui.access import TOKEN_ENV, TokenError, choose_token
from bbzide.ui.scenario_links import scratch_copy
from bbzide.worlds.registry import DEFAULT_SEED

if TYPE_CHECKING:  # imported lazily at run time: the CLI starts without viser
    from bbzide.ui.app import IdeApp
    from bbzide.ui.replay_app import ReplayApp

DEFAULT_PORT = 8080


#: Files the compiler writes: the IDE never opens them as the text it saves.
BYTECODE_SUFFIXES = (".bo", ".bbo", ".bdb")


class IdeError(UserError):
    """Bad `bbzide ide` arguments (missing script, unknown world, bad robot count)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    ide = subparsers.add_parser("ide", help="the browser IDE: editor, simulator, memory inspector")
    ide.add_argument("script", nargs="?", type=Path, help="Buzz script to edit and run (.bzz)")
    ide.add_argument("--world", help="world to open (default: the Kilobot table)")
    ide.add_argument("--robots", type=int, help="number of robots (default: the world's)")
    ide.add_argument("--seed", type=int, default=None,
                     help=f"world seed (default: the scenario's, else {DEFAULT_SEED} "
                          "as bbzide run --world)")
    ide.add_argument(
        "--speed",
        type=float,
        default=30.0,
        help="control steps per second, 0 = as fast as possible (default 30)",
    )
    ide.add_argument("--threads", type=int, default=1, metavar="N",
                     help="split each step of a large swarm over N threads (default 1; the "
                          "same run, sooner on a machine with cores to spare)")
    ide.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    ide.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default 8080)")
    add_token_argument(ide)
    ide.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    ide.add_argument("--paused", action="store_true", help="start paused")
    ide.add_argument("--scenarios", type=Path, metavar="DIR",
                     help="a folder of scenarios that links (/?scenario=NAME) may open, "
                          "besides the lessons and examples")
    ide.set_defaults(
        handler=run_ide,
        script=None,
        world=None,
        robots=None,
        seed=None,
        speed=30.0,
        threads=1,
        host="127.0.0.1",
        port=DEFAULT_PORT,
        token=None,
        no_browser=False,
        paused=False,
        scenarios=None,
    )
    register_replay(subparsers)


def register_replay(subparsers: argparse._SubParsersAction) -> None:
    replay = subparsers.add_parser(
        "replay", help="open a recorded mission (.rrd) in the IDE: timeline, scene, inspector"
    )
    replay.add_argument("recording", type=Path, help="a recording made with --record")
    replay.add_argument("--host", default="127.0.0.1", help="address to listen on")
    replay.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default 8080)")
    add_token_argument(replay)
    replay.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    replay.set_defaults(handler=run_replay)


def add_token_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--token",
        help=f"secret the browser must present (default: ${TOKEN_ENV}, else a new random one "
        "per launch; it is part of the printed address)",
    )


def launch_token(args: argparse.Namespace) -> str:
    """`--token`, $BBZIDE_TOKEN or a fresh one; a bad given token is the user's error."""
    try:
        return choose_token(getattr(args, "token", None))
    except TokenError as error:
        raise IdeError(str(error)) from None


def check_listen_address(host: str, port: int) -> None:
    """Refuse an address the server cannot listen on, before it starts.

    viser's server thread would otherwise die with a traceback on a port outside 0..65535, or
    keep trying further ports on an address that is not this machine's, without a word.
    """
    if not 0 <= port <= 65535:  # TCP ports are 16-bit
        raise IdeError(f"--port must be 0..65535, got {port}")
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind) as probe:
            probe.bind(address)  # port 0: any free port; only the address is tested
    except OSError as error:
        raise IdeError(f"cannot listen on {host}: {error.strerror or error}") from None


def run_replay(args: argparse.Namespace) -> int:
    from bbzide.recording.reader import read_recording
    from bbzide.ui.replay_app import ReplayApp
    from bbzide.ui.replay_session import ReplaySession

    check_listen_address(args.host, args.port)
    token = launch_token(args)

    recording = read_recording(args.recording, isolated=True)  # a damaged file may crash Rerun
    app = ReplayApp(ReplaySession(recording), host=args.host, port=args.port,
                    token=token).start()
    cut = " (cut off: shown up to its last flushed step)" if recording.truncated else ""
    print(
        f"bbzide replay: {app.url}  ({args.recording}: steps {recording.first_step}.."
        f"{recording.last_step}{cut}; Ctrl-C to stop)",
        flush=True,
    )
    return serve_until_interrupted(app, open_browser=not args.no_browser)


def ide_scenario(path: Path, args: argparse.Namespace, script: Path | None = None) -> Any:
    """The scenario at `path` for the IDE: options it pins refused, --seed applied, and every
    robot group's script replaced by `script` when given (a lesson's saved work)."""
    from bbzide.worlds.scenario import load_scenario

    for option, value in (("--world", args.world), ("--robots", args.robots)):
        if value is not None:
            raise IdeError(f"{option} cannot be combined with a scenario file: edit {path}")
    scenario = load_scenario(path)
    scripts = scenario.scripts()
    if len(scripts) != 1:
        raise IdeError(f"{path}: the IDE edits one script and this scenario runs "
                       f"{len(scripts) or 'no'} script(s): run it with bbzide run {path}")
    if script is not None:
        scenario = scenario.with_script(script)
    if args.seed is not None:
        scenario = scenario.with_seed(args.seed)
    return scenario


def example_set_up(script: Path, args: argparse.Namespace) -> Path | None:
    """`X.toml` beside `X.bzz` when it runs `X.bzz` alone: the example's own world, options and
    robots (aggregation needs its scattered layout to show anything). Not when the command
    line chose the world or the robot count."""
    if args.world is not None or args.robots is not None or script.suffix != ".bzz":
        return None
    beside = script.with_suffix(".toml")
    if not beside.is_file():
        return None
    from bbzide.worlds.scenario import load_scenario

    try:
        scripts = load_scenario(beside).scripts()
    except UserError:
        return None  # a broken set-up file: the script opens in the world's defaults
    return beside if [p.resolve() for p in scripts] == [script.resolve()] else None


def run_ide(args: argparse.Namespace) -> int:
    scenario = None
    banner = ""
    if args.script is not None and args.script.suffix == ".bzz" and args.script.is_file():
        set_up = example_set_up(args.script, args)
        if set_up is not None:
            banner = f"bbzide IDE: the set-up of {set_up} (world, options, robots)"
            args.script = set_up
    if args.script is not None and args.script.suffix == ".toml":
        check_listen_address(args.host, args.port)
        scenario = ide_scenario(args.script, args)
    return open_ide(args, scenario, banner)


def open_ide(args: argparse.Namespace, scenario: Any = None, banner: str = "") -> int:
    """Start the IDE on `args.script` (or `scenario`'s script) and serve until Ctrl-C."""
    from bbzide.ui.app import IdeApp
    from bbzide.ui.run_controller import RunSettings
    from bbzide.ui.world_adapter import WorldsBackend

    check_listen_address(args.host, args.port)
    token = launch_token(args)
    seed = args.seed if args.seed is not None else DEFAULT_SEED
    if scenario is not None:
        args.script, args.world, args.robots = scenario.scripts()[0], scenario.world, \
            scenario.robots
        seed = scenario.seed
    if seed < 0:  # numpy's seed sequences take non-negative integers only
        raise IdeError(f"--seed must be >= 0, got {seed}")
    if args.script is not None:
        resolve_script(args.script, None)  # a bad path fails before any room is loaded
    backend = WorldsBackend()
    world = args.world or backend.default_world()
    if world not in backend.world_names():
        raise IdeError(
            f"unknown world {world!r}; choose one of: {', '.join(backend.world_names())}"
        )
    robots = args.robots if args.robots is not None else backend.default_robots(world)
    from bbzide.ui.controls import MAX_ROBOTS

    if not 1 <= robots <= MAX_ROBOTS:
        raise IdeError(f"--robots must be 1..{MAX_ROBOTS} in the IDE, got {robots} "
                       "(larger swarms: bbzide run --world)")
    if args.threads < 1:
        raise IdeError(f"--threads must be >= 1, got {args.threads}")
    from bbzide.vm import swarm_batch

    swarm_batch.set_threads(args.threads)
    script = resolve_script(args.script, backend.example_path(world))
    folder = getattr(args, "scenarios", None)
    if folder is not None and not folder.is_dir():
        raise IdeError(f"--scenarios {folder}: no such folder")
    settings = RunSettings(
        world=world, robots=robots, seed=seed, steps_per_second=max(0.0, args.speed),
        scenario=scenario,
    )
    app = IdeApp(script, backend, settings, host=args.host, port=args.port, token=token,
                 scenario_folder=folder)
    app.start(run=not args.paused)
    if banner:
        print(banner, flush=True)
    print(f"bbzide IDE: {app.url}  (editing {script}; Ctrl-C to stop)", flush=True)
    return serve_until_interrupted(app, open_browser=not args.no_browser)


def serve_until_interrupted(app: IdeApp | ReplayApp, open_browser: bool) -> int:
    """Open a browser tab on the started app (unless told not to), serve until Ctrl-C, stop."""
    if open_browser:
        webbrowser.open(app.url)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    # Ctrl-C stops the app once its run thread has ended its current work. On a fresh clone
    # whose kernels `make setup` has not compiled yet that work can be numba compiling one for
    # the first time (a minute or more on a loaded machine): a compile cannot be interrupted,
    # but the process can exit once the thread returns, cleanly and with the kernel cached.
    # A second Ctrl-C quits without waiting (a Buzz step that never ends), with no traceback.
    try:
        app.stop(wait_for_run=True)
    except KeyboardInterrupt:
        pass
    return 0


def _check_utf8(script: Path) -> None:
    """The editor reads and saves UTF-8: refuse other bytes, naming where they are."""
    data = script.read_bytes()
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as error:
        before = data[: error.start]
        line = before.count(b"\n") + 1
        col = len(before) - (before.rfind(b"\n") + 1)
        raise IdeError(f"{script}:{line}:{col}: byte 0x{data[error.start]:02x} is not UTF-8; "
                       "the IDE edits and saves UTF-8 text: convert the file (e.g. "
                       f"iconv -f latin1 -t utf-8) and open it again") from None


def resolve_script(script: Path | None, example: Path | None) -> Path:
    """The file to edit: the user's script, or a scratch copy of the world's example."""
    if script is not None:
        if script.is_dir():
            raise IdeError(f"{script} is a folder, not a Buzz script")
        if not script.is_file():
            raise IdeError(f"no such Buzz script: {script}")
        if script.suffix == ".rrd":
            raise IdeError(f"{script} is a recording: open it with bbzide replay {script}")
        if script.suffix in BYTECODE_SUFFIXES:  # the editor would save its edits over it
            raise IdeError(f"{script} is bytecode, not Buzz source: open the .bzz it was "
                           "compiled from")
        _check_utf8(script)
        if not os.access(script, os.W_OK):
            raise IdeError(f"{script} is read-only: the IDE saves your edits to it")
        return script.resolve()
    if example is None or not example.is_file():
        raise IdeError("this world has no example script: give one, e.g. `bbzide ide my.bzz`")
    return scratch_copy(example)
