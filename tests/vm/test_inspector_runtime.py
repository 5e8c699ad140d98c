"""Inspector data of a running robot: stigmergy, neighbors, swarms, queues, stack growth of
the robot loop, globals by name, memory figures and the last error."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from test_robot import PINGPONG, exchange, program  # noqa: E402

from bbzide.vm.inspector import inspect_robot  # noqa: E402
from bbzide.vm.profiles import KILOBOT, PC  # noqa: E402
from bbzide.vm.robot import Robot  # noqa: E402


def test_stigmergy_and_neighbors_after_an_exchange() -> None:
    for profile, distance in ((KILOBOT, 10), (PC, 10.0)):
        robots, _ = exchange(profile)
        view = inspect_robot(robots[1])
        assert [(e.key, e.value, e.timestamp, e.robot) for e in view.stigmergy] == \
            [("leader", "7", 1, 0)]
        assert [(n.robot, n.distance) for n in view.neighbors] == [(0, distance)]
        # robot 0's last broadcast and stigmergy query wait for the next step, by priority
        assert [m[0] for m in view.queues.incoming] == [0, 2]
        assert view.queues.outgoing == ()
        assert view.globals["heard"] == "2"  # two of robot 0's pings processed so far
        assert view.memory.used_bytes + view.memory.free_bytes == profile.heap_size
        assert view.memory.peak_bytes >= view.memory.used_bytes
        assert view.last_error is None


def test_queued_messages_are_shown_as_wire_bytes() -> None:
    r = Robot(program(PINGPONG), KILOBOT, 4, {"log": lambda call: None})
    r.boot()
    ping = r.program.string_id("ping")
    message = bytes([0, 2, 0, ping, 0, 0x09, 5, 0])
    r.receive(message, 3.0, 0.0, 0.0)
    view = inspect_robot(r)
    assert view.queues.incoming == (message,)
    assert view.queues.in_capacity == KILOBOT.in_queue_cap
    assert [n.robot for n in view.neighbors] == [2]


def test_swarm_membership_and_swarm_stack() -> None:
    src = """
    seen = -1
    function init() {
      s = swarm.create(3)
      s.join()
      t = swarm.create(5)
      t.join()
      t.leave()
    }
    function step() { s.exec(function() { seen = swarm.id() }) }
    """
    r = Robot(program(src), PC, 0)
    r.boot()
    r.control_step()
    view = inspect_robot(r)
    assert view.swarms.member_of == (3,)
    assert view.swarms.executing == ()
    assert view.globals["seen"] == "3"


def test_robot_loop_stack_growth_is_visible() -> None:
    r = Robot(program("function step() { return 1 }"), KILOBOT, 0, loop="robot")
    r.boot()
    depths = []
    for _ in range(3):
        r.control_step()
        depths.append(inspect_robot(r).stack.depth)
    assert depths == [1, 2, 3]


def test_last_error_is_reported() -> None:
    r = Robot(program("function step() { x = swarm.create(12) }"), PC, 0)
    r.boot()
    r.control_step()
    view = inspect_robot(r)
    assert view.state == "ERROR"
    assert view.last_error is not None and "SWARM" in view.last_error
