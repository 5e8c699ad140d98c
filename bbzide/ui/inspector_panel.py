"""The inspector of one browser tab: the robot that tab clicked, its memory and runtime state.

Each tab (viser client) gets its own `InspectorPanel` built from `client.gui`, so two tabs can
watch different robots of the same run. The app's ticker calls `refresh(inspection)`; every
widget is rewritten only when its text changed, so a paused robot's view is still and its
expanded tables stay open.
"""

from __future__ import annotations

import html

import viser

from bbzide.ui.heap_map import legend_html, render_heap_svg
from bbzide.ui.inspection import PausedAt, RobotInspection


class InspectorPanel:
    def __init__(self, client: viser.ClientHandle) -> None:
        self.client = client
        self.selected: int | None = None
        gui = client.gui
        with gui.add_folder("Inspector", order=3):
            self.header = gui.add_markdown("*Click a robot to inspect its memory.*")
            self.pick = gui.add_html("")  # above the map: a tall map scrolls it away
            self.heap = gui.add_html("")
            self.memory = gui.add_markdown("")
            tabs = gui.add_tab_group()
            with tabs.add_tab("Objects"):
                self.objects = gui.add_html("")
            with tabs.add_tab("Stack"):
                self.stack = gui.add_markdown("")
            with tabs.add_tab("Globals"):
                self.globals = gui.add_markdown("")
            with tabs.add_tab("Comm"):
                self.comm = gui.add_markdown("")
            with tabs.add_tab("Problems"):
                self.problems = gui.add_markdown("")
            self.deselect = gui.add_button("Deselect", icon=viser.Icon.X, visible=False)

    def show_nothing(self, message: str) -> None:
        _set(self.header, message)
        for handle in (
            self.heap,
            self.pick,
            self.memory,
            self.objects,
            self.stack,
            self.globals,
            self.comm,
            self.problems,
        ):
            _set(handle, "")
        self.deselect.visible = self.selected is not None

    def refresh(self, view: RobotInspection, paused: PausedAt | None = None) -> None:
        """Show `view`; with `paused` (the debugger's stop) on this robot, the Stack tab shows
        its call frames and their locals first."""
        self.deselect.visible = True
        state = view.state if view.last_error is None else "error"
        pc = f" · pc {view.pc}" if view.pc is not None else ""
        if view.pc is not None and view.pc_line is not None:
            pc += f" (line {view.pc_line})"
        _set(
            self.header,
            f"**Robot {view.robot_id}** (#{view.robot_index}) · step {view.step} · "
            f"{state}{pc}  \nROP **{view.rop}** · LSP **{view.lsp}** · heap {view.heap_size} B",
        )
        _set(
            self.heap,
            f'<div class="heap-wrap" data-rop="{view.rop}" data-lsp="{view.lsp}">'
            f"{render_heap_svg(view)}{legend_html()}</div>",
        )
        # rewritten only for another robot: a click on the map fills it in the browser
        _set(self.pick, pick_box_html(view.robot_index))
        _set(self.memory, _memory_markdown(view))
        _set(self.objects, _objects_html(view))
        stack = _list_markdown("Stack frames", view.frames)
        if paused is not None and paused.robot_index == view.robot_index:
            stack = paused_markdown(paused) + "\n\n" + stack
        _set(self.stack, stack)
        _set(self.globals, _pairs_markdown("Globals", view.globals))
        comm = [
            _pairs_markdown("Stigmergy", view.stigmergy),
            _pairs_markdown("Neighbors", view.neighbors),
            _list_markdown("Swarms", view.swarms),
            _list_markdown("Incoming queue", view.in_queue),
            _list_markdown("Outgoing queue", view.out_queue),
        ]
        _set(self.comm, "\n\n".join(comm))
        _set(self.problems, _problems_markdown(view))


def paused_markdown(paused: PausedAt) -> str:
    """Where the debugger stopped and the call frames there, innermost first, with locals."""
    where = f"line {paused.line}" if paused.line else "no source line"
    pc = f" · pc {paused.pc}" if paused.pc is not None else ""
    parts = [f"**Paused** ({paused.reason}) at {where}{pc} · step {paused.step}"]
    if paused.message:
        parts.append(f"**Error:** {_escape_emphasis(paused.message)}")
    for depth, frame in enumerate(paused.frames):
        line = f" · line {frame.line}" if frame.line else ""
        title = f"**#{depth} `{frame.function}`**{line}"
        if frame.locals:
            rows = "\n".join(f"| `{name}` | `{value}` |" for name, value in frame.locals.items())
            parts.append(f"{title}\n\n| local | value |\n|---|---|\n{rows}")
        else:
            parts.append(f"{title} · no locals")
    if not paused.frames:
        parts.append("*no Buzz function running*")
    return "\n\n".join(parts)


