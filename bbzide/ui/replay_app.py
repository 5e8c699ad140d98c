"""The IDE in replay mode: a recorded mission on a timeline, the same scene and inspector.

    browser tab ──viser──▶ timeline (slider, play/pause, speed, step ±1, event jumps)
                           SwarmScene clicks ──▶ InspectorPanel (per tab, robot rebuilt at step)
    player thread (≤ 30 Hz) ──▶ seek(step) ──▶ SwarmScene.draw(frame) · status · inspectors

Design: there is no simulation; `seek(step)` is the one way the shown step changes (slider,
buttons, jumps, the player thread) and does everything a step change needs, under one lock:
draw the recorded frame, move the slider, rewrite the status line, rebuild and show each tab's
selected robot. Playing at `speed`× advances `speed / step_seconds` steps per second, drawn at
most `FRAME_HZ` times a second (at 16× several steps pass per frame). The editor is replaced
by the recorded program's source, read-only. The Watches and Stigmergy folders are the live
IDE's, read from the robots rebuilt at the shown step (`ReplaySession.watch_values`): a seek
redraws them, and the player thread notices a watch added or cleared.
"""

from __future__ import annotations

import html
import threading
import time
from typing import Any

import viser

from bbzide.ui.access import new_token
from bbzide.ui.debug_panel import BACKWARD, FORWARD, WHY
from bbzide.ui.inspector_panel import InspectorPanel
from bbzide.ui.overlay_view import OverlayView
from bbzide.ui.replay_session import JUMP_KINDS, MAX_HIT_SEARCH_STEPS, ReplaySession
from bbzide.ui.scene import SwarmScene
from bbzide.ui.viser_server import open_server, page_url
from bbzide.ui.watches import (
    STIGMERGY_ROBOTS,
    BadWatch,
    Watch,
    WatchBook,
    WatchPanel,
    stigmergy_markdown,
)

_JUMP_LABELS = dict(JUMP_KINDS)

#: Playback speeds offered, as multiples of the mission's real time (0.25x to 16x).
SPEEDS = {"0.25×": 0.25, "0.5×": 0.5, "1×": 1.0, "2×": 2.0, "4×": 4.0, "8×": 8.0, "16×": 16.0}
#: The player redraws at most this often: smooth enough, and a seek's inspector rebuild fits.
FRAME_HZ = 30.0
#: Width of the source panel (same as the live IDE's editor).
SOURCE_PANEL_WIDTH = 560


def numbered_source_html(source: str | None, marked: int | None = None) -> str:
    """The recorded program with its line numbers (grey), as the editor numbers them; the
    `marked` line (where stepping paused) on a yellow band, as the editor marks it."""
    if not source:
        return "(the recording has no source text)"
    lines = source.splitlines()
    width = len(str(len(lines)))
    return "\n".join(
        ('<span class="bbzide-paused-line" style="background:#fff3bf">' if number == marked
         else "<span>")
        + f'<span style="color:#868e96;user-select:none">{number:>{width}} │ </span>'
        f"{html.escape(line)}</span>"
        for number, line in enumerate(lines, start=1))


def source_view_html(source: str | None, marked: int | None = None) -> str:
    """The Program tab's content: the numbered source in a scrolling block."""
    return ("<pre class='bbzide-replay-source' style='font-size:12px;line-height:1.35;"
            "white-space:pre;overflow:auto;max-height:calc(100vh - 160px)'>"
            + numbered_source_html(source, marked) + "</pre>")


#: The event list's first entry, which seeks nowhere.
NO_EVENT = "— choose an event to go to its step —"


