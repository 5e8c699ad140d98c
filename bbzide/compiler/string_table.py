"""String tables: the BittyBuzz base strings and `.bst` files (spec §B.1, §D.1, §D.2).

BittyBuzz's VM never sees string text, only 16-bit ids, and its C code hard-codes the ids of the
strings it uses itself (`bbzstrids.h`). Those 46 strings are therefore always the first entries
of a BittyBuzz string table (`BittyBuzzStrings.bst`), followed by the firmware's host-function
names (the user `.bst`), followed by the script's own strings. Written here from the spec's list.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bbzide.diagnostics import UserError

#: The BittyBuzz base strings, in id order 0..45 (spec §D.2, `bbzstrids.h`).
BITTYBUZZ_BASE_STRINGS: tuple[str, ...] = (
    "id",
    "swarm",
    "create",
    "select",
    "init",
    "step",
    "reset",
    "destroy",
    "join",
    "unselect",
    "leave",
    "in",
    "exec",
    "intersection",
    "union",
    "difference",
    "others",
    "neighbors",
    "foreach",
    "map",
    "reduce",
    "distance",
    "azimuth",
    "elevation",
    "count",
    "kin",
    "nonkin",
    "data",
    "filter",
    "broadcast",
    "listen",
    "ignore",
    "stigmergy",
    "put",
    "get",
    "size",
    "onconflict",
    "onconflictlost",
    "robot",
    "timestamp",
    "pos",
    "x",
    "y",
    "orientation",
    "__INTERNAL_1_DO_NOT_USE__",
    "__INTERNAL_2_DO_NOT_USE__",
)

#: Host functions the Kilobot firmware registers (the Kilobot `.bst` of the BittyBuzz build and
#: the corpus: `led set_motor delay abs`). Used by `compile --platform kilobot` without `--bst`.
KILOBOT_HOST_NAMES: tuple[str, ...] = ("led", "set_motor", "delay", "abs")

#: `bzzparse` reads `.bst` lines with `fgets` into a 1024-byte buffer: longer lines are split.
BST_LINE_BUFFER = 1024


def bittybuzz_string_table(host_names: Sequence[str]) -> list[str]:
    """The 46 base strings followed by `host_names` (the concatenated `.bst` of §D.1)."""
    return [*BITTYBUZZ_BASE_STRINGS, *host_names]


def parse_bst(data: bytes) -> list[str]:
    """`.bst` lines as `bzzparse` reads them: one trailing LF removed per line, CR kept, long
    lines split at 1023 bytes; empty lines count."""
    strings: list[str] = []
    position = 0
    while position < len(data):
        end = data.find(b"\n", position)
        line = data[position:] if end < 0 else data[position : end + 1]
        line = line[: BST_LINE_BUFFER - 1]
        position += len(line)
        if line.endswith(b"\n"):
            line = line[:-1]
        strings.append(line.decode("utf-8", "surrogateescape"))
    return strings


def read_bst(path: str | Path) -> list[str]:
    try:
        return parse_bst(Path(path).read_bytes())
    except OSError as error:
        raise UserError(f"cannot read string table {path}: {error.strerror}") from None


def format_bst(strings: Sequence[str]) -> bytes:
    return b"".join(text.encode("utf-8", "surrogateescape") + b"\n" for text in strings)


def write_bst(path: str | Path, strings: Sequence[str]) -> None:
    Path(path).write_bytes(format_bst(strings))


def base_strings_mismatch(strings: Sequence[str]) -> str | None:
    """Why a compiled program's string table (its `.bo` strings) is not a BittyBuzz one, or
    None when it starts with the base strings (or is unknown: empty).

    The VM's built-ins (`neighbors`, `broadcast`, `stigmergy`, ...) use the fixed ids 0..45 of
    the base strings, so a `.bbo` made from a `.bo` compiled without them runs, but its swarm
    calls go nowhere (the gradient example sent no message at all). Host functions are bound
    by name, so any host list after the base strings is fine.
    """
    base = list(BITTYBUZZ_BASE_STRINGS)
    found = list(strings)
    if not found or found[: len(base)] == base:
        return None
    at = next((i for i, (a, b) in enumerate(zip(found, base, strict=False)) if a != b),
              len(found))
    seen = repr(found[at]) if at < len(found) else "missing"
    return (f"it was compiled without BittyBuzz's string table (string {at} is {seen}, "
            f"BittyBuzz's is {base[at]!r}), so its neighbors/stigmergy calls would go nowhere")
