"""`bbzide lesson`: list the lessons, open one in the IDE, check or reset a student's work.

    bbzide lesson                    the lessons: number, world, title, where your work is
    bbzide lesson N                  print lesson N's text, open the IDE on your work copy in the
                                     lesson's scenario (created from the starter the first time)
    bbzide lesson N --check [FILE]   run the lesson's automatic check headless on FILE (default:
                                     your work copy): PASS/FAIL and what to look at; exit 0 / 1
    bbzide lesson N --reset          put the starter back in place of your work copy

The lessons and their checks live in the lessons room (bbzide/lessons/); this module is in the
UI room only because opening a lesson starts the IDE (`commands.open_ide`). A student's work is
kept where `bbzide.lessons.catalog.lessons_home()` says (`$BBZIDE_LESSONS_HOME`, else the
user's data directory).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from bbzide.ui.commands import (
    DEFAULT_PORT,
    IdeError,
    add_token_argument,
    ide_scenario,
    open_ide,
)

if TYPE_CHECKING:  # the lessons room is imported when a lesson command runs
    from bbzide.lessons.catalog import Lesson


def register(subparsers: argparse._SubParsersAction) -> None:
    lesson = subparsers.add_parser(
        "lesson", help="the teaching track: list the lessons, open one, check your work")
    lesson.add_argument("number", nargs="?", type=int, help="the lesson to open")
    what = lesson.add_mutually_exclusive_group()
    what.add_argument("--check", nargs="?", const="", metavar="FILE",
                      help="run the lesson's check on FILE (default: your work copy)")
    what.add_argument("--reset", action="store_true",
                      help="restore the starter script in place of your work copy")
    lesson.add_argument("--host", default="127.0.0.1", help="address to listen on")
    lesson.add_argument("--port", type=int, default=DEFAULT_PORT, help="port (default 8080)")
    lesson.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    lesson.add_argument("--paused", action="store_true", help="start paused")
    add_token_argument(lesson)
    lesson.set_defaults(handler=run_lesson)


def run_lesson(args: argparse.Namespace) -> int:
    from bbzide.lessons import catalog

    if args.number is None:
        if args.check is not None or args.reset:
            raise IdeError("give the lesson's number, e.g. bbzide lesson 1 --check")
        print(lesson_list())
        return 0
    chosen = catalog.lesson(args.number)
    if args.reset:
        path = catalog.reset_work(chosen)
        print(f"lesson {chosen.number}: {path} is the starter script again")
        return 0
    if args.check is not None:
        return check_lesson(chosen, Path(args.check) if args.check else None)
    work = catalog.work_file(chosen)
    ide_args = argparse.Namespace(script=None, world=None, robots=None, seed=None, speed=30.0,
                                  threads=1, host=args.host, port=args.port,
                                  no_browser=args.no_browser,
                                  paused=args.paused, token=args.token)
    scenario = ide_scenario(chosen.scenario_path, ide_args, script=work)
    print(chosen.text.rstrip())
    banner = (f"\nlesson {chosen.number}: your work is {work}\n"
              f"  check it:  bbzide lesson {chosen.number} --check\n"
              f"  start over: bbzide lesson {chosen.number} --reset\n")
    return open_ide(ide_args, scenario, banner=banner)


def lesson_list() -> str:
    from bbzide.lessons import catalog

    lines = ["Lessons (bbzide lesson N opens one):"]
    for lesson in catalog.lessons():
        started = " (started)" if catalog.work_path(lesson).exists() else ""
        lines.append(f"  {lesson.number:2}  {lesson.world:10} {lesson.title}{started}")
    lines.append(f"Your work is kept in {catalog.lessons_home()} "
                 f"(set {catalog.HOME_VARIABLE} to move it).")
    return "\n".join(lines)


def check_lesson(chosen: Lesson, script: Path | None) -> int:
    from bbzide.lessons import catalog
    from bbzide.lessons.checks import run_check

    if script is None:
        script = catalog.work_path(chosen)
        if not script.exists():
            raise IdeError(f"you have not started lesson {chosen.number} yet: open it with "
                           f"bbzide lesson {chosen.number}, or give a file to --check")
    elif not script.is_file():
        raise IdeError(f"no such Buzz script: {script}")
    verdict = run_check(chosen, script)
    print(f"lesson {chosen.number} ({chosen.title}), checking {script}")
    print(verdict.render())
    return 0 if verdict.passed else 1
