"""What the last good compile produced: footprint against the platform, and the listing.

Footprint: the `.bo` (Buzz bytecode) and `.bbo` (BittyBuzz bytecode, what is flashed) sizes
against the platform's flash budget for bytecode, and the string count. Listing: the `.basm`
text regrouped under the source lines its annotations point at (`TAB instr TAB |line,col,file`,
notes §B.3), moved back to the line they end when the annotated token opens the next line, with
each instruction's `.bbo` pc and the text of `pushs` strings, so a student sees which
instructions each line of Buzz became.
"""

from __future__ import annotations

import html
import json
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


#: The paused robot's instruction in the listing: the editor's paused-line colours.
CURRENT_PC_STYLE = "background:#fff3bf;box-shadow:inset 3px 0 0 #f08c00;font-weight:600"


def listing_html(compiled: Any, program: Any, source_text: str, source_path: Path,
                 current_pc: int | None = None) -> str:
    """The assembly grouped under its source lines, as preformatted HTML: each instruction with
    its program counter in the `.bbo` (what the inspector's pc names) and a `pushs` with the
    string it pushes; `current_pc` (where the debugger stopped) is highlighted."""
    source_lines = source_text.splitlines()
    pcs = _bbo_pcs(compiled, program)
    strings = list(getattr(compiled, "strings", []) or [])
    groups: list[tuple[int, list[tuple[int | None, str]]]] = []  # (source line or 0, rows)
    instruction_index = 0
    for raw in compiled.basm.splitlines():
        if not raw.startswith(("\t", "@")):
            continue  # string table and blank lines
        match = _ANNOTATION.search(raw)
        line = 0
        if match and Path(match.group(3)).name == source_path.name:
            line = _owning_line(int(match.group(1)), int(match.group(2)), source_lines)
        instruction = _ANNOTATION.sub("", raw).strip()
        pc = None
        if not instruction.startswith("@"):
            pc = pcs[instruction_index] if instruction_index < len(pcs) else None
            instruction_index += 1
            instruction = _with_string(instruction, strings)
        if groups and groups[-1][0] == line:
            groups[-1][1].append((pc, instruction))
        else:
            groups.append((line, [(pc, instruction)]))
    out = []
    for line, rows in groups:
        if 1 <= line <= len(source_lines):
            out.append(
                f'<span style="color:#1864ab">{line:4d} │ '
                f"{html.escape(source_lines[line - 1])}</span>"
            )
        elif line == 0:
            out.append('<span style="color:#868e96">     │ (no source line)</span>')
        for pc, instruction in rows:
            colour = "#5f3dc4" if instruction.startswith("@") else "#212529"
            where = f"{pc:5d}" if pc is not None else "     "
            current = pc is not None and pc == current_pc
            style = f"color:{colour}" + (f";{CURRENT_PC_STYLE}" if current else "")
            marker = " ➜ " if current else "   "
            css_class = ' class="current-pc"' if current else ""
            out.append(f'<span style="{style}" data-pc="{"" if pc is None else pc}"{css_class}>'
                       f'  {marker}│ <span style="color:#868e96">{where}</span>  '
                       f"{html.escape(instruction)}</span>")
    body = "\n".join(out)
    caption = (
        '<div style="font-size:11px;color:#868e96;margin-bottom:4px">Each instruction sits under '
        "the source line it comes from; the grey number is its program counter (pc) in the "
        "<code>.bbo</code>, as the inspector shows it.</div>"
    )
    return caption + (
        '<pre style="font:11px/1.35 ui-monospace,monospace;max-height:60vh;overflow:auto;'
        f'margin:0;white-space:pre" class="asm-listing">{body}</pre>'
    )


def _owning_line(line: int, col: int, source_lines: list[str]) -> int:
    """The source line an instruction belongs to. The compiler annotates each instruction with
    the token it was looking at *after* reading what the instruction does (Buzz's debug info):
    when that token opens its line (the next statement, a closing `}`), the instruction ends
    the code before it, on the previous line that holds code."""
    if not 1 <= line <= len(source_lines):
        return line
    text = source_lines[line - 1]
    if col != len(text) - len(text.lstrip()):
        return line
    previous = line - 1
    while previous >= 1 and _is_blank_or_comment(source_lines[previous - 1]):
        previous -= 1
    return previous if previous >= 1 else line


def _is_blank_or_comment(text: str) -> bool:
    stripped = text.strip()
    return not stripped or stripped.startswith("#")


def _bbo_pcs(compiled: Any, program: Any) -> list[int | None]:
    """The `.bbo` offset of each instruction of the `.bo`, in code order."""
    from bbzide.compiler.bytecode import read_bo

    bo_to_bbo = getattr(program, "bo_to_bbo", {}) or {}
    try:
        instructions = read_bo(compiled.bo).instructions
    except Exception:  # noqa: BLE001 - the listing then just has no pcs
        return []
    return [bo_to_bbo.get(i.offset) for i in instructions]


def _with_string(instruction: str, strings: list[str]) -> str:
    """`pushs 53` as `pushs "g"` (the string id's text)."""
    name, _, operand = instruction.partition(" ")
    if name == "pushs" and operand.isdigit() and int(operand) < len(strings):
        return f"pushs {json.dumps(strings[int(operand)], ensure_ascii=False)}"
    return instruction
