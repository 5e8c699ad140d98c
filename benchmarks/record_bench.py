"""Recording cost, file size and seek latency of mission recordings, against their goals.

    python benchmarks/record_bench.py [--robots 25] [--steps 1000] [--toy] [--world kilobot]
                                      [--script X.bzz] [--set KEY=VALUE]...

The reference mission the goals are set for (25 drones x 5,000 steps of search and rescue):

    python benchmarks/record_bench.py --world m300 --script examples/sar/sar.bzz --steps 1000

Runs a swarm in a world for `--steps` steps while recording it, and prints:
* recording overhead: time spent in `MissionRecorder.record_step` (and closing the file) plus
  what capturing the inputs adds to the simulation (the same swarm unrecorded, built with the
  engine's own robot factory and stepped in turn with the recorded one), as a share of the
  unrecorded simulation's time (goal: <= 10 %), in wall-clock time, in the process's CPU time
  per part, and in CPU time with Rerun's own threads counted whole (the main thread's CPU time
  per part plus every other thread's over the run: the process's CPU time of a part also holds
  what those threads did meanwhile, so their work during the steps lands in both swarms' times);
* file size, and the size extrapolated to 25 robots x 5,000 steps (goal: <= 50 MB);
* seek latency in the replay: frame lookup + rebuilding one robot's VM at random steps
  (keyframe + re-executed inputs) + decoding it for the inspector, median and worst (goal:
  <= 100 ms);
* read time of the whole file (paid once when a replay opens), and the replay's warm-up.

With `--toy` the robots run `ToyRobot` (tests/recording/doubles.py: no Buzz VM) instead of the
world's example on the real VM, which isolates the recorder's own cost.
"""

from __future__ import annotations

