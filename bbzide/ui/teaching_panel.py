"""The IDE's teaching controls: the Lessons menu, "Save setup", and `?scenario=` links.

Design: two folders of the control panel, shared by every tab like the run controls (one IDE,
one swarm, one edited file). **Lessons** lists the track (bbzide/lessons/); opening a lesson
switches the editor to the student's work copy of it (created from the starter the first
time; `bbzide.lessons.catalog`), runs the lesson's scenario, and shows its text; **Check** runs
the lesson's automatic check headless on the saved work (`bbzide.lessons.checks.run_check`,
the same as `bbzide lesson N --check`) and shows PASS, or FAIL and what to look at; **Reset
lesson** puts the starter back once the tab that clicked it confirms. **Scenario** says what
the running scenario pins (its title, the step it pauses at, the globals it watches, which
opening it adds to the Watches folder's plots) and saves
the current set-up as a scenario file (`RunController.save_setup`). A link `/?scenario=NAME`
goes through `open_link`, which opens only what `bbzide.ui.scenario_links` allows and shows a
refusal or a schema error as one line here. Every action that compiles or runs the swarm runs
on a worker thread, one at a time, so viser's callbacks and its event loop never wait for a
compile or a check.
"""

from __future__ import annotations

import html
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qs

import viser

from bbzide.diagnostics import UserError
from bbzide.ui.scenario_links import LinkError, resolve_link, scratch_copy
from bbzide.ui.watches import Watch

if TYPE_CHECKING:
    from bbzide.lessons.catalog import Lesson
    from bbzide.lessons.checks import Verdict
    from bbzide.ui.app import IdeApp

#: The dropdown's first entry: no lesson open.
NO_LESSON = "(choose a lesson)"
#: Colours of the check's verdict (the status line's red for errors; a readable green).
PASS_COLOUR, FAIL_COLOUR = "#2b8a3e", "#c92a2a"