def _set(handle: viser.GuiMarkdownHandle | viser.GuiHtmlHandle, text: str) -> None:
    if handle.content != text:
        handle.content = text


def _memory_markdown(view: RobotInspection) -> str:
    used_pct = 100 * view.used_bytes / view.heap_size if view.heap_size else 0
    lines = [
        f"**Heap** used {view.used_bytes} B · free {view.free_bytes} B ({used_pct:.0f} % used)"
    ]
    extras = []
    if view.peak_bytes is not None:
        extras.append(f"peak {view.peak_bytes} B")
    if view.gc_runs is not None:
        extras.append(f"GC runs {view.gc_runs}")
    if view.ram_bytes:
        extras.append(
            f"heap = {100 * view.heap_size / view.ram_bytes:.0f} % of the {view.ram_bytes} B RAM"
        )
    if extras:
        lines.append(" · ".join(extras))
    return "  \n".join(lines)


def pick_box_html(robot_index: int) -> str:
    """The box a click on a heap block fills with that block's object (see `heap_map`)."""
    return (
        f'<div class="bbz-heap-pick" data-robot="{robot_index}" style="white-space:pre-wrap;'
        "font:11px/1.45 ui-monospace,monospace;border:1px solid #dee2e6;border-radius:4px;"
        'padding:4px 6px;margin:2px 0 4px">'
        "Click a block of the heap map: its object, offset, size, value and who refers to it."
        "</div>"
    )


def _objects_html(view: RobotInspection) -> str:
    if not view.objects:
        return "<i>no objects</i>"
    rows = []
    for row in view.objects:
        where = f" @{row.offset} {row.size} B" if row.offset >= 0 else ""
        called = f" {html.escape(row.name)}" if row.name and row.type_name != "closure" else ""
        name = (f"#{row.index}{where} {html.escape(row.type_name)}{called}"
                f"{' (permanent)' if row.permanent else ''}")
        if row.referrers:
            name = (f'<span title="referred to by: {html.escape("; ".join(row.referrers))}">'
                    f"{name}</span>")
        if row.children:
            entries = "".join(
                f"<div style='padding-left:14px'>{html.escape(k)} = {html.escape(v)}</div>"
                for k, v in row.children
            )
            rows.append(
                f"<details><summary>{name}: {html.escape(row.value)}</summary>{entries}</details>"
            )
        else:
            rows.append(f"<div>{name}: {html.escape(row.value)}</div>")
    return (
        '<div style="font:11px/1.45 ui-monospace,monospace;max-height:40vh;overflow:auto">'
        + "".join(rows)
        + "</div>"
    )


def _list_markdown(title: str, items: list[str]) -> str:
    if not items:
        return f"**{title}**: none"
    return f"**{title}**\n\n" + "\n".join(f"- `{item}`" for item in items)


def _prose_list_markdown(title: str, items: list[str]) -> str:
    """Sentences that already mark their code with backticks (warnings, errors): shown as
    text, with `*` and `_` escaped so a message never turns into emphasis."""
    if not items:
        return f"**{title}**: none"
    return f"**{title}**\n\n" + "\n".join(f"- {_escape_emphasis(item)}" for item in items)


def _escape_emphasis(text: str) -> str:
    """Escape markdown emphasis outside `code` spans (inside them it is literal already)."""
    pieces = text.split("`")
    for index in range(0, len(pieces), 2):  # even pieces are outside code spans
        pieces[index] = pieces[index].replace("*", "\\*").replace("_", "\\_")
    return "`".join(pieces)


def _pairs_markdown(title: str, pairs: list[tuple[str, str]]) -> str:
    if not pairs:
        return f"**{title}**: none"
    rows = "\n".join(f"| `{name}` | `{value}` |" for name, value in pairs)
    return f"**{title}**\n\n| name | value |\n|---|---|\n{rows}"


def _problems_markdown(view: RobotInspection) -> str:
    parts = []
    if view.last_error:
        parts.append(f"**Last error:** {_escape_emphasis(view.last_error)}")
        if view.last_error_line:
            parts.append(f"```\n{view.last_error_line}\n```")
    else:
        parts.append("**Last error:** none")
    parts.append(_prose_list_markdown("Warnings", view.warnings))
    if view.notes:
        parts.append("*" + "; ".join(view.notes) + "*")
    return "\n\n".join(parts)