import argparse
import gc
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: The reference mission the goals are set for: 25 robots for 5,000 steps.
TARGET_ROBOTS, TARGET_STEPS = 25, 5000
#: Random seeks measured (each rebuilds the robot from its keyframe: no cache help).
SEEKS = 40


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="kilobot")
    parser.add_argument("--script", type=Path, default=None)
    parser.add_argument("--robots", type=int, default=25)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--toy", action="store_true", help="toy firmware instead of the VM")
    parser.add_argument("--keyframe-every", type=int, default=None,
                        help="the recorder's step bound between keyframes (default: its own)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="world option (as `bbzide run --set`)")
    args = parser.parse_args()

    import random

    from bbzide.recording.reader import read_recording
    from bbzide.recording.rebuild import RobotRebuilder
    from bbzide.recording.recorder import KEYFRAME_BUDGET_SECONDS, MissionRecorder, Recordable
    from bbzide.ui.replay_session import ReplaySession
    from bbzide.worlds.commands import load_script, parse_world_options
    from bbzide.worlds.engine import Simulation
    from bbzide.worlds.registry import WORLDS

    spec = WORLDS[args.world]
    script = args.script or REPO / spec.example
    program = load_script(script, spec.host_names, [])
    build = None
    if args.toy:
        from tests.recording.doubles import ToyRobot

        build = ToyRobot
    recordable = Recordable(build=build)
    options = parse_world_options(args.set)
    sim = Simulation(spec.name, program, robots=args.robots, seed=1, world_options=options,
                     robot_factory=recordable.factory, watch=() if args.toy else ("role",))
    # The same swarm without recording, for the reference simulation time: built the plain
    # way (the engine's own robot factory: no host-function taps, no recording hooks), so
    # whatever a recordable swarm costs more counts as recording cost. It steps in turn
    # with the recorded one (one step each, in alternating order), so a change of the
    # machine's load hits both.
    plain = Simulation(spec.name, program, robots=args.robots, seed=1, world_options=options,
                       robot_factory=None if build is None else build,
                       watch=() if args.toy else ("role",))
    Simulation(spec.name, program, robots=2, seed=1, world_options=options).run(3)  # JIT warm-up

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.rrd"
        started = time.perf_counter()
        extra = {} if args.keyframe_every is None else {"keyframe_every": args.keyframe_every}
        recorder = MissionRecorder(path, sim, recordable, **extra)
        setup = time.perf_counter() - started
        # Wall-clock and CPU seconds (the process's: Rerun encodes and writes in threads of
        # its own) of: the unrecorded steps, the recorded steps (input capture), the recorder.
        # The process's CPU time of a part holds whatever Rerun's threads did meanwhile, so
        # their work during the steps of either swarm lands in both simulations' times; the
        # main thread's CPU time per part (`thread_time`) and every other thread's over the
        # whole run count them whole instead.
        wall = [0.0, 0.0, 0.0]
        cpu = [0.0, 0.0, 0.0]
        own = [0.0, 0.0, 0.0]
        clocks = (time.perf_counter, time.process_time, time.thread_time)

        def timed(part: int, action: Callable[[], object]) -> None:
            w, c, t = (clock() for clock in clocks)
            action()
            wall[part] += time.perf_counter() - w
            cpu[part] += time.process_time() - c
            own[part] += time.thread_time() - t

        run_cpu, run_own = time.process_time(), time.thread_time()

        for step in range(args.steps):
            # Whichever swarm steps second in a pair runs ~5 % slower (measured both ways, on
            # the same swarm): alternate, so that bias cancels out of the capture's share.
            if step % 2 == 0:
                timed(0, plain.step)
                timed(1, sim.step)
            else:
                timed(1, sim.step)
                timed(0, plain.step)
            timed(2, recorder.record_step)
        timed(2, recorder.close)
        time.sleep(0.2)  # the writer thread finishes the last flush
        others = (time.process_time() - run_cpu) - (time.thread_time() - run_own)
        keyframes = sum(recorder._keyframe_counts.values())
        size = path.stat().st_size
        # A replay process holds the recording, not the simulations: drop them, so that the
        # garbage collector's full passes during seeks walk what a replay would have.
        del sim, plain, recorder, recordable
        gc.collect()
        t0 = time.perf_counter()
        recording = read_recording(path)
        read_seconds = time.perf_counter() - t0
        session = ReplaySession(recording, RobotRebuilder(recording, build=build))

        seek_cpu: list[float] = []

        def seek(index: int, step: int) -> float:
            t0, c0 = time.perf_counter(), time.process_time()
            session.frame(step)
            if args.toy:  # the toy has no Buzz heap to decode
                session.rebuilder.robot_at(index, step)
            else:  # what the replay does for a selected robot: rebuild + inspector view
                session.inspect(index, step)
            seek_cpu.append(time.process_time() - c0)
            return time.perf_counter() - t0

        rng = random.Random(1)
        # What the replay app runs in the background when it opens: boots every robot's
        # rebuild robot and re-executes its first keyframe span once (which loads the compiled
        # VM functions a replay uses from numba's cache: a one-off of the process), gc.freeze.
        t0, c0 = time.perf_counter(), time.process_time()
        session.warm_up()
        warm_wall, warm_cpu = time.perf_counter() - t0, time.process_time() - c0
        # Then the first click on each robot (the rebuild robot is booted, its cache holds
        # the end of its first span).
        first = [seek(index, rng.randint(recording.first_step, recording.last_step))
                 for index in range(args.robots)]
        latencies = []
        seek_cpu.clear()
        for _ in range(SEEKS):
            step = rng.randint(recording.first_step, recording.last_step)
            index = rng.randrange(args.robots)
            session.rebuilder._cache.clear()  # a cold seek: keyframe + inputs every time
            latencies.append(seek(index, step))

    steps = args.steps
    scale = (TARGET_ROBOTS * TARGET_STEPS) / (args.robots * steps)
    firmware = "toy firmware" if args.toy else f"{script.name} on the VM"
    print(f"{args.world}, {args.robots} robots x {steps} steps, {firmware}")
    for name, (plain_seconds, sim_seconds, recorder_seconds) in (("wall-clock", wall),
                                                                  ("CPU", cpu)):
        capture = sim_seconds - plain_seconds
        cost = recorder_seconds + capture
        print(f"{name} time: simulation {1e3 * plain_seconds / steps:.2f} ms/step without "
              f"recording ({steps / plain_seconds:.1f} steps/s), {1e3 * sim_seconds / steps:.2f} "
              f"with input capture ({100 * capture / plain_seconds:+.1f} %)")
        print(f"  recording: {1e3 * recorder_seconds / steps:.2f} ms/step in the recorder "
              f"{1e3 * capture / steps:+.2f} of input capture = {1e3 * cost / steps:.2f} ms/step "
              f"= {100 * cost / plain_seconds:.1f} % of the simulation time (goal <= 10 %)")
    plain_seconds, sim_seconds, recorder_seconds = own
    cost = recorder_seconds + (sim_seconds - plain_seconds) + others
    print(f"CPU time, other threads counted whole: simulation {1e3 * plain_seconds / steps:.2f} "
          f"ms/step (main thread); recording: {1e3 * recorder_seconds / steps:.2f} ms/step in "
          f"the recorder {1e3 * (sim_seconds - plain_seconds) / steps:+.2f} of input capture + "
          f"{1e3 * others / steps:.2f} in Rerun's threads = {1e3 * cost / steps:.2f} ms/step = "
          f"{100 * cost / plain_seconds:.1f} % of the simulation time")
    print(f"(plus {setup:.2f} s once at the start: stream, first keyframes); {keyframes} "
          f"keyframes = one per robot every {args.robots * steps / max(keyframes, 1):.0f} steps")
    print(f"file:       {size / 1e6:.2f} MB = {size / (args.robots * steps):.0f} B per robot-step;"
          f" 25 x 5,000 extrapolated linearly: {size * scale / 1e6:.1f} MB (goal <= 50 MB)")
    print(f"open:       {read_seconds:.2f} s to read the whole file")
    print(f"seek:       median {1e3 * statistics.median(latencies):.1f} ms, worst "
          f"{1e3 * max(latencies):.1f} ms over {SEEKS} cold seeks of booted robots (goal <= "
          f"100 ms; keyframe every {recording.meta['keyframe_every']} steps"
          f" or {1e3 * KEYFRAME_BUDGET_SECONDS:.0f} ms of VM CPU time);"
          f" CPU time median {1e3 * statistics.median(seek_cpu):.1f} ms, worst "
          f"{1e3 * max(seek_cpu):.1f} ms")
    print(f"warm-up:    {warm_wall:.2f} s wall, {warm_cpu:.2f} s CPU (background, when a replay"
          f" opens: boots every robot's rebuild and re-executes its first span once)")
    print(f"first seek of each robot after the warm-up: median {1e3 * statistics.median(first):.1f}"
          f" ms, worst {1e3 * max(first):.1f} ms")


if __name__ == "__main__":
    main()
