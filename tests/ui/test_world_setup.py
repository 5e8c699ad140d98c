"""What the World setup folder and `bbzide ide X.bzz` set up, on the real worlds: world options
(`--set`), the firmware loop (`--loop`), and an example opened in the scenario beside it."""

from __future__ import annotations

import argparse
from pathlib import Path

from bbzide.ui.commands import example_set_up
from bbzide.ui.world_adapter import WorldsBackend
from bbzide.ui.world_setup_panel import options_text, parse_options_text

REPO = Path(__file__).resolve().parents[2]
BACKEND = WorldsBackend()


def test_world_options_and_the_firmware_loop_reach_the_swarm(tmp_path: Path) -> None:
    """What the World setup folder sends: `--set` options build the world, `--loop robot`
    keeps each step's return value on the stack (the stack grows one slot a step)."""
    path = tmp_path / "loop.bzz"
    text = "function init() { }\nfunction step() { return 7 }\n"
    path.write_text(text)
    _, program = BACKEND.compile(text, path, "kilobot")
    firmware = BACKEND.create("kilobot", program, 2, 0, world_options={"layout": "random"},
                              loop="robot")
    pop = BACKEND.create("kilobot", program, 2, 0)
    assert firmware.sim.world.layout == "random" and pop.sim.world.layout == "lattice"
    depths = []
    for _ in range(3):
        firmware.step()
        pop.step()
        depths.append(int(firmware.robot(0).vm.stackptr))
    assert depths[1] - depths[0] == depths[2] - depths[1] == 1
    assert int(pop.robot(0).vm.stackptr) < depths[0]


def test_the_options_field_reads_what_the_command_line_reads() -> None:
    assert parse_options_text("layout=random, width=0.4 light=spot") == {
        "layout": "random", "width": 0.4, "light": "spot"}
    assert options_text({"layout": "random", "width": 0.4}) == "layout=random width=0.4"


def test_an_example_opens_in_its_own_set_up() -> None:
    """aggregation.bzz does nothing on the default 5 cm lattice (every robot hears two
    neighbours at once): `bbzide ide` opens it in aggregation.toml's scattered layout."""
    plain = argparse.Namespace(world=None, robots=None)
    aggregation = REPO / "examples" / "kilobot" / "aggregation.bzz"
    assert example_set_up(aggregation, plain) == aggregation.with_suffix(".toml")
    chosen = argparse.Namespace(world="kilobot", robots=None)
    assert example_set_up(aggregation, chosen) is None  # the command line chose the world
    assert example_set_up(REPO / "examples" / "sar" / "belief_keys.bzz", plain) is None
