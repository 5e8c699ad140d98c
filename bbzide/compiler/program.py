"""The compiler's products: `CompiledProgram` (bzzc's outputs) and `BittyBuzzProgram` (bo2bbo's).

Both carry the bytes byte-identical to the reference tools plus what the VM and the IDE need:
the string table by id, and a debug map from code offset to `SourceLocation`. For a
`BittyBuzzProgram` the offsets are `.bbo` offsets, i.e. VM program counters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bbzide.compiler.bo2bbo import bo_to_bbo
from bbzide.compiler.call_sites import CallSite, ScriptSymbols
from bbzide.diagnostics import SourceLocation


@dataclass(slots=True)
class BittyBuzzProgram:
    """A `.bbo` and its string table / debug map (keyed by `.bbo` offset = VM pc)."""

    bbo: bytes
    strings: list[str]
    debug_map: dict[int, SourceLocation] = field(default_factory=dict)
    bo_to_bbo: dict[int, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    #: `.bbo` offset of each `callc` -> the call as written (empty for a stored `.bbo`)
    call_sites: dict[int, CallSite] = field(default_factory=dict)
    #: the globals the script defines and reads (empty for a stored `.bbo`)
    symbols: ScriptSymbols = field(default_factory=ScriptSymbols)
    #: the main script (its path as in the debug map) and its text as compiled, if known
    source_file: str | None = None
    source_text: str | None = None

    def source_line(self, location: SourceLocation) -> str | None:
        """The text of `location`'s line in the script as it was compiled (None for another
        file, or when the text is not known): what a robot runs, even if the file changed."""
        if self.source_text is None or location.file != self.source_file:
            return None
        lines = self.source_text.splitlines()
        return lines[location.line - 1] if 1 <= location.line <= len(lines) else None

    def location_of(self, pc: int) -> SourceLocation | None:
        return self.debug_map.get(pc)

    def string_id(self, name: str) -> int | None:
        try:
            return self.strings.index(name)
        except ValueError:
            return None


@dataclass(slots=True)
class CompiledProgram:
    """bzzc's outputs: `.basm` text, `.bo`, `.bdb`, strings, debug map keyed by `.bo` offset."""

    basm: str
    bo: bytes
    bdb: bytes
    strings: list[str]
    debug_map: dict[int, SourceLocation] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    filename: str = "<bo>"
    #: `.bo` offset of each `callc` -> the call as written (see `call_sites.py`)
    call_sites: dict[int, CallSite] = field(default_factory=dict)
    symbols: ScriptSymbols = field(default_factory=ScriptSymbols)
    source_file: str | None = None
    source_text: str | None = None

    def to_bbo(self) -> BittyBuzzProgram:
        conversion = bo_to_bbo(self.bo, self.filename)
        debug_map = {
            conversion.bo_to_bbo[offset]: location
            for offset, location in self.debug_map.items()
            if offset in conversion.bo_to_bbo
        }
        call_sites = {
            conversion.bo_to_bbo[offset]: site
            for offset, site in self.call_sites.items()
            if offset in conversion.bo_to_bbo
        }
        return BittyBuzzProgram(
            conversion.bbo, list(self.strings), debug_map, conversion.bo_to_bbo,
            conversion.warnings, call_sites, self.symbols, self.source_file, self.source_text,
        )
