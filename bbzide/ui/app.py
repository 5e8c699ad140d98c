"""The IDE, wired together: one viser server, one editor, one program, one running swarm.

    browser tab ──(viser websocket)──▶ RunControls, SwarmScene clicks, InspectorPanel (per tab)
         └──<iframe /editor/>──(editor websocket)──▶ ProgramSession ──compile──▶ RunController
    FileWatcher (external saves) ──────────▶ ProgramSession.reload_from_disk
    RunController thread ──frames (≤30 Hz)──▶ SwarmScene.draw
    ticker thread (4 Hz) ──▶ status line, build view, each tab's inspector (under the run lock)
    TeachingPanel: Lessons and Scenario folders; a page request `/?scenario=` ──▶ open_link
    editor gutter ──breakpoints──▶ BreakpointBook ──▶ RunController ──stop──▶ paused line in the
         editor, pc in the Build listing, the stopped robot selected, its frames in Stack

`IdeApp` only connects the parts; each part lives in its own module. Everything is served on one
port, behind one check of every request (`bbzide.ui.viser_server`, `bbzide.ui.access`).
"""

from __future__ import annotations

import html
import threading
import time
from dataclasses import replace
from pathlib import Path

import viser

from bbzide.compiler.call_sites import lint_globals, robot_phrase
from bbzide.ui.access import new_token
from bbzide.ui.breakpoints import BreakpointBook
from bbzide.ui.build_panel import footprint_markdown, listing_html
from bbzide.ui.controls import RunControls
from bbzide.ui.debug_panel import DebugControls
from bbzide.ui.editor_server import EDITOR_PATH, editor_routes
from bbzide.ui.file_watcher import FileWatcher
from bbzide.ui.inspector_panel import InspectorPanel
from bbzide.ui.overlay_view import OverlayView
from bbzide.ui.pitfalls import find_pitfalls
from bbzide.ui.program_session import CompileOutcome, Diagnostic, ProgramSession
from bbzide.ui.run_controller import STOP_WAIT_S, RunController, RunSettings, StepInProgress
from bbzide.ui.scene import SwarmScene
from bbzide.ui.teaching_panel import TeachingPanel
from bbzide.ui.viser_server import open_server, page_url
from bbzide.ui.watches import (
    STIGMERGY_ROBOTS,
    WatchBook,
    WatchPanel,
    stigmergy_markdown,
)
from bbzide.ui.world_backend import SimulationHandle, SwarmFrame, WorldBackend
from bbzide.ui.world_setup_panel import WorldSetupPanel