class ReplayApp:
    def __init__(
        self,
        session: ReplaySession,
        host: str = "127.0.0.1",
        port: int = 8080,
        token: str | None = None,
    ) -> None:
        self.session = session
        self.token = token or new_token()
        self.server = open_server(host, port, self.token)
        self.scene = SwarmScene(self.server, on_robot_click=self._on_robot_click)
        self.scene.set_world(session.geometry(), session.frame(session.first_step).positions)
        self.overlays = OverlayView(self.server)
        self.overlays.set_scale(session.geometry().robot_radius)
        self.step = session.first_step
        self.playing = False
        self.speed = 1.0
        self.last_seek_seconds = 0.0
        #: what the status line adds until the next seek (a jump that found nothing says so)
        self.note = ""
        #: turns of the player thread, each a look at `playing` (a paused player is idle after
        #: two: the turn in progress at the pause, then one that saw it)
        self.player_turns = 0
        self._lock = threading.RLock()
        #: the debugger stepping a scratch copy of the swarm from a shown step (None: none)
        self.debugger: Any = None
        self._source = session.source()
        self._inspectors: dict[int, InspectorPanel] = {}
        self._stop = threading.Event()
        self._player = threading.Thread(target=self._play_loop, name="bbzide-replay", daemon=True)
        self._build_gui()
        self.watch_book = WatchBook()
        self.watches = WatchPanel(self.server, self.watch_book, self._robot_ids)
        self._watch_generation = self.watch_book.generation
        with self.server.gui.add_folder("Stigmergy", order=2.6, expand_by_default=False):
            self.stigmergy = self.server.gui.add_markdown("*no stigmergy yet*")
        self.server.on_client_connect(self._on_client_connect)
        self.server.on_client_disconnect(self._on_client_disconnect)

    @property
    def url(self) -> str:
        """The address to open, with the launch's token."""
        return page_url(self.server, self.token)

    def start(self) -> ReplayApp:
        # One robot's warm-up now, before the page is announced: it pays the process's one-off
        # costs (a fresh process's first rebuild loads compiled VM functions: ~0.5 s), so no
        # click waits for them; the other robots warm up in the background.
        self.session.warm_up(self._stop, count=1)
        self.seek(self.session.first_step)
        self._player.start()
        threading.Thread(target=self.session.warm_up, args=(self._stop,),
                         name="bbzide-replay-warm-up", daemon=True).start()
        return self

    def stop(self, wait_for_run: bool = False) -> None:
        """Stop serving; the player thread gets 5 s to end its current frame, or with
        `wait_for_run` all it takes (a first rebuild may be compiling VM functions)."""
        self._stop.set()
        try:
            if self._player.is_alive():
                self._player.join(timeout=None if wait_for_run else 5)
        finally:
            self.server.stop()

    # ---- layout ----------------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui = self.server.gui
        session = self.session
        recording = session.recording
        meta = recording.meta
        with gui.add_folder("Replay", order=1):
            self.status_line = gui.add_markdown("*loading…*")
            self.slider = gui.add_slider(
                "Step", min=session.first_step, max=session.last_step, step=1,
                initial_value=session.first_step)
            self.transport = gui.add_button_group("Play", ("▶ Play", "❚❚ Pause"))
            self.stepper = gui.add_button_group("Step", ("−1", "+1"))
            self.speed_choice = gui.add_dropdown("Speed", tuple(SPEEDS), initial_value="1×")
            self.break_line = gui.add_number(
                "Break at line", initial_value=0, min=0, step=1,
                hint="A line of the recorded program (0: none); the button below seeks to the "
                     "next step in which a robot runs it")
            self.break_robots = gui.add_text(
                "Break for robots", initial_value="",
                hint="Robot ids, comma-separated (empty: any robot)")
            self.seek_hit = gui.add_button("Seek to the next hit",
                                           icon=viser.Icon.PLAYER_SKIP_FORWARD)
            self.debug_forward = gui.add_button_group(
                "Debug", tuple(FORWARD),
                hint="Step the selected robot (else the one stopped) from the shown step: "
                     "Continue to the breakpoint line above, Over / Into / Out of a call, one "
                     "VM Instruction; the recorded steps are re-executed on a scratch copy")
            self.debug_backward = gui.add_button_group(
                "Back", tuple(BACKWARD),
                hint="Step back one line or one control step, or to the previous hit")
            self.debug_where = gui.add_markdown("")
            self.jumps = {}
            for kind, label in session.jump_kinds():
                count = len(session.event_steps(kind))
                self.jumps[kind] = gui.add_button_group(
                    f"{label} ({count})", ("◀ previous", "next ▶"), disabled=count == 0)
        with gui.add_folder("View", order=2, expand_by_default=False):
            links = gui.add_checkbox("Radio links", initial_value=self.scene.show_links)
            ranges = gui.add_checkbox("Radio ranges", initial_value=self.scene.show_ranges)
            trails = gui.add_checkbox("Trails", initial_value=self.scene.show_trails)
            overlays = gui.add_checkbox("World overlays", initial_value=True)
        links.on_update(lambda _: self.scene.set_toggles(links=links.value))
        ranges.on_update(lambda _: self.scene.set_toggles(ranges=ranges.value))
        trails.on_update(lambda _: self.scene.set_toggles(trails=trails.value))
        overlays.on_update(lambda _: self.overlays.set_visible(bool(overlays.value)))
        panel = gui.add_panel()
        with panel.add_tab("Mission", icon=viser.Icon.INFO_CIRCLE):
            truncated = (" · **cut off** (the recorder did not finish; shown up to its last "
                         "flushed step)" if recording.truncated else "")
            gui.add_markdown(
                f"**{html.escape(recording.path.name)}** · world `{meta['world']}` · "
                f"{meta['robots']} robots · seed {meta['seed']} · steps "
                f"{session.first_step}..{session.last_step}{truncated}")
            choices = session.event_choices()
            self._event_steps = dict(choices)
            if choices:  # a dropdown: choosing an event seeks to its step
                self.event_choice = gui.add_dropdown(
                    "Go to event", (NO_EVENT, *self._event_steps), initial_value=NO_EVENT)
                self.event_choice.on_update(lambda _: self._event_chosen())
            else:
                gui.add_markdown("**Events**: *none*")
        source = session.source()
        with panel.add_tab("Program", icon=viser.Icon.CODE):
            self.source_view = gui.add_html(source_view_html(source))
        panel.dock_left()
        panel.set_width(SOURCE_PANEL_WIDTH)
        self.slider.on_update(lambda _: self._slider_moved())
        self.transport.on_click(lambda event: self._transport(event.target.value))
        self.stepper.on_click(lambda event: self.step_by(-1 if "−" in event.target.value else 1))
        self.speed_choice.on_update(
            lambda _: setattr(self, "speed", SPEEDS.get(str(self.speed_choice.value), 1.0)))
        self.seek_hit.on_click(lambda _: self.seek_next_hit(int(self.break_line.value),
                                                            str(self.break_robots.value)))
        self.debug_forward.on_click(lambda event: self.debug(
            FORWARD[event.target.value], self._selected(event.client)))
        self.debug_backward.on_click(lambda event: self.debug(
            BACKWARD[event.target.value], self._selected(event.client)))
        for kind, group in self.jumps.items():
            group.on_click(lambda event, kind=kind: self.jump(kind, "next" in event.target.value))

    def _on_client_connect(self, client: viser.ClientHandle) -> None:
        inspector = InspectorPanel(client)
        self._inspectors[client.client_id] = inspector
        inspector.deselect.on_click(lambda _: self._select(client, None))
        self.scene.aim_camera(client)

    def _on_client_disconnect(self, client: viser.ClientHandle) -> None:
        self._inspectors.pop(client.client_id, None)
        self.scene.forget_client(client.client_id)

    # ---- time ------------------------------------------------------------------------------------
    def seek(self, step: int, stepping: bool = False) -> None:
        """Show `step` everywhere: scene, slider, status line, every tab's inspector (a seek
        ends stepping, unless `stepping` moves the timeline along with it)."""
        session = self.session
        step = max(session.first_step, min(session.last_step, int(step)))
        started = time.perf_counter()
        with self._lock:
            if not stepping and (self.debugger is not None or step != self.step):
                self._end_stepping()
            self.step = step
            self.note = ""
            frame = session.frame(step)
            self.scene.draw(frame)
            self.overlays.show(session.recording.overlays_at(step) or None,
                               positions=frame.positions)
            if int(self.slider.value) != step:
                self.slider.value = step
            for inspector in list(self._inspectors.values()):
                self._refresh_inspector(inspector)
            self._refresh_watches()
            if not self.playing:  # while playing, the player thread reads it once a second
                self._refresh_stigmergy()
            self._refresh_status()
        self.last_seek_seconds = time.perf_counter() - started

    def _event_chosen(self) -> None:
        step = self._event_steps.get(str(self.event_choice.value))
        if step is not None:
            self.playing = False
            self.seek(step)

    def step_by(self, delta: int) -> None:
        self.playing = False
        self.seek(self.step + delta)

    def jump(self, kind: str, forward: bool) -> None:
        target = self.session.jump(kind, self.step, forward)
        if target is None:
            self.note = f"no {'later' if forward else 'earlier'} {_JUMP_LABELS[kind].lower()}"
            self._refresh_status()
            return
        self.playing = False
        self.seek(target)

    def seek_next_hit(self, line: int, robot_ids: str = "") -> int | None:
        """Seek to the next recorded step in which one of the robots (ids, comma-separated;
        empty: any) runs a statement of `line`; say so when none does."""
        self.playing = False
        try:
            wanted = [int(part) for part in robot_ids.replace(" ", "").split(",") if part]
        except ValueError:
            self.note = "robot ids are whole numbers, comma-separated"
            self._refresh_status()
            return None
        ids = [int(i) for i in self.session.recording.meta["robot_ids"]]
        unknown = [i for i in wanted if i not in ids]
        if line < 1 or unknown:
            self.note = (f"no robot {unknown[0]} in this recording" if unknown
                         else "choose a line to break at")
            self._refresh_status()
            return None
        robots = [ids.index(i) for i in wanted] or None
        found = self.session.next_hit(line, self.step, robots)
        if found is None:
            self.note = (f"no robot runs line {line} in the next "
                         f"{MAX_HIT_SEARCH_STEPS} recorded steps")
            self._refresh_status()
            return None
        step, index = found
        self.seek(step)
        self.note = f"line {line} run by robot {ids[index]} in this step"
        self._refresh_status()
        for client_id in list(self._inspectors):
            client = self.server.get_clients().get(client_id)
            if client is not None:
                self._select(client, index)
        return step

    # ---- stepping --------------------------------------------------------------------------------
    def debug(self, command: str, robot_index: int | None = None) -> Any:
        """One debugger command (`debug_panel.FORWARD`/`BACKWARD`'s names) on a scratch copy
        of the swarm rebuilt at the shown step (made at the first command after a seek): the
        robot `robot_index`, else the one stopped, else the first with a VM. Its `Stop` or
        None; the Debug line and the Program tab show where it paused."""
        from bbzide.debugger import Breakpoint, DebuggerError
        from bbzide.diagnostics import UserError

        self.playing = False
        with self._lock:
            ids = [int(i) for i in self.session.recording.meta["robot_ids"]]
            try:
                if self.debugger is None:
                    self.debugger = self.session.debugger_at(self.step)
                debugger = self.debugger
                line = int(self.break_line.value)
                wanted = [int(p) for p in str(self.break_robots.value).replace(" ", "")
                          .split(",") if p]
                debugger.breakpoints = [Breakpoint(line, robot=robot) for robot in
                                        (wanted or [None])] if line > 0 else []
                paused = debugger.paused_at
                if robot_index is not None:
                    robot = ids[robot_index]
                elif paused is not None:
                    robot = paused.robot
                else:
                    robot = next(ids[i] for i in range(len(ids)) if self.session.has_vm(i))
                if command == "continue":
                    stop = debugger.run(MAX_HIT_SEARCH_STEPS)
                elif command == "step_back_line":
                    stop = debugger.step_back(robot, "line")
                elif command == "step_back_control_step":
                    stop = debugger.step_back(robot, "control_step")
                elif command == "run_back_to_previous_hit":
                    stop = debugger.run_back_to_previous_hit()
                else:
                    stop = getattr(debugger, command)(robot)
            except ValueError:
                self.note = "robot ids are whole numbers, comma-separated"
                self._refresh_status()
                return None
            except (UserError, DebuggerError) as error:
                # e.g. the recording's end: the scratch copy is dropped (a step it failed in
                # cannot go on) and the next command rebuilds it at the shown step
                self.debugger = None
                self.note = str(error).splitlines()[0]
                self._refresh_status()
                return None
            self.seek(debugger.simulation.step_count, stepping=True)
            self._show_stop(stop)
            return stop

    def _show_stop(self, stop: Any) -> None:
        """The Debug line, the Program tab's mark and the status note for `stop`."""
        if stop is None:
            self.note = "stepping: the robot did not stop (or nothing earlier to go back to)"
            text = ""
            marked = None
        else:
            function = f" in `{stop.frames[0].function}`" if stop.frames else ""
            where = f"line **{stop.line}**" if stop.line else "no source line"
            self.note = (f"robot {stop.robot} paused at line {stop.line} "
                         f"({WHY.get(stop.reason, stop.reason)})")
            text = (f"**Paused:** robot **{stop.robot}** at {where}{function} "
                    f"({WHY.get(stop.reason, stop.reason)}, in recorded step {stop.step + 1}; "
                    "a scratch copy of the swarm)")
            for frame in stop.frames:
                if frame.locals:
                    text += f"  \n`{frame.function}`: " + ", ".join(
                        f"{name} = {html.escape(value)}" for name, value in frame.locals.items())
            if stop.error:
                text += f"  \n**{html.escape(stop.error)}**"
            marked = stop.line
        if self.debug_where.content != text:
            self.debug_where.content = text
        self.source_view.content = source_view_html(self._source, marked)
        self._refresh_status()

    def _end_stepping(self) -> None:
        if self.debugger is None:
            return
        debugger, self.debugger = self.debugger, None
        try:
            debugger.close()  # a control step it holds ends (its thread with it)
        except Exception:  # noqa: BLE001 - a scratch copy: nothing of it is kept
            pass
        self.debug_where.content = ""
        self.source_view.content = source_view_html(self._source)

    def _selected(self, client: viser.ClientHandle | None) -> int | None:
        inspector = None if client is None else self._inspectors.get(client.client_id)
        return None if inspector is None else inspector.selected

    def play(self) -> None:
        if self.step >= self.session.last_step:
            self.seek(self.session.first_step)
        self.playing = True

    def pause(self) -> None:
        self.playing = False
        with self._lock:
            self._refresh_stigmergy()
            self._refresh_status()

    def _transport(self, value: str) -> None:
        if "Play" in value:
            self.play()
        else:
            self.pause()

    def _slider_moved(self) -> None:
        value = int(self.slider.value)
        if value != self.step:
            self.playing = False
            self.seek(value)

    def _play_loop(self) -> None:
        position = float(self.step)
        last = time.monotonic()
        while not self._stop.wait(1.0 / FRAME_HZ):
            self.player_turns += 1
            if self.watch_book.generation != self._watch_generation:
                with self._lock:
                    self._refresh_watches()
            if self.playing and self.player_turns % int(FRAME_HZ) == 0:
                with self._lock:
                    self._refresh_stigmergy()
            now = time.monotonic()
            if not self.playing:
                position, last = float(self.step), now
                continue
            position += (now - last) * self.speed / self.session.step_seconds
            last = now
            if int(position) != self.step:
                if position >= self.session.last_step:
                    position = self.session.last_step
                    self.playing = False
                self.seek(int(position))

    # ---- watches and the stigmergy view ---------------------------------------------------------
    def _robot_ids(self) -> list[int]:
        return [int(i) for i in self.session.recording.meta["robot_ids"]]

    def _refresh_watches(self) -> None:
        """Every watch's series up to the shown step, from the robots rebuilt at each step."""
        book, session = self.watch_book, self.session
        self._watch_generation = book.generation
        watches = book.watches
        session.forget_watches(watches)
        book.clear_samples()
        if watches:
            for step in session.watch_steps(self.step):
                book.sample(step, lambda watch, step=step: self._watch_values(watch, step))
        self.watches.refresh()

    def _watch_values(self, watch: Watch, step: int) -> list[float]:
        try:
            return self.session.watch_values(watch, step)
        except BadWatch:
            raise
        except Exception as error:  # noqa: BLE001 - a damaged keyframe must not stop the replay
            raise BadWatch(f"cannot rebuild the robots at step {step}: {error}") from None

    def _refresh_stigmergy(self) -> None:
        try:
            rows = self.session.stigmergy_versions(self.step, STIGMERGY_ROBOTS)
            text = stigmergy_markdown(rows)
        except Exception as error:  # noqa: BLE001 - a damaged keyframe must not stop the replay
            text = f"*cannot rebuild the robots at step {self.step}: {html.escape(str(error))}*"
        if self.stigmergy.content != text:
            self.stigmergy.content = text

    # ---- inspector -----------------------------------------------------------------------------
    def _on_robot_click(self, client: viser.ClientHandle, index: int) -> None:
        self._select(client, index)

    def _select(self, client: viser.ClientHandle, index: int | None) -> None:
        inspector = self._inspectors.get(client.client_id)
        if inspector is None:
            return
        with self._lock:
            inspector.selected = index
            self.scene.select(client, index)
            self._refresh_inspector(inspector)

    def _refresh_inspector(self, inspector: InspectorPanel) -> None:
        index = inspector.selected
        if index is None:
            inspector.show_nothing("*Click a robot to see its memory at this step.*")
            return
        if not self.session.has_vm(index):
            inspector.show_nothing(f"*robot #{index} has no VM (a passive body)*")
            return
        try:
            view = self.session.inspect(index, self.step)
        except Exception as error:  # noqa: BLE001 - a damaged keyframe must not stop the replay
            inspector.show_nothing(f"*cannot rebuild robot #{index} at step {self.step}: "
                                   f"{html.escape(str(error))}*")
            return
        inspector.refresh(view)

    def _refresh_status(self) -> None:
        session = self.session
        state = "playing" if self.playing else "paused"
        labels = session.labels(self.step)
        failed = int(session.recording.failed[session.recording.row(self.step)].sum())
        parts = [f"**step {self.step}** of {session.first_step}..{session.last_step}", state,
                 f"speed {self.speed:g}×", f"{failed} in error"]
        for name, values in labels.items():
            counts: dict[str, int] = {}
            for value in values:
                if value:
                    counts[value] = counts.get(value, 0) + 1
            if counts:
                parts.append(f"{name}: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
        if self.note:
            parts.append(self.note)
        text = " · ".join(parts)
        if self.status_line.content != text:
            self.status_line.content = text
