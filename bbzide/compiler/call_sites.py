"""What the compiler knows about calls and globals, kept beside the bytecode (never inside it).

The reference debug info (`.bdb`) puts each instruction at the parser's look-ahead token, so a
`callc` sits on the token *after* the call: often the next line's `}`. A runtime error on that
`callc` then points at the wrong line and can only say "wrong operand type". The parser knows
better while it parses: the called expression's text (`nosuchfunction`, `neighbors.broadcast`)
and its first token's line and column. `CallSite` records that, one per `callc`, and
`ScriptSymbols` records the globals the script defines and the ones it reads (for the
undefined-global lint). Both travel in `CompiledProgram`/`BittyBuzzProgram` next to the debug
map, so the `.bo`/`.bdb` bytes stay identical to the reference tools'.

How a call site finds its instruction: the parser emits each `callc` as a `CallLine` (a `str`
that also carries its `CallSite`); the `.basm` text is made of the same strings, so the call
lines in text order are the `callc` instructions in `.bo` order (the assembler is linear and
`callc` comes from nowhere else).

`explain_failed_call` turns a TYPE error on a `callc` into the student's terms; the CLI and the
IDE both use it.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from bbzide.diagnostics import SourceLocation

#: Globals every BittyBuzz VM registers before the script runs (`bbzvm_construct` and the
#: `*_register` functions of neighbors, swarm, stigmergy and the table library).
BITTYBUZZ_GLOBALS: tuple[str, ...] = (
    "id", "neighbors", "swarm", "stigmergy", "foreach", "map", "reduce", "filter", "size",
)

#: How many known names a warning lists: the close matches first, then enough others to show
#: what exists without drowning the message (a world has at most ~15 host functions).
LISTED_NAMES = 12


@dataclass(frozen=True, slots=True)
class CallSite:
    """One call in the source: where it starts, the called expression as written, and the
    global name called when the callee is a bare global identifier (`f(x)`, not `t.f(x)`)."""

    location: SourceLocation
    callee: str
    global_name: str | None = None


class CallLine(str):
    """A `.basm` line of a `callc`, carrying its call site (the text is the plain line)."""

    site: CallSite

    def __new__(cls, text: str, site: CallSite) -> CallLine:
        line = super().__new__(cls, text)
        line.site = site
        return line


@dataclass(slots=True)
class ScriptSymbols:
    """Globals the script defines (functions, top-level `var`, assignments to a global) and the
    first place each global is read or called (the name's own token)."""

    defined: set[str] = field(default_factory=set)
    first_reads: dict[str, SourceLocation] = field(default_factory=dict)

    def read(self, name: str, location: SourceLocation) -> None:
        self.first_reads.setdefault(name, location)


def call_sites_by_offset(lines: Iterable[str], callc_offsets: Sequence[int]) -> dict[int, CallSite]:
    """Pair the `CallLine`s of the `.basm` (in text order) with the `callc` offsets of the
    `.bo` (in code order). A count mismatch means a `callc` we did not emit ourselves (e.g. a
    hand-written `.basm`): then nothing is paired rather than pairing wrongly."""
    sites = [line.site for line in lines if isinstance(line, CallLine)]
    if len(sites) != len(callc_offsets):
        return {}
    return dict(zip(callc_offsets, sites, strict=True))


def known_names_text(name: str, known: Iterable[str]) -> str:
    """`known` as a short list for a message, the names closest to `name` first."""
    names = sorted(set(known))
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
    ordered = close + [n for n in names if n not in close]
    shown = ", ".join(f"`{n}`" for n in ordered[:LISTED_NAMES])
    more = len(ordered) - LISTED_NAMES
    return shown + (f" and {more} more" if more > 0 else "")


def explain_failed_call(site: CallSite, defined: Iterable[str], host_names: Sequence[str],
                        platform: str) -> str:
    """A TYPE error on the `callc` of `site`, in the student's terms.

    `defined`: globals the script defines; `host_names`: host functions registered on this
    robot; `platform`: how to name the robot ("the Kilobot")."""
    callee = site.callee
    name = site.global_name
    if name is None:
        return f"`{callee}` is not a function here, so it cannot be called"
    if name in host_names or name in BITTYBUZZ_GLOBALS:
        return f"`{name}` is not a function here (it was assigned another value), so it " \
               "cannot be called"
    if name in set(defined):
        return f"`{name}` is not a function when this call runs: the script defines it, but " \
               "as another value (or not yet)"
    close = difflib.get_close_matches(name, [*host_names, *BITTYBUZZ_GLOBALS, *defined], n=1,
                                      cutoff=0.6)
    suggestion = f"; did you mean `{close[0]}`?" if close else ""
    return f"`{name}` is nil here: it is not defined, and no host function of {platform} " \
           f"has that name{suggestion}"


def undefined_globals(symbols: ScriptSymbols, host_names: Sequence[str]
                      ) -> list[tuple[str, SourceLocation]]:
    """Globals read or called but never defined by the script, the VM or the platform, each
    with the first place it is used (source order)."""
    known = {*symbols.defined, *BITTYBUZZ_GLOBALS, *host_names}
    found = [(name, where) for name, where in symbols.first_reads.items() if name not in known]
    return sorted(found, key=lambda item: (item[1].file, item[1].line, item[1].col))


def undefined_global_message(name: str, symbols: ScriptSymbols, host_names: Sequence[str],
                             platform: str) -> str:
    """The lint warning for one undefined global, with the names that do exist."""
    known = [*symbols.defined, *host_names, *BITTYBUZZ_GLOBALS]
    return (f"`{name}` is never defined: it is not a global of the script, nor a host function "
            f"of {platform}, so it is nil when read (calling it stops the robot). "
            f"Known names: {known_names_text(name, known)}")


def robot_phrase(world_name: str) -> str:
    """The robot of a world in a sentence: "the Kilobot", "the M300"."""
    return f"the {world_name[:1].upper()}{world_name[1:]}" if world_name else "this robot"


def lint_globals(program: object, host_names: Sequence[str], platform: str
                 ) -> list[tuple[SourceLocation, str]]:
    """The undefined-global warnings of a compiled program (`CompiledProgram` or
    `BittyBuzzProgram`): one per name, at its first use."""
    symbols = getattr(program, "symbols", None)
    if symbols is None:
        return []
    return [(where, undefined_global_message(name, symbols, host_names, platform))
            for name, where in undefined_globals(symbols, host_names)]


def explain_failure(program: object, reason: str, pc: int, host_names: Sequence[str],
                    platform: str) -> tuple[SourceLocation, str] | None:
    """Where and why, in the student's terms, for a robot stopped by `reason` at `pc` of
    `program` (a `BittyBuzzProgram`); None when the compiler knows nothing better than the
    debug map (not a TYPE error on a call, or a stored `.bbo` without call sites)."""
    if reason != "TYPE":
        return None
    site = getattr(program, "call_sites", {}).get(pc)
    if site is None:
        return None
    symbols = getattr(program, "symbols", None)
    defined = symbols.defined if symbols is not None else set()
    return site.location, explain_failed_call(site, defined, host_names, platform)
