"""The swarm debugger: breakpoints, source-level stepping, pause on error and reverse stepping
for a whole swarm of BittyBuzz robots in a world (`bbzide.worlds.engine.Simulation`).

    from bbzide.debugger import Breakpoint, SwarmDebugger
    debugger = SwarmDebugger(simulation)
    debugger.breakpoints = [Breakpoint(20, robot=3, condition="heard > 1", hit_count=2)]
    stop = debugger.run(max_steps=100)        # Stop | None
    stop = debugger.step_over(stop.robot)     # also step_into, step_out, step_instruction
    stop = debugger.step_back(stop.robot, unit="line")    # or unit="control_step"
    stop = debugger.run_back_to_previous_hit()
    debugger.evaluate(stop.robot, "size(neighbors_seen) + gradient")
    debugger.frames(stop.robot)               # [Frame(function, line, locals)], innermost first

API (robots are named by robot id; every command returns the `Stop` it ended at or None):
`Breakpoint(line, path=None, robot=None, condition=None, hit_count=None)`; `Stop(robot, step,
pc, line, column, reason, frames, error, breakpoint, instructions)` with reason "breakpoint",
"step", "error" or "pause"; `Frame(function, line, locals, host)`; `SwarmDebugger(simulation)`
with `breakpoints` (settable; each checked: `DebuggerError`, one line), `paused_at`,
`pause_on_error`, `run(max_steps)`, `step_over/step_into/step_out/step_instruction(robot)`,
`step_back(robot, unit)`, `run_back_to_previous_hit()`, `evaluate(robot, expression)`,
`frames(robot)`, `hits(breakpoint)`, `request_pause()` (from another thread).

What "paused mid-step" means. A control step is: sense, deliver the radio's messages, every
robot's turn (its in-queue with the listeners, `step`, its out-queue), the radio, the physics.
When the debugger stops robot R before one of its instructions (or right after the
instruction that failed), the swarm is inside R's turn: every robot has already *received*
this step's messages (they wait in its in-queue; neighbour tables are updated), the robots
whose turn comes before R's (lower index; in an asynchronous run, earlier phase) have finished
their turn, R has run up to the instruction shown, and the robots after R have not started
theirs. Nothing of the step after the turns has happened: what the robots sent this step is
not on the air yet, and no robot has moved. Sensor readings are this step's. Going on from
the stop finishes the step exactly as an uninterrupted run would have (`turn_observer` runs
the same turns in the same order; the traced robots run the VM's reference mode, which leaves
the same bytes as the fast one).

Reverse stepping restores a checkpoint taken at the start of a control step (every
`TRACED_CHECKPOINT_EVERY` traced steps, every `CHECKPOINT_EVERY` steps of the fast path) and
re-executes forward to the instruction wanted: the swarm, the world and the robots' heaps are
byte for byte as they were the first time (hit counts of breakpoints are restored with them).
Breakpoints stop robots in their control steps: code that runs only at boot (the top level,
`init`) is refused as a breakpoint line.

Cost: with no breakpoint and nothing being stepped `run` is the engine's fast step plus a
checkpoint every `CHECKPOINT_EVERY` steps; with breakpoints the robots they can stop run one
instruction at a time in the VM's reference mode (`benchmarks/debugger_bench.py`).
"""

from bbzide.debugger.swarm_debugger import (
    CHECKPOINT_EVERY,
    REASONS,
    Breakpoint,
    DebuggerError,
    Frame,
    Stop,
    SwarmDebugger,
)

__all__ = ["CHECKPOINT_EVERY", "REASONS", "Breakpoint", "DebuggerError", "Frame", "Stop",
           "SwarmDebugger"]