#: How often the status line and inspectors refresh: 4 Hz reads as "live" and costs little.
TICK_SECONDS = 0.25
#: Width of the editor panel: ~70 columns of 13 px monospace plus the line-number gutter.
EDITOR_PANEL_WIDTH = 600
#: World overlays (light field, belief map, targets) are re-read every 4 ticks (1 s): they
#: change slowly and the Kilobot light raster costs 1,024 evaluations.
OVERLAY_TICKS = 4
#: How long an inspector refresh may wait for the current step to end before skipping a tick.
INSPECT_LOCK_TIMEOUT = 0.2
class IdeApp:
    def __init__(
        self,
        source_path: Path,
        backend: WorldBackend,
        settings: RunSettings,
        host: str = "127.0.0.1",
        port: int = 8080,
        token: str | None = None,
        scenario_folder: Path | None = None,
    ) -> None:
        self.backend = backend
        self.token = token or new_token()
        self.controller = RunController(backend, settings)
        self.session = ProgramSession(
            source_path, self._compile, self.controller.load_program, lint_fn=self._pitfalls
        )
        self.breakpoints = BreakpointBook(on_change=self.controller.set_breakpoints)
        self.server = open_server(
            host, port, self.token,
            replace(editor_routes(self.session, lambda: self.controller.settings.world,
                                  self.breakpoints, self._paused_in_editor),
                    on_visit=self._on_visit),
        )
        self.scene = SwarmScene(self.server, on_robot_click=self._on_robot_click)
        self.overlays = OverlayView(self.server)
        self._overlay_ticks = 0
        self.controls = RunControls(self.server, self.controller, self.scene, backend.world_names())
        self.controls.world.on_update(lambda _: self._change_world(str(self.controls.world.value)))
        self.world_setup = WorldSetupPanel(self.server, self.controller, self.scene,
                                           self.controls.world)
        self.controls.record.on_update(lambda _: self._toggle_recording(self.controls.record.value))
        self.controls.load_example.on_click(lambda _: self.load_world_example())
        self.controls.overlays.on_update(
            lambda _: self.overlays.set_visible(bool(self.controls.overlays.value))
        )
        self.teaching = TeachingPanel(self.server, self, scenario_folder)
        self.debug = DebugControls(self.server, self.controller, self._robot_to_step)
        self.watch_book = WatchBook(
            on_first=lambda: self.controller.add_step_listener(self._sample_watches),
            on_empty=lambda: self.controller.remove_step_listener(self._sample_watches))
        self.watches = WatchPanel(self.server, self.watch_book, self._robot_ids)
        with self.server.gui.add_folder("Stigmergy", order=2.6, expand_by_default=False):
            self.stigmergy = self.server.gui.add_markdown("*no stigmergy yet*")
        self._stops_shown = 0
        self._listing_pc: int | None = None
        self._inspectors: dict[int, InspectorPanel] = {}
        self._world_generation = -1
        self._build_dirty = True
        self._stop = threading.Event()
        self._ticker = threading.Thread(
            target=self._tick_loop, name="bbzide-ui-ticker", daemon=True
        )
        self.watcher = FileWatcher(source_path, self._reload_from_disk)
        self._build_gui()
        self.controller.add_frame_listener(self._on_frame)
        self.session.add_listener(self._on_compiled)
        self.server.on_client_connect(self._on_client_connect)
        self.server.on_client_disconnect(self._on_client_disconnect)

    # ---- lifetime ------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The address to open, with the launch's token."""
        return page_url(self.server, self.token)

    @property
    def editor_url(self) -> str:
        """The editor frame's address as the page at `url` loads it (no token: the cookie)."""
        return self.url.partition("?")[0].rstrip("/") + EDITOR_PATH

    def start(self, run: bool = True) -> IdeApp:
        self.controller.start()
        self.watcher.start()
        self.session.compile_now()  # first program -> controller builds the world
        if run:
            self.controller.play()
        self._ticker.start()
        return self

    def stop(self, wait_for_run: bool = False) -> None:
        """Stop serving; the run thread gets `STOP_WAIT_S` to end its current step, or with
        `wait_for_run` all it takes. A KeyboardInterrupt during that wait cuts it short and
        still stops the server, then goes on up."""
        self._stop.set()
        self.watcher.stop()
        try:
            self.controller.stop(None if wait_for_run else STOP_WAIT_S)
        finally:
            if self._ticker.is_alive():
                self._ticker.join(timeout=5)
            self.server.stop()

    # ---- layout --------------------------------------------------------------------------------
    def _build_gui(self) -> None:
        gui = self.server.gui
        panel = gui.add_panel()
        with panel.add_tab(self.session.path.name, icon=viser.Icon.CODE):
            gui.add_html(  # relative: the frame comes from wherever the page came from
                f'<iframe src="{EDITOR_PATH}" title="Buzz editor" '
                'class="bbzide-editor" style="width:100%;height:calc(100vh - 140px);border:0;'
                'display:block"></iframe>'
            )
        with panel.add_tab("Build", icon=viser.Icon.FILE_CODE):
            self.footprint = gui.add_markdown("*not compiled yet*")
            self.step_instruction = gui.add_button(
                "Step one instruction", icon=viser.Icon.ARROW_BAR_TO_DOWN,
                hint="Run one VM instruction of the selected (else the stopped) robot; its pc "
                     "is highlighted below")
            self.step_instruction.on_click(
                lambda event: self.debug.command("step_instruction", event.client))
            self.listing = gui.add_html("")
        panel.dock_left()
        panel.set_width(EDITOR_PANEL_WIDTH)

    def _on_client_connect(self, client: viser.ClientHandle) -> None:
        self._inspectors[client.client_id] = inspector = InspectorPanel(client)
        inspector.deselect.on_click(lambda _: self._select(client, None))
        self.scene.aim_camera(client)

    def _on_client_disconnect(self, client: viser.ClientHandle) -> None:
        self._inspectors.pop(client.client_id, None)
        self.scene.forget_client(client.client_id)

    # ---- program -------------------------------------------------------------------------------
    def _compile(self, text: str, path: Path) -> tuple[object, object]:
        return self.backend.compile(text, path, self.controller.settings.world)

    def _pitfalls(self, text: str, program: object) -> list[Diagnostic]:
        """BittyBuzz pitfalls of the text and the globals it uses but nothing defines."""
        world = self.controller.settings.world
        platform = self.backend.platform(world)
        found = find_pitfalls(text, floats_supported=bool(getattr(platform, "float_ops", True)))
        names = getattr(self.backend, "host_names", None)  # not every backend names them
        if names is None:
            return found
        undefined = lint_globals(program, names(world), robot_phrase(world))
        return found + [Diagnostic(where.line, where.col, message, "warning")
                        for where, message in undefined if where.file == str(self.session.path)]

    def _toggle_recording(self, on: bool) -> None:
        if not on:
            self.controller.set_recording(None)
            return
        self.controller.set_recording(new_recording_path(self.session.path), self.session.text)

    def _reload_from_disk(self) -> None:
        self.session.reload_from_disk()

    def edit_file(self, path: Path) -> None:
        """Edit `path` from now on (a lesson's work copy, a linked scenario's script)."""
        self.watcher.stop()
        self.session.switch_file(path)
        self.watcher = FileWatcher(self.session.path, self._reload_from_disk).start()

    def _on_visit(self, query: str) -> threading.Thread | None:
        """The page was opened with a query: a `?scenario=` link (`TeachingPanel.open_link`)."""
        teaching = getattr(self, "teaching", None)  # a request may beat the panel's creation
        return None if teaching is None else teaching.open_link(query)

    def _on_compiled(self, outcome: CompileOutcome) -> None:
        self._build_dirty = True
        if outcome.ok:
            self.breakpoints.program_compiled(outcome.revision, outcome.program)

    def _change_world(self, world: str) -> None:
        if world == self.controller.settings.world:
            return
        self.controller.update_settings(world=world, robots=self.backend.default_robots(world),
                                        world_options={})
        self.controls.robots.value = self.backend.default_robots(world)
        self.session.compile_now()  # host functions differ per platform

    def load_world_example(self) -> bool:
        """Put the current world's example into the editor (saved and compiled like an edit);
        False when the world has none."""
        # the dropdown's world: the controller applies a world change on its own thread
        example = self.backend.example_path(str(self.controls.world.value))
        if example is None or not example.is_file():
            self.controller.status.error = "this world has no example script"
            return False
        self.session.edit_from_browser(example.read_text(encoding="utf-8"))
        return True

    def _refresh_build_view(self) -> None:
        self._build_dirty = False
        good = self.session.last_good
        outcome = self.session.outcome
        note = ""
        if outcome is not None and not outcome.ok:
            first = outcome.diagnostics[0] if outcome.diagnostics else None
            where = f"line {first.line}:{first.col}: {html.escape(first.message)}" if first else ""
            note = (
                f"\n\n⚠ **the current text does not compile** ({where}); "
                "the robots run the last good program."
            )
        if good is None:
            self.footprint.content = "*no successful compile yet*" + note
            self.listing.content = ""
            return
        world = self.controller.settings.world
        platform = self.backend.platform(world)
        budget = getattr(platform, "flash_budget", None)
        if budget is None and hasattr(self.backend, "flash_budget"):
            budget = self.backend.flash_budget(world)
        name = getattr(platform, "name", world)
        self.footprint.content = (
            footprint_markdown(good.compiled, good.program, name, budget) + note
        )
        paused = self.controller.status.paused_at
        self._listing_pc = paused.pc if paused is not None else None
        self.listing.content = listing_html(
            good.compiled, good.program, self.session.text, self.session.path, self._listing_pc
        )

    # ---- frames and selection -------------------------------------------------------------------
    def _on_frame(self, frame: SwarmFrame) -> None:
        """From the simulation thread: redraw the world after a rebuild, then the robots."""
        with self.controller.locked() as sim:
            generation = id(sim)
            if sim is not None and generation != self._world_generation:
                self._world_generation = generation
                geometry = sim.geometry()
                self.scene.set_world(geometry, frame.positions)
                self.overlays.set_scale(geometry.robot_radius)
        self.scene.draw(frame)
        self.world_setup.draw(frame)

    def _on_robot_click(self, client: viser.ClientHandle, index: int) -> None:
        self._select(client, index)

    def _select(self, client: viser.ClientHandle, index: int | None) -> None:
        inspector = self._inspectors.get(client.client_id)
        if inspector is None:
            return
        inspector.selected = index
        self.scene.select(client, index)
        self._refresh_inspector(inspector)

    def _refresh_inspector(self, inspector: InspectorPanel) -> None:
        index = inspector.selected
        if index is None:
            inspector.show_nothing("*Click a robot to inspect its memory.*")
            return
        try:
            with self.controller.locked(timeout=INSPECT_LOCK_TIMEOUT) as sim:
                if sim is None:
                    inspector.show_nothing("*no running world*")
                    return
                if index >= sim.frame().count:
                    inspector.show_nothing(f"*robot #{index} is gone (fewer robots now)*")
                    return
                view = sim.inspect(index)
        except StepInProgress:
            return  # keep the last view; the status line says a step is running long
        view.warnings = self._program_warnings() + view.warnings
        inspector.refresh(view, self.controller.status.paused_at)

    def _refresh_overlays(self) -> None:
        try:
            with self.controller.locked(timeout=INSPECT_LOCK_TIMEOUT) as sim:
                read = getattr(sim, "overlays", None)
                overlays = read() if read is not None else None
        except StepInProgress:
            return
        frame = self.controller.last_frame
        self.overlays.show(overlays, positions=None if frame is None else frame.positions)

    def _refresh_runtime_errors(self) -> None:
        """The swarm's failures in this file, grouped by place, as the editor's runtime markers
        (for the revision of the program the robots run)."""
        good = self.session.last_good
        try:
            with self.controller.locked(timeout=INSPECT_LOCK_TIMEOUT) as sim:
                read = getattr(sim, "runtime_errors", None)
                found = read() if read is not None else []
        except StepInProgress:
            return
        path = str(self.session.path)
        markers = [
            Diagnostic(where.line, where.col, message, "runtime", robots)
            for where, message, robots in found
            if where is not None and where.file == path
        ]
        self.session.set_runtime_errors(good.revision if good is not None else -1, markers)

    def _program_warnings(self) -> list[str]:
        """The running program's compiler warnings and pitfalls, as `line:col: message`."""
        good = self.session.last_good
        if good is None:
            return []
        return [
            f"{d.line}:{d.col}: {d.message}" for d in good.diagnostics if d.severity == "warning"
        ]

    # ---- debugger --------------------------------------------------------------------------------
    def _robot_to_step(self, client: viser.ClientHandle | None) -> int | None:
        """The robot a step command from `client`'s tab applies to: the one its inspector
        shows, else (None) the one the debugger stopped."""
        inspector = None if client is None else self._inspectors.get(client.client_id)
        return None if inspector is None else inspector.selected

    def _paused_in_editor(self) -> dict[str, object] | None:
        """Where the editor marks the paused line: the line of the program the robots run."""
        paused = self.controller.status.paused_at
        good = self.session.last_good
        if paused is None or paused.line is None or good is None:
            return None
        return {"line": paused.line, "robot": paused.robot_id, "reason": paused.reason,
                "revision": good.revision}

    def _show_stop(self) -> None:
        """A new stop: every tab selects the stopped robot; the listing marks its pc."""
        self._stops_shown = self.controller.status.stops
        paused = self.controller.status.paused_at
        if paused is None:
            return
        for client_id, inspector in list(self._inspectors.items()):
            client = self.server.get_clients().get(client_id)
            if client is not None and inspector.selected != paused.robot_index:
                self._select(client, paused.robot_index)

    # ---- watches and stigmergy -------------------------------------------------------------------
    def _sample_watches(self, sim: SimulationHandle) -> None:
        """After every step (simulation thread, run lock held): read every watch."""
        read = getattr(sim, "watch_values", None)
        if read is not None:
            self.watch_book.sample(sim.step_count, read)

    def _robot_ids(self) -> list[int]:
        frame = self.controller.last_frame
        return [] if frame is None else list(frame.robot_ids)

    def _refresh_stigmergy(self) -> None:
        try:
            with self.controller.locked(timeout=INSPECT_LOCK_TIMEOUT) as sim:
                read = getattr(sim, "stigmergy_versions", None)
                rows = read(STIGMERGY_ROBOTS) if read is not None else []
        except StepInProgress:
            return
        text = stigmergy_markdown(rows)
        if self.stigmergy.content != text:
            self.stigmergy.content = text

    # ---- ticker ----------------------------------------------------------------------------------
    def _tick_loop(self) -> None:
        while not self._stop.wait(TICK_SECONDS):
            try:
                self._tick()
            except Exception as error:  # noqa: BLE001 - the ticker must survive a bad frame
                self.controller.status.error = f"display: {type(error).__name__}: {error}"

    def _tick(self) -> None:
        outcome = self.session.outcome
        note = ""
        if outcome is not None and not outcome.ok and self.controller.has_program:
            note = "⚠ editor text has errors: robots keep running the last good program"
        self.controls.refresh_status(note)
        self.teaching.refresh()
        self.debug.refresh(self.breakpoints.items)
        if self.controller.status.stops != self._stops_shown:
            self._show_stop()
        paused = self.controller.status.paused_at
        if self._build_dirty or (paused.pc if paused else None) != self._listing_pc:
            self._refresh_build_view()
        self._overlay_ticks += 1
        if self._overlay_ticks % OVERLAY_TICKS == 1:
            self._refresh_overlays()
            self._refresh_stigmergy()
        self.watches.refresh()
        self._refresh_runtime_errors()
        busy_since = self.controller.status.step_started_at
        step_is_long = (
            busy_since is not None and time.monotonic() - busy_since > INSPECT_LOCK_TIMEOUT
        )
        for inspector in list(self._inspectors.values()):
            if inspector.selected is not None and not step_is_long:
                self._refresh_inspector(inspector)


def new_recording_path(script: Path) -> Path:
    """`<script folder>/recordings/<script>-<date>-<time>.rrd`, never an existing file."""
    folder = script.parent / "recordings"
    folder.mkdir(exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = folder / f"{script.stem}-{stamp}.rrd"
    suffix = 1
    while path.exists():
        suffix += 1
        path = folder / f"{script.stem}-{stamp}-{suffix}.rrd"
    return path
