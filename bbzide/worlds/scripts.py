"""A world's scripts: compile a `.bzz` against the world's string table, or load a `.bbo`.

The one place where a script becomes a `BittyBuzzProgram` for a world: `bbzide run`, scenario
files, recordings, experiments and the IDE all load their scripts here, so a `.bbo` compiled for
another platform is refused the same way everywhere.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bbzide.diagnostics import UserError
from bbzide.worlds.radio import WorldConfigError
from bbzide.worlds.registry import WORLDS


def load_script(path: Path, host_names: tuple[str, ...], include: list[str]) -> Any:
    """Compile a `.bzz` for a world's string table (or load a `.bbo`): a BittyBuzzProgram."""
    from bbzide import compiler
    from bbzide.compiler.commands import include_path_from_environment

    if not path.exists():
        raise UserError(f"no such script: {path}")
    strings = compiler.bittybuzz_string_table(list(host_names))
    if path.suffix == ".bbo":
        program = compiler.load_program(path)
        check_string_table(path, program.strings, tuple(host_names))
        return program
    include_path = (*include, *include_path_from_environment(), str(path.parent))
    return compiler.compile_file(str(path), include_path=include_path,
                                 string_table=strings).to_bbo()


def check_string_table(path: Path, found: list[str], host_names: tuple[str, ...]) -> None:
    """Refuse a `.bbo` whose `.bo` shows it was compiled without BittyBuzz's base strings
    (`compiler.base_strings_mismatch`); without a `.bo` beside it nothing can be checked."""
    from bbzide.compiler import base_strings_mismatch

    why = base_strings_mismatch(found)
    if why is None:
        return
    platform = next((spec.profile for spec in WORLDS.values() if spec.host_names == host_names),
                    "P")
    raise WorldConfigError(f"{path}: {why}: compile it with --platform {platform}, or run the "
                           ".bzz")
