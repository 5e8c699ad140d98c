"""The Build view's listing: instructions under the line they come from, with their `.bbo` pc
(the pc the inspector shows) and `pushs` operands as the strings they push."""

from __future__ import annotations

import re
from pathlib import Path

from bbzide.compiler import bittybuzz_string_table, compile_source
from bbzide.compiler.bytecode import read_bbo
from bbzide.ui.build_panel import listing_html

SCRIPT = """\
var n = 0

# count the steps
function step() {
  if (n < 10) {
    n = n + 1
  }
  log(n)
}
"""


def _rows(tmp_path: Path) -> tuple[list[tuple[int | None, int | None, str]], object]:
    path = tmp_path / "count.bzz"
    path.write_text(SCRIPT)
    compiled = compile_source(SCRIPT, str(path), string_table=bittybuzz_string_table(["log"]))
    program = compiled.to_bbo()
    text = re.sub(r"<[^>]+>", "", listing_html(compiled, program, SCRIPT, path))
    text = text.replace("&quot;", '"').replace("&lt;", "<")
    rows: list[tuple[int | None, int | None, str]] = []
    line = None
    for row in text.splitlines():
        heading = re.match(r"\s*(\d+) │ ", row)
        if heading:
            line = int(heading.group(1))
            continue
        instruction = re.match(r"\s*│\s+(\d+)  (.*)$", row)
        if instruction:
            rows.append((line, int(instruction.group(1)), instruction.group(2)))
    return rows, program


def test_instructions_sit_under_their_own_line(tmp_path: Path) -> None:
    rows, _ = _rows(tmp_path)
    by_text = {(text, line) for line, _, text in rows}
    assert ("jumpz @__label_2", 5) in by_text        # the if's test, not under line 6
    assert ('pushs "n"', 1) in by_text and ("gstore", 1) in by_text
    assert ("add", 6) in by_text and ("gstore", 6) in by_text
    assert ("callc", 8) in by_text                   # log(n): not under the `}` of line 9


def test_pcs_are_the_bbo_offsets_and_strings_are_shown(tmp_path: Path) -> None:
    rows, program = _rows(tmp_path)
    instructions = read_bbo(program.bbo).instructions  # type: ignore[attr-defined]
    assert [pc for _, pc, _ in rows] == [i.offset for i in instructions]
    assert [text.split()[0] for _, _, text in rows] == [i.mnemonic for i in instructions]
    assert any(text == 'pushs "log"' for _, _, text in rows)
