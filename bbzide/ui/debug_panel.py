"""The Debug folder of the IDE: continue, pause, step forward and back, and where the run stopped.

Design: like the Run folder (`controls.py`), every button only queues a command on the run
controller; the simulation thread applies it between (or, paused mid-step, within) steps. A
step command applies to the robot the clicking tab has selected in its inspector, else to the
robot the debugger stopped. The two rows are viser button groups (one click = one command),
which keeps nine buttons in two lines of the panel. `refresh` rewrites the text from the run's
status on the app's ticker; breakpoints themselves are set in the editor's gutter.
"""

from __future__ import annotations

from collections.abc import Callable

import viser

from bbzide.ui.breakpoints import LineBreakpoint
from bbzide.ui.inspection import PausedAt
from bbzide.ui.run_controller import RunController

#: Forward row: button label -> controller command ("continue" is play; pausing is the Run
#: folder's Pause).
FORWARD = {"Continue": "continue", "Over": "step_over", "Into": "step_into",
           "Out": "step_out", "Instr.": "step_instruction"}
#: Backward row: button label -> controller command.
BACKWARD = {"Line": "step_back_line", "Control step": "step_back_control_step",
            "Previous hit": "run_back_to_previous_hit"}


class DebugControls:
    def __init__(self, server: viser.ViserServer, controller: RunController,
                 selected_robot: Callable[[viser.ClientHandle | None], int | None]) -> None:
        self.controller = controller
        self.selected_robot = selected_robot
        gui = server.gui
        with gui.add_folder("Debug", order=1.5):
            self.where = gui.add_markdown(NOT_PAUSED)
            self.forward = gui.add_button_group(
                "Step", tuple(FORWARD),
                hint="Continue · step Over / Into / Out of a call (the selected robot, "
                     "else the stopped one) · one VM Instruction (see the Build listing)")
            self.backward = gui.add_button_group(
                "Back", tuple(BACKWARD),
                hint="Step back one line or one control step (exact: replayed from a "
                     "snapshot), or run back to the previous breakpoint hit")
            self.pause_on_error = gui.add_checkbox(
                "Pause on error", initial_value=controller.pause_on_error,
                hint="A robot whose VM fails pauses the run at the failing line")
            self.breakpoint_list = gui.add_markdown(NO_BREAKPOINTS)
        self.forward.on_click(lambda event: self.command(FORWARD[event.target.value],
                                                         event.client))
        self.backward.on_click(lambda event: self.command(BACKWARD[event.target.value],
                                                          event.client))
        self.pause_on_error.on_update(
            lambda _: setattr(controller, "pause_on_error", bool(self.pause_on_error.value)))

    def command(self, command: str, client: viser.ClientHandle | None = None) -> None:
        """One debugger command, as a click from `client`'s tab would send it."""
        if command == "continue":
            self.controller.play()
        elif command == "pause":
            self.controller.pause()
        else:
            self.controller.debug(command, self.selected_robot(client))

    def refresh(self, breakpoints: list[LineBreakpoint]) -> None:
        status = self.controller.status
        text = where_markdown(status.paused_at)
        if status.debug_note:
            text += f"  \n*{status.debug_note}*"
        for refused in status.breakpoint_errors:
            text += f"  \n⚠ {refused}"
        if self.where.content != text:
            self.where.content = text
        listed = breakpoints_markdown(breakpoints)
        if self.breakpoint_list.content != listed:
            self.breakpoint_list.content = listed


NOT_PAUSED = "*not stopped by the debugger* · click the editor's left margin to set a breakpoint"
NO_BREAKPOINTS = "**Breakpoints**: none (click a line's left margin; right-click for options)"


#: Why the debugger stopped, as the Debug folder says it.
WHY = {"breakpoint": "breakpoint", "step": "stepped", "error": "error", "pause": "paused"}


def where_markdown(paused: PausedAt | None) -> str:
    """The Debug folder's first line: which robot stopped where, and why."""
    if paused is None:
        return NOT_PAUSED
    line = f"line **{paused.line}**" if paused.line else "no source line"
    function = f" in `{paused.frames[0].function}`" if paused.frames else ""
    text = (f"**Paused:** robot **{paused.robot_id}** (#{paused.robot_index}) at {line}"
            f"{function} ({WHY.get(paused.reason, paused.reason)}, control step {paused.step})")
    if paused.mid_step:
        text += "  \n*mid-step: the robots before it ran this step, the others have not yet*"
    if paused.message:
        text += f"  \n**{paused.message}**"
    return text


def breakpoints_markdown(breakpoints: list[LineBreakpoint]) -> str:
    if not breakpoints:
        return NO_BREAKPOINTS
    return "**Breakpoints**  \n" + "  \n".join(f"● {b.describe()}" for b in breakpoints)
