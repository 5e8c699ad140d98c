"""``bbzide run X.bzz|X.bbo --platform P --steps N ...``: one robot, headless, on the VM model.

The options are the corpus harness's (``--robot --steps --seed --loop --reg NAME=KIND
--inject FILE``) plus ``--platform`` (a profile), ``--dump`` (print the ``#BBZDUMP 1`` text
instead of the script's log) and ``--budget`` (instructions per entry into Buzz code), so
every command of ``bbz/*.cmd`` can be replayed with ``bbzide run ... --dump`` and diffed
with the reference by ``bbzconf.py diff``. Without ``--reg`` the script gets ``log`` (the
harness's ``print`` kind). A ``.bzz`` is compiled with the BittyBuzz string table extended
by the registered names, exactly as the corpus's ``.bst`` files are built.

Output: the arguments of every ``log`` call, one line each (the ``out`` lines without
``out``); a VM error becomes a ``UserError`` at the failing instruction's source position.
``bbzide/cli.py`` defines ``run`` (shared with the worlds) and calls ``add_run_arguments`` and
``run_single_robot``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bbzide.compiler.opcodes import Op
from bbzide.diagnostics import UserError
from bbzide.vm.harness_options import Registration, group_registrations
from bbzide.vm.profiles import PROFILES
from bbzide.vm.robot import DEFAULT_BUDGET

if TYPE_CHECKING:
    from bbzide.vm.injections import Injection

#: control steps when --steps is not given
DEFAULT_STEPS = 10
#: the largest robot id: BittyBuzz keeps a robot id in 16 bits (`bbzrobot_id_t`, the u16
#: sender id of every message)
MAX_ROBOT_ID = 0xFFFF


#: What a one-robot run registers when no --reg is given: `log` (the harness's `print`) and the
#: platform firmware's host functions, so a world's example runs here too: Kilobot `led`,
#: `set_motor`, `delay` are shown as calls (`led(1)`), `abs` computes (the Kilobot `.bst`).
DEFAULT_REGISTRATIONS: dict[str, tuple[str, ...]] = {
    "kilobot": ("log=print", "led=trace", "set_motor=trace", "delay=trace", "abs=abs"),
}
#: A heap whose peak reaches this share of the profile's heap gets a warning: the next
#: allocation burst (a table, a message) may stop the robot with MEM.
HEAP_WARNING_SHARE = 0.85


def register(subparsers: argparse._SubParsersAction) -> None:
    """No subcommand of its own: ``run`` is registered by ``bbzide/cli.py``."""


def _has_option(parser: argparse.ArgumentParser, option: str) -> bool:
    return option in parser._option_string_actions


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    if not any(action.dest == "script" for action in parser._actions):
        parser.add_argument("script", help="the .bzz (or .bbo) file")
    group = parser.add_argument_group("one robot on the VM model (without --world)")
    group.add_argument("--platform", default="kilobot", choices=sorted(PROFILES),
                       help="VM profile (default kilobot)")
    if not _has_option(parser, "--steps"):
        group.add_argument("--steps", type=int, default=None,
                           help=f"control steps (default {DEFAULT_STEPS})")
    if not _has_option(parser, "--seed"):
        group.add_argument("--seed", type=int, default=0, help="seed of the rand host kind")
    group.add_argument("--robot", type=int, default=0, help="robot id (default 0)")
    group.add_argument("--loop", choices=("pop", "robot"), default="pop",
                       help="pop the value step() returns (default) or keep it, like the "
                            "Kilobot firmware (the stack grows)")
    group.add_argument("--reg", action="append", default=[], metavar="NAME=KIND",
                       help="host closure: print|log|ret0|ret0/N|retnil|rand|min|trace|abs|"
                            "reti:V (default: log=print and, on kilobot, the firmware's "
                            "led/set_motor/delay traced and abs)")
    group.add_argument("--inject", type=Path, help="message injection file (corpus format)")
    group.add_argument("--dump", action="store_true", help="print #BBZDUMP 1 dumps")
    group.add_argument("--budget", type=int, default=DEFAULT_BUDGET,
                       help="instructions per call into Buzz code before the robot fails "
                            f"with BUDGET (default {DEFAULT_BUDGET}; 0 = no limit, as the "
                            "reference harness)")
    if not _has_option(parser, "-I"):
        group.add_argument("-I", dest="include", action="append", default=[],
                           help="include folder")


def host_names(registrations: list[Registration]) -> list[str]:
    """Names the registrations add to the string table (``tbl`` and each field)."""
    names: list[str] = []
    for reg in registrations:
        names.append(reg.name)
        names.extend(f for f, _ in reg.fields)
    return names


def load(script: Path, registrations: list[Registration], include: list[str]):  # noqa: ANN201
    """A BittyBuzzProgram from a ``.bzz`` (compiled) or a ``.bbo`` (+ ``.bo``/``.bdb``)."""
    from bbzide.compiler import (
        base_strings_mismatch,
        bittybuzz_string_table,
        compile_file,
        load_program,
    )

    if not script.exists():
        raise UserError(f"{script}: no such file")
    if script.suffix == ".bbo":
        bo, bdb = script.with_suffix(".bo"), script.with_suffix(".bdb")
        program = load_program(script, bo=bo if bo.exists() else None,
                               bdb=bdb if bdb.exists() else None)
        why = base_strings_mismatch(program.strings)
        if why is not None:
            raise UserError(f"{script}: {why}: compile it with --platform, or run the .bzz")
        return program
    table = bittybuzz_string_table(host_names(registrations))
    return compile_file(script, include_path=include, string_table=table).to_bbo()


def run_single_robot(args: argparse.Namespace) -> int:
    from bbzide.vm.harness import run_harness

    script = Path(args.script)
    steps = DEFAULT_STEPS if args.steps is None else int(args.steps)
    if steps < 0:
        raise UserError("--steps must be ≥ 0")
    if args.budget is not None and args.budget < 0:
        raise UserError(f"--budget must be ≥ 0 (0 = no limit), got {args.budget}")
    if not 0 <= args.robot <= MAX_ROBOT_ID:
        raise UserError(f"--robot must be a robot id in 0..{MAX_ROBOT_ID} (BittyBuzz ids are "
                        f"16-bit), got {args.robot}")
    registrations = group_registrations(
        args.reg or list(DEFAULT_REGISTRATIONS.get(args.platform, ("log=print",))))
    program = load(script, registrations, list(getattr(args, "include", []) or []))
    from bbzide.compiler.call_sites import lint_globals

    names = host_names(registrations)
    for where, message in lint_globals(program, names, f"this run (--reg {', '.join(names)})"):
        print(f"{where}: warning: {message}", file=sys.stderr)
    injections = _injections(Path(args.inject)) if args.inject else []
    run = run_harness(program, PROFILES[args.platform], robot_id=args.robot, steps=steps,
                      seed=int(args.seed or 0), loop=args.loop, registrations=registrations,
                      injections=injections, bbo_name=script.with_suffix(".bbo").name,
                      bo_name=script.with_suffix(".bo").name,
                      instruction_budget=args.budget or None)
    out = sys.stdout
    if args.dump:
        out.write("\n".join(run.lines) + "\n")
    else:
        for line in run.lines:
            if line == "out" or line.startswith("out "):
                out.write(line[4:] + "\n")
    out.flush()
    if not args.dump:
        print(_run_summary(run.robot, PROFILES[args.platform], steps), file=sys.stderr)
    failure = run.robot.failure
    if failure is not None:
        from bbzide.compiler.call_sites import explain_failure

        explained = explain_failure(program, failure.reason, failure.pc, names,
                                    f"this run (--reg {', '.join(names)})")
        if explained is not None:
            location, message = explained
            raise UserError(f"robot {args.robot} stopped: {failure.reason} at pc {failure.pc}: "
                            f"{message}", location, program.source_line(location),
                            hint=_REG_HINT)
        raise UserError(f"robot {args.robot} stopped: {failure.reason} at pc {failure.pc}: "
                        f"{failure.message}", failure.location,
                        hint=_call_hint(run.robot, failure))
    return 0


#: What to do about a call of a host function that a one-robot run does not register.
_REG_HINT = ("a host function such as led() exists only where it is registered: "
             "--reg NAME=ACTION here, or run the script in its world "
             "(--world kilobot|crazyflie|m300)")


def _run_summary(robot: Any, profile: Any, steps: int) -> str:
    """After a run: steps, heap peak against the profile's heap, and a warning near the limit."""
    peak, size = int(robot.vm.heap.peak_used), int(profile.heap_size)
    text = (f"robot {robot.robot_id}: {steps} step(s) on the {profile.name} profile; heap peak "
            f"{peak} of {size} B ({100 * peak / size:.0f} %)")
    if peak >= HEAP_WARNING_SHARE * size:
        text += (f"\nwarning: the heap peaked at {100 * peak / size:.0f} % of the {profile.name} "
                 "heap: a larger table or more messages may stop the robot with MEM")
    return text


def _injections(path: Path) -> list[Injection]:
    """The injection file's messages, or a UserError naming what is wrong with the file."""
    from bbzide.vm.injections import parse_injection_file

    if path.is_dir():
        raise UserError(f"--inject {path} is a folder, not an injection file")
    try:
        return parse_injection_file(path)
    except FileNotFoundError:
        raise UserError(f"--inject {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"--inject {path}: cannot read it ({exc})") from None


def _call_hint(robot: Any, failure: Any) -> str | None:
    """A TYPE error on a ``callc`` called something that is not a function: most often a
    host function this run does not register (a one-robot run registers only what `--reg`
    names; a world's `led`, `goTo`... exist only with `--world`). bzzparse places a call's
    debug position at the token after it, often the next line's `}`, so say so."""
    bcode = robot.vm.bcode
    if failure.reason != "TYPE" or not 0 <= failure.pc < len(bcode) \
            or bcode[failure.pc] != Op.CALLC:
        return None
    return ("the value called is not a function (the call can be on the line before "
            f"the one shown). {_REG_HINT[0].upper()}{_REG_HINT[1:]}.")