class TeachingPanel:
    def __init__(self, server: viser.ViserServer, app: IdeApp,
                 scenario_folder: Path | None = None) -> None:
        from bbzide.lessons import catalog

        self.app = app
        self.scenario_folder = scenario_folder
        self.lesson: Lesson | None = None
        self._busy = threading.Lock()  # one open, check or save at a time
        self._lessons = {lesson_label(each): each for each in catalog.lessons()}
        gui = server.gui
        with gui.add_folder("Lessons", order=2.5):  # after View, before Inspector (3)
            self.choice = gui.add_dropdown("Lesson", (NO_LESSON, *self._lessons),
                                           initial_value=NO_LESSON)
            self.open_button = gui.add_button(
                "Open lesson", icon=viser.Icon.BOOK,
                hint="Edit your copy of the lesson's script (the starter the first time) in the "
                     "lesson's world")
            self.text = gui.add_markdown("*Choose a lesson, then Open lesson.*")
            self.check_button = gui.add_button(
                "Check", icon=viser.Icon.CHECKLIST, color="blue", disabled=True,
                hint="Run the lesson's automatic check on your saved script")
            self.verdict = gui.add_markdown("")
            self.reset_button = gui.add_button(
                "Reset lesson", icon=viser.Icon.RESTORE, disabled=True,
                hint="Put the lesson's starter script back in place of your work")
        with gui.add_folder("Scenario", order=2.6):
            self.about = gui.add_markdown("")
            self.save_path = gui.add_text(
                "Save as", initial_value="",
                hint="A .toml file; a relative path is taken from the edited script's folder")
            self.pin = gui.add_checkbox(
                "Pin robot positions", initial_value=False,
                hint="Save where the robots stand now (else the world places them)")
            self.save_button = gui.add_button(
                "Save setup", icon=viser.Icon.DEVICE_FLOPPY,
                hint="Save world, options, robots, seed, script, steps and watches as a "
                     "scenario file")
            self.message = gui.add_markdown("")
        self.open_button.on_click(lambda _: self._in_background(self._open_chosen))
        self.check_button.on_click(lambda _: self._in_background(self.check))
        self.reset_button.on_click(lambda event: self._confirm_reset(event.client))
        self.save_button.on_click(lambda _: self._in_background(self._save_from_field))
        self._adopt_started_lesson()
        self.refresh()

    # ---- lessons ---------------------------------------------------------------------------------
    def _adopt_started_lesson(self) -> None:
        """`bbzide lesson N` starts the IDE on a work copy: show that lesson as open."""
        from bbzide.lessons import catalog

        path = self.app.session.path
        for label, each in self._lessons.items():
            if catalog.work_path(each).resolve() == path:
                self._show_lesson(each, label)

    def _open_chosen(self) -> None:
        chosen = self._lessons.get(str(self.choice.value))
        if chosen is None:
            self.text.content = "*Choose a lesson in the list first.*"
            return
        self.open_lesson(chosen)

    def open_lesson(self, chosen: Lesson) -> None:
        """Edit the student's work copy of `chosen` in its scenario, and show its text."""
        from bbzide.lessons import catalog

        work = catalog.work_file(chosen)
        self.apply_scenario(chosen.scenario().with_script(work), work)
        self._show_lesson(chosen, lesson_label(chosen))
        self.choice.value = lesson_label(chosen)

    def _show_lesson(self, chosen: Lesson, label: str) -> None:
        self.lesson = chosen
        self.text.content = lesson_markdown(chosen.text)
        self.verdict.content = "*Press Check when your robots do what the objective says.*"
        self.check_button.disabled = self.reset_button.disabled = False
        if not self.save_path.value:
            self.save_path.value = f"{chosen.name}.toml"

    def check(self) -> Verdict | None:
        """Run the open lesson's check on the saved work; show and return its verdict."""
        from bbzide.lessons.checks import run_check

        chosen = self.lesson
        if chosen is None:
            self.verdict.content = "*Open a lesson first.*"
            return None
        self.verdict.content = "*checking…*"
        try:
            verdict = run_check(chosen, self.app.session.path)
        except UserError as error:
            self.verdict.content = failure_line(error.render())
            return None
        self.verdict.content = verdict_markdown(verdict)
        return verdict

    def _confirm_reset(self, client: viser.ClientHandle | None) -> None:
        """Ask in the tab that clicked before the starter replaces the student's work."""
        if client is None or self.lesson is None:
            return
        with client.gui.add_modal("Reset lesson?") as modal:
            client.gui.add_markdown(f"Your script for lesson {self.lesson.number} is replaced "
                                    "by the starter script. This cannot be undone.")
            confirm = client.gui.add_button("Reset to the starter", color="red")
            cancel = client.gui.add_button("Keep my work")

            def reset_and_close(_: object) -> None:
                modal.close()
                self._in_background(self.reset)

            confirm.on_click(reset_and_close)
            cancel.on_click(lambda _: modal.close())

    def reset(self) -> None:
        """Put the open lesson's starter back (the editor shows it at once)."""
        from bbzide.lessons import catalog

        chosen = self.lesson
        if chosen is None:
            return
        catalog.reset_work(chosen)
        self.app.session.reload_from_disk()
        self.verdict.content = "*The starter script is back.*"

    # ---- scenarios -------------------------------------------------------------------------------
    def apply_scenario(self, scenario: Any, script: Path) -> None:
        """Run `scenario` with the editor on `script`: world, robots and seed set (the run
        controls follow), the script compiled for that world, the swarm rebuilt at step 0."""
        controller = self.app.controller
        controller.pause()
        controller.update_settings(world=scenario.world, robots=scenario.robots,
                                   seed=scenario.seed, scenario=scenario)
        controller.flush()  # the compile below is for the new world
        controls = self.app.controls
        controls.world.value = scenario.world  # already applied: the callbacks change nothing
        controls.robots.value = scenario.robots
        controls.seed.value = scenario.seed
        self.app.edit_file(script)
        controller.reset()
        panel = getattr(self.app, "watches", None)
        for name in controller.watches if panel is not None else ():
            panel.add_watch(Watch("expression", name))  # the scenario's globals, from step 0
        controller.play()
        self.refresh()

    def open_link(self, query: str) -> threading.Thread | None:
        """A page address's query: open its `scenario=` (in the background), if any."""
        names = parse_qs(query).get("scenario")
        if not names:
            return None
        return self._in_background(lambda: self._open_link_name(names[-1]))

    def _open_link_name(self, name: str) -> None:
        try:
            target = resolve_link(name, self.scenario_folder)
            if target.lesson is not None:
                self.open_lesson(target.lesson)
            else:
                scenario = target.scenario
                if len(scenario.scripts()) != 1:
                    raise LinkError(f"{scenario.source}: the IDE edits one script and this "
                                    f"scenario runs {len(scenario.scripts())}")
                script = scenario.scripts()[0]
                # a shipped script is edited through a scratch copy (as bbzide ide does)
                edited = scratch_copy(script) if target.shipped else script
                self.lesson = None
                self.check_button.disabled = self.reset_button.disabled = True
                self.text.content = "*Choose a lesson, then Open lesson.*"
                self.apply_scenario(scenario.with_script(edited), edited)
        except UserError as error:
            refusal = f"link {name[:60]!r} not opened: {error.render()}"
            self.message.content = failure_line(refusal)
            self.app.controller.status.notice = f"⚠ {html.escape(refusal)}"  # seen first
            return
        self.message.content = f"Opened `{html.escape(name)}` from the link."

    def _save_from_field(self) -> None:
        text = str(self.save_path.value).strip()
        if not text:
            self.message.content = failure_line("give a file name ending in .toml")
            return
        self.save_setup(Path(text).expanduser())

    def save_setup(self, path: Path) -> Path | None:
        """Save the current set-up as a scenario at `path` (relative: beside the script)."""
        session = self.app.session
        if not path.is_absolute():
            path = session.path.parent / path
        try:
            saved = self.app.controller.save_setup(path, session.path,
                                                   pin_positions=bool(self.pin.value))
        except UserError as error:
            self.message.content = failure_line(error.render())
            return None
        self.message.content = (f"Saved `{html.escape(str(saved))}`: open it with "
                                f"`bbzide ide {html.escape(str(saved))}`")
        return saved

    def refresh(self) -> None:
        """What the running scenario pins (called by the app's ticker)."""
        controller = self.app.controller
        scenario = controller.settings.scenario
        if scenario is None:
            text = "*No scenario: the world's defaults.* Save setup writes one."
        else:
            title = f"**{html.escape(scenario.title)}**  \n" if scenario.title else ""
            steps = controller.scenario_steps
            pause = f"pauses at step {steps}" if steps else "runs on"
            watches = ", ".join(f"`{name}`" for name in controller.watches) or "none"
            text = f"{title}{scenario.robots} robots, seed {scenario.seed}, {pause}; " \
                   f"watches: {watches}"
        if self.about.content != text:
            self.about.content = text

    def _in_background(self, action: Callable[[], object]) -> threading.Thread:
        def run() -> None:
            with self._busy:
                try:
                    action()
                except Exception as error:  # noqa: BLE001 - shown in the panel, not a traceback
                    self.message.content = failure_line(f"{type(error).__name__}: {error}")

        worker = threading.Thread(target=run, name="bbzide-teaching", daemon=True)
        worker.start()
        return worker


def lesson_label(lesson: Lesson) -> str:
    return f"{lesson.number}. {lesson.title}"


def lesson_markdown(text: str) -> str:
    """A lesson's text for the narrow panel: its headings two levels smaller."""
    lines = []
    for line in text.splitlines():
        if line.startswith("#"):
            hashes = len(line) - len(line.lstrip("#"))
            line = "#" * min(hashes + 2, 6) + line[hashes:]
        lines.append(line)
    return "\n".join(lines)


def verdict_markdown(verdict: Verdict) -> str:
    colour, word = (PASS_COLOUR, "PASS") if verdict.passed else (FAIL_COLOUR, "FAIL")
    head = (f"<span style='color:{colour}'>**{word}**</span>: "
            f"{html.escape(verdict.summary)}")
    if not verdict.look_at:
        return head
    return head + "  \nLook at:\n" + "\n".join(f"- {html.escape(line)}"
                                               for line in verdict.look_at)


def failure_line(text: str) -> str:
    return f"<span style='color:{FAIL_COLOUR}'>**{html.escape(text)}**</span>"

