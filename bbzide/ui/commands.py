"""`bbzide ide [X.bzz]`: open the browser IDE (also what plain `bbzide` does).

    bbzide ide [X.bzz] [--world W] [--robots N] [--seed K] [--host H] [--port P] [--no-browser]
    bbzide replay X.rrd [--host H] [--port P] [--no-browser]

Without a script the IDE opens the world's example. The example is copied once to a scratch
file in the user's data directory (`~/.local/share/bbzide/scratch/`), because the editor saves
every change and the shipped example must stay as it is. The server listens on 127.0.0.1 unless
`--host` says otherwise, prints its URL and, unless `--no-browser`, opens it.
"""

from __future__ import annotations

import argparse
import os
import shutil
import time
import webbrowser
from pathlib import Path
from typing import TYPE_CHECKING

from bbzide.diagnostics import UserError

if TYPE_CHECKING:  # imported lazily at run time: the CLI starts without viser
    from bbzide.ui.app import IdeApp
    from bbzide.ui.replay_app import ReplayApp

DEFAULT_PORT = 8080


class IdeError(UserError):
    """Bad `bbzide ide` arguments (missing script, unknown world, bad robot count)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    ide = subparsers.add_parser("ide", help="the browser IDE: editor, simulator, memory inspector")
    ide.add_argument("script", nargs="?", type=Path, help="Buzz script to edit and run (.bzz)")
    ide.add_argument("--world", help="world to open (default: the Kilobot table)")
    ide.add_argument("--robots", type=int, help="number of robots (default: the world's)")
    ide.add_argument("--seed", type=int, default=1, help="world seed (default 1)")
    ide.add_argument(
        "--speed",
        type=float,
        default=30.0,
        help="control steps per second, 0 = as fast as possible (default 30)",
    )
    ide.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    ide.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default 8080)")
    ide.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    ide.add_argument("--paused", action="store_true", help="start paused")
    ide.set_defaults(
        handler=run_ide,
        script=None,
        world=None,
        robots=None,
        seed=1,
        speed=30.0,
        host="127.0.0.1",
        port=DEFAULT_PORT,
        no_browser=False,
        paused=False,
    )
    register_replay(subparsers)


def register_replay(subparsers: argparse._SubParsersAction) -> None:
    replay = subparsers.add_parser(
        "replay", help="open a recorded mission (.rrd) in the IDE: timeline, scene, inspector"
    )
    replay.add_argument("recording", type=Path, help="a recording made with --record")
    replay.add_argument("--host", default="127.0.0.1", help="address to listen on")
    replay.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default 8080)")
    replay.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    replay.set_defaults(handler=run_replay)


def run_replay(args: argparse.Namespace) -> int:
    from bbzide.recording.reader import read_recording
    from bbzide.ui.replay_app import ReplayApp
    from bbzide.ui.replay_session import ReplaySession

    recording = read_recording(args.recording)
    app = ReplayApp(ReplaySession(recording), host=args.host, port=args.port).start()
    cut = " (cut off: shown up to its last flushed step)" if recording.truncated else ""
    print(
        f"bbzide replay: {app.url}  ({args.recording}: steps {recording.first_step}.."
        f"{recording.last_step}{cut}; Ctrl-C to stop)",
        flush=True,
    )
    return serve_until_interrupted(app, open_browser=not args.no_browser)


def run_ide(args: argparse.Namespace) -> int:
    from bbzide.ui.app import IdeApp
    from bbzide.ui.run_controller import RunSettings
    from bbzide.ui.world_adapter import WorldsBackend

    if args.script is not None:
        resolve_script(args.script, None)  # a bad path fails before any room is loaded
    backend = WorldsBackend()
    world = args.world or backend.default_world()
    if world not in backend.world_names():
        raise IdeError(
            f"unknown world {world!r}; choose one of: {', '.join(backend.world_names())}"
        )
    robots = args.robots if args.robots is not None else backend.default_robots(world)
    if robots < 1:
        raise IdeError("--robots must be at least 1")
    script = resolve_script(args.script, backend.example_path(world))
    settings = RunSettings(
        world=world, robots=robots, seed=args.seed, steps_per_second=max(0.0, args.speed)
    )
    app = IdeApp(script, backend, settings, host=args.host, port=args.port)
    app.start(run=not args.paused)
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
    finally:
        app.stop()
    return 0


def resolve_script(script: Path | None, example: Path | None) -> Path:
    """The file to edit: the user's script, or a scratch copy of the world's example."""
    if script is not None:
        if not script.is_file():
            raise IdeError(f"no such Buzz script: {script}")
        if not os.access(script, os.W_OK):
            raise IdeError(f"{script} is read-only: the IDE saves your edits to it")
        return script.resolve()
    if example is None or not example.is_file():
        raise IdeError("this world has no example script: give one, e.g. `bbzide ide my.bzz`")
    data_home = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    scratch = data_home / "bbzide" / "scratch" / example.name
    if not scratch.exists():
        scratch.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(example, scratch)
    return scratch
