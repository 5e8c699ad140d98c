"""Where the time to find all targets goes, per run of one sweep configuration: rerun each
pair of a finished `bbzide experiment sar` folder step by step and trace it.

Design: a run is a pure function of its spec (seed, world options), so the pairs are rerun here
with the sweep's own `RunSpec` and program rather than recorded during the sweep. Per run it
logs the step each target was first seen, which drone saw it, how many goals that drone had
started by then (its leg: 0 = the first goal after takeoff) and whether any drone had already
ended a 20-goal run (flown back to the rendezvous) before the last find; per pair, how many
drones started from the same first goal under both searches (each drone has its own random
stream and the belief search only draws again when it rejects a goal). The summary says which
part of the find time is fixed (the 5 m climb at 1 m/s: 50 steps), which the first leg, and
which the search after it.

    PYTHONPATH=. python experiments/sar/where_time_goes.py SWEEP_FOLDER DRONES ARENA [TRIALS]
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

import numpy as np

from bbzide.worlds.engine import Simulation
from bbzide.worlds.sar_experiment import RunSpec, _program

#: Steps after which a trace gives up (the sweeps' longest 20 m runs end well before).
TRACE_LIMIT = 5000
#: M300Field.mode of a drone in the air (takeoff sets the goal straight above it, so every
#: later change of the goal's x, y is a goal of the script: search, rendezvous or relay).
FLYING = 1


def trace(spec: RunSpec) -> dict:
    """Find step, finder's leg and role for each target, first goals, rendezvous before the end."""
    sim = Simulation("m300", _program(), robots=spec.drones, seed=spec.seed,
                     world_options=spec.world_options())
    world = sim.world
    legs = np.zeros(spec.drones, dtype=int)
    goals = world.goals.copy()
    first_goals: list = [None] * spec.drones
    seen_before = world.found_step.copy()
    finds = []
    rendezvous_before_last = False
    while sim.step_count < TRACE_LIMIT and not (world.found_step >= 0).all():
        sim.step()
        airborne = world.mode == FLYING
        changed = (np.abs(world.goals[:, :2] - goals[:, :2]).sum(axis=1) > 1e-9) & airborne
        for i in np.nonzero(changed & (legs == 0))[0]:
            if first_goals[i] is None:
                first_goals[i] = tuple(np.round(world.goals[i, :2], 3))
        legs += changed
        goals = world.goals.copy()
        rendezvous_before_last |= "rendezvous" in world.roles
        footprints = world._footprints(sim)
        for k in np.nonzero((world.found_step >= 0) & (seen_before < 0))[0]:
            finder = int(np.nonzero(footprints[:, k])[0][0])
            finds.append({"step": sim.step_count, "target": int(k), "leg": int(legs[finder]) - 1,
                          "role": world.roles[finder]})
        seen_before = world.found_step.copy()
    return {"finds": finds, "first_goals": first_goals,
            "rendezvous_before_last": bool(rendezvous_before_last)}


def main(folder: Path, drones: int, arena: float, trials: int | None) -> None:
    pairs: dict[int, dict[str, dict]] = {}
    for path in sorted((folder / "runs").glob(f"d{drones}_a{arena:g}_*.json")):
        run = json.loads(path.read_text())
        pairs.setdefault(run["trial"], {})[run["search"]] = run
    chosen = sorted(t for t, p in pairs.items() if set(p) == {"random", "belief"})[:trials]
    summary: dict[str, list] = {"random": [], "belief": []}
    same_first = []
    for trial in chosen:
        traces = {}
        for search in ("random", "belief"):
            run = pairs[trial][search]
            spec = RunSpec(drones, arena, search, trial, run["seed"],
                           targets_where=run.get("targets_where", "anywhere"))
            traces[search] = trace(spec)
            last = traces[search]["finds"][-1]
            summary[search].append((last["step"], last["leg"],
                                    traces[search]["rendezvous_before_last"]))
            print(f"t{trial:03d} {search:6} find {last['step']:5}  "
                  + "  ".join(f"{f['step']}@leg{f['leg']}" for f in traces[search]["finds"])
                  + ("  (after a rendezvous)" if traces[search]["rendezvous_before_last"] else ""))
        same = sum(a == b and a is not None for a, b in zip(traces["random"]["first_goals"],
                                                            traces["belief"]["first_goals"],
                                                            strict=True))
        same_first.append(same)
    print(f"\n{drones} drones, {arena:g} m, {len(chosen)} pairs ({folder}):")
    for search, rows in summary.items():
        steps = [r[0] for r in rows]
        first_leg = sum(r[1] == 0 for r in rows)
        after_rendezvous = sum(r[2] for r in rows)
        print(f"  {search:6}: median find {statistics.median(steps)}; last target found on the "
              f"finder's first goal in {first_leg}/{len(rows)} runs; after a drone's return to "
              f"the rendezvous in {after_rendezvous}/{len(rows)}")
    print(f"  drones whose first goal is the same under both searches: median "
          f"{statistics.median(same_first)} of {drones}; 50 of the steps are the climb to 5 m")


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]),
         int(sys.argv[4]) if len(sys.argv) > 4 else None)
