"""The field run (thesis §5.5: 36 m field, 3 drones, 1 target, fixed belief map), recorded with
`bbzide run ... --record` from the command the experiment gives for it, and replayed.

One live run of the field preset's first belief trial goes until the relay line is complete
(as `bbzide experiment sar --preset field` runs it), noting each drone's exact VM state at a few
steps. The experiment's `reproduce_command` for that run, plus `--record`, must then record the
same mission: same poses, the target found at the same step, the roles and relay links of the
line at the end, role colours on the LEDs, and a robot rebuilt from the recording byte-identical
to the live VM at the sampled steps (one of them while the root runs its auction).
"""

from __future__ import annotations

import random
import zlib
from pathlib import Path

import numpy as np
import pytest

from bbzide.cli import main
from bbzide.recording.reader import read_recording
from bbzide.recording.rebuild import RobotRebuilder
from bbzide.vm.robot import Robot
from bbzide.worlds import sar_experiment as sx
from bbzide.worlds.engine import Simulation
from bbzide.worlds.m300 import ROLE_COLOURS

#: The field preset's first trial of sweep seed 2026 (any seed forms the line; this one does
#: so in ~700 steps, ~3 s live and ~4 s recorded).
SPEC = sx.RunSpec(drones=3, arena=36.0, search="belief", trial=0,
                  seed=sx.run_seed(2026, 3, 36.0, 0), targets=(sx.FIELD_TARGET,),
                  belief_map=str(sx.FIELD_BELIEF), comm_range=sx.FIELD_COMM_RANGE)
#: The line must form well before this (the 6 field runs we measured took 530-1,220 steps).
MAX_STEPS = 3000


def vm_state(robot: object) -> tuple:
    vm = robot.vm  # type: ignore[attr-defined]
    heap = vm.heap
    return (bytes(heap.data), heap.rtobj, heap.ltseg, vm.pc, vm.stackptr,
            list(vm.stack[: vm.stackptr + 1]), zlib.crc32(Robot.comparable(robot.snapshot())))  # type: ignore


@pytest.fixture(scope="module")
def field(tmp_path_factory: pytest.TempPathFactory) -> dict:
    sim = Simulation("m300", sx._program(), robots=SPEC.drones, seed=SPEC.seed,
                     world_options=SPEC.world_options())
    world = sim.world
    positions, roles = {0: sim.positions.copy()}, {0: list(world.roles)}
    auction_step = -1
    while sim.step_count < MAX_STEPS:
        sim.step()
        positions[sim.step_count] = sim.positions.copy()
        roles[sim.step_count] = list(world.roles)
        if auction_step < 0 and "auctioneer" in world.roles:
            auction_step = sim.step_count
        if (sim.step_count % sx.CHECK_PERIOD == 0 and (world.found_step >= 0).all()
                and world.relay_complete(sim)):
            break
    last = sim.step_count
    assert world.relay_complete(sim) and not sim.failures
    # Sampled steps: the auction's first step, the end, and a few random ones.
    rng = random.Random(7)
    sampled = sorted({auction_step, last, *(rng.randint(1, last) for _ in range(3))})
    # A second live run to the sampled steps for the VM states (a recorder is not attached,
    # so this is the experiment's run exactly; copying 3 x 60 KB heaps at every step would not).
    again = Simulation("m300", sx._program(), robots=SPEC.drones, seed=SPEC.seed,
                       world_options=SPEC.world_options())
    states = {}
    for step in sampled:
        again.run(step - again.step_count)
        states[step] = [vm_state(s.robot) for s in again.robots]
    path = tmp_path_factory.mktemp("field") / "field.rrd"
    command = sx.reproduce_command(SPEC, last)
    assert main([*command, "--record", str(path)]) == 0
    return {"recording": read_recording(path), "positions": positions, "roles": roles,
            "found": int(world.found_step[0]), "last": last, "states": states,
            "auction_step": auction_step, "links": world.relay_links()}


