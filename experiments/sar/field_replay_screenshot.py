"""Screenshot of `bbzide replay` on the field run (thesis §5.5) at its last step: the README's
picture of the relay line (root red at the meeting point, networkers green, links orange over
the belief map).

Design: the field preset's first belief trial (sweep seed 2026) is recorded with the command
`bbzide experiment sar` gives for it (`reproduce_command` + `--record`), opened in the replay
app, shown at its last step and photographed in headless Chromium with the browser tests'
helpers (tests/ui/browser.py). The picture is cropped to the scene and the replay controls and
stored as a 256-colour PNG (~30 KB instead of ~160 KB: the scene is flat colours).

    PYTHONPATH=. python experiments/sar/field_replay_screenshot.py [OUT.png]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from PIL import Image

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "ui"))

from browser import (  # noqa: E402 - the browser tests' helpers, found through sys.path
    FIRST_RENDER_TIMEOUT_MS,
    chromium_context,
    free_port,
    wait_until,
)

from bbzide.cli import main  # noqa: E402
from bbzide.recording.reader import read_recording  # noqa: E402
from bbzide.recording.rebuild import RobotRebuilder  # noqa: E402
from bbzide.ui.replay_app import ReplayApp  # noqa: E402
from bbzide.ui.replay_session import ReplaySession  # noqa: E402
from bbzide.worlds import sar_experiment as sx  # noqa: E402

#: A wide page so the floating replay controls do not cover the field; the crop keeps the
#: field and the controls (pixels of the 2,100 x 1,000 page).
PAGE = (2100, 1000)
CROP = (980, 40, 2100, 840)
#: Seconds for software WebGL to draw the frame after the seek (first frames take 3-13 s).
SETTLE_SECONDS = 3.0


def record_field_run(folder: Path) -> Path:
    spec = sx.RunSpec(drones=3, arena=36.0, search="belief", trial=0,
                      seed=sx.run_seed(2026, 3, 36.0, 0), targets=(sx.FIELD_TARGET,),
                      belief_map=str(sx.FIELD_BELIEF), comm_range=sx.FIELD_COMM_RANGE)
    steps = sx.run_one(spec)["steps"]
    path = folder / "field.rrd"
    if main([*sx.reproduce_command(spec, steps), "--record", str(path)]) != 0:
        raise SystemExit("recording the field run failed")
    return path


def screenshot(recording_path: Path, out: Path) -> None:
    recording = read_recording(recording_path)
    app = ReplayApp(ReplaySession(recording, RobotRebuilder(recording)), port=free_port())
    app.start()
    try:
        with chromium_context(*PAGE) as context:
            page = context.new_page()  # type: ignore[attr-defined]
            page.set_default_timeout(FIRST_RENDER_TIMEOUT_MS)
            page.goto(app.url, wait_until="domcontentloaded")
            wait_until(lambda: app.server.get_clients(), 30, message="websocket")
            page.wait_for_selector("canvas")
            next(iter(app.server.get_clients().values())).get_render(height=200, width=300)
            app.seek(recording.last_step)
            time.sleep(SETTLE_SECONDS)
            raw = out.with_suffix(".raw.png")
            page.screenshot(path=str(raw))
    finally:
        app.stop()
    image = Image.open(raw).convert("RGB").crop(CROP)
    image.quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(out, optimize=True)
    raw.unlink()


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name(
        "field-replay.png")
    with tempfile.TemporaryDirectory() as folder:
        screenshot(record_field_run(Path(folder)), target)
    print(f"{target} ({target.stat().st_size / 1e3:.0f} KB)")
