"""What the last good compile produced: footprint against the platform, and the listing.

Footprint: the `.bo` (Buzz bytecode) and `.bbo` (BittyBuzz bytecode, what is flashed) sizes
against the platform's flash budget for bytecode, and the string count. Listing: the `.basm`
text regrouped under the source lines its annotations point at (`TAB instr TAB |line,col,file`,
notes §B.3), so a student sees which instructions each line of Buzz became.
"""

from __future__ import annotations

import html
import re
from pathlib import Path
from typing import Any

#: `.basm` annotation: `|line,col,file` at the end of a code line.
_ANNOTATION = re.compile(r"\t\|(\d+),(\d+),(.*)$")


def footprint_markdown(
    compiled: Any, program: Any, platform_name: str, flash_budget: int | None
) -> str:
    bo_size = len(compiled.bo)
    bbo_size = len(program.bbo)
    rows = ["| artefact | bytes | of budget |", "|---|---:|---:|"]
    budget_cell = (
        (lambda size: f"{100 * size / flash_budget:.1f} %") if flash_budget else (lambda _: "–")
    )
    rows.append(f"| `.bo` (Buzz) | {bo_size} | {budget_cell(bo_size)} |")
    rows.append(f"| `.bbo` (BittyBuzz, flashed) | {bbo_size} | {budget_cell(bbo_size)} |")
    rows.append(f"| strings | {len(program.strings)} | |")
    budget = f"{flash_budget} B" if flash_budget else "unknown"
    text = f"**Footprint on {platform_name}** (bytecode budget {budget})\n\n" + "\n".join(rows)
    if flash_budget and bbo_size > flash_budget:
        text += f"\n\n⚠ the `.bbo` is {bbo_size - flash_budget} B over the budget: it will not fit."
    return text


def listing_html(basm: str, source_text: str, source_path: Path) -> str:
    """The assembly grouped under its source lines, as preformatted HTML."""
    source_lines = source_text.splitlines()
    groups: list[tuple[int, list[str]]] = []  # (source line or 0, instructions)
    for raw in basm.splitlines():
        if not raw.startswith(("\t", "@")):
            continue  # string table and blank lines
        match = _ANNOTATION.search(raw)
        line = 0
        if match and Path(match.group(3)).name == source_path.name:
            line = int(match.group(1))
        instruction = _ANNOTATION.sub("", raw).strip()
        if groups and groups[-1][0] == line:
            groups[-1][1].append(instruction)
        else:
            groups.append((line, [instruction]))
    out = []
    for line, instructions in groups:
        if 1 <= line <= len(source_lines):
            out.append(
                f'<span style="color:#1864ab">{line:4d} │ '
                f"{html.escape(source_lines[line - 1])}</span>"
            )
        elif line == 0:
            out.append('<span style="color:#868e96">     │ (no source line)</span>')
        for instruction in instructions:
            colour = "#5f3dc4" if instruction.startswith("@") else "#212529"
            out.append(f'<span style="color:{colour}">     │     {html.escape(instruction)}</span>')
    body = "\n".join(out)
    caption = (
        '<div style="font-size:11px;color:#868e96;margin-bottom:4px">Each instruction sits under '
        "the line of the token the compiler was looking at when it emitted it (as in Buzz's "
        "debug info), so an instruction may appear one line late.</div>"
    )
    return caption + (
        '<pre style="font:11px/1.35 ui-monospace,monospace;max-height:60vh;overflow:auto;'
        f'margin:0;white-space:pre" class="asm-listing">{body}</pre>'
    )