def test_the_recorded_command_replays_the_experiment_run(field: dict) -> None:
    recording, last = field["recording"], field["last"]
    assert (recording.first_step, recording.last_step, recording.robot_count) == (0, last, 3)
    for step in range(0, last + 1, 37):
        np.testing.assert_allclose(recording.positions[recording.row(step)],
                                   field["positions"][step], atol=1e-4)
        assert list(recording.labels["role"][recording.row(step)]) == field["roles"][step]
    targets = [e for e in recording.events if e.kind == "target"]
    assert [e.step for e in targets] == [field["found"]]


def test_replay_shows_the_relay_line_and_role_colours(field: dict) -> None:
    recording, last = field["recording"], field["last"]
    overlays = recording.overlays_at(last)
    roles = overlays["roles"]
    assert sorted(roles) == ["networker", "networker", "root"]
    root = roles.index("root")
    # The links form one line: each networker relays for the root or for the other networker.
    links = {child: parent for child, parent in overlays["relay_links"]}
    assert [tuple(link) for link in overlays["relay_links"]] == field["links"]
    assert set(links) == {i for i, r in enumerate(roles) if r == "networker"}
    for child in links:
        hops, node = 0, child
        while node != root and hops < 3:
            node, hops = links[node], hops + 1
        assert node == root
    assert overlays["targets_found"] == [True]
    leds = recording.leds[recording.row(last)]
    for robot, role in enumerate(roles):
        assert np.allclose(leds[robot] / 255, ROLE_COLOURS[role], atol=1 / 255)
    changes = {e.text.rsplit(" ", 1)[-1] for e in recording.events if e.kind == "role"}
    assert {"root_candidate", "auctioneer", "networker_bidder", "networker"} <= changes


def test_rebuilt_drone_vm_is_byte_identical_to_the_live_one(field: dict) -> None:
    rebuilder = RobotRebuilder(field["recording"])
    assert field["auction_step"] in field["states"]
    for step, live in field["states"].items():
        for index in range(3):
            assert vm_state(rebuilder.robot_at(index, step)) == live[index], (index, step)


def test_reproduce_command_sets_every_world_option() -> None:
    command = sx.reproduce_command(SPEC, 10)
    options = dict(item.split("=", 1) for item in command[command.index("--set") + 1::2])
    assert options["targets"] == "26:24" and options["comm_range"] == "15"
    assert Path(options["belief_map"]) == sx.FIELD_BELIEF
    assert command[command.index("--seed") + 1] == str(SPEC.seed)


def test_replay_app_draws_role_colours_and_the_relay_tree(field: dict) -> None:
    """What `bbzide replay field.rrd` puts in the scene at the last step (no browser needed:
    the viser scene nodes are the page's content)."""
    from bbzide.ui.replay_app import ReplayApp
    from bbzide.ui.replay_session import ReplaySession

    recording, last = field["recording"], field["last"]
    app = ReplayApp(ReplaySession(recording, RobotRebuilder(recording)), port=0)
    try:
        app.seek(last)
        roles = recording.overlays_at(last)["roles"]
        colours = np.asarray(app.scene._robots.batched_colors)  # type: ignore[union-attr]
        for robot, role in enumerate(roles):
            assert np.allclose(colours[robot] / 255, ROLE_COLOURS[role], atol=2 / 255), role
        handles = app.overlays._handles
        assert {"/overlays/relay_links", "/overlays/belief_map", "/overlays/targets"} <= set(
            handles)
        drawn = np.asarray(handles["/overlays/relay_links"].points)[:, :, :2]
        at = recording.positions[recording.row(last), :, :2]
        np.testing.assert_allclose(drawn, [[at[c], at[p]] for c, p in field["links"]],
                                   atol=1e-4)
        app.seek(field["found"] - 1)              # before the find: no tree, nobody a root
        assert "/overlays/relay_links" not in app.overlays._handles
    finally:
        app.server.stop()
