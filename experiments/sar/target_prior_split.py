"""Why the belief search does not win every pair: split a finished `bbzide experiment sar`
folder by where the targets lie in the prior belief map.

Design: a run's belief map and targets are a pure function of its seed (`M300Field.attach`
draws them from `default_rng([seed, 0x300])`), so they are redrawn here with the world's own
functions rather than stored per run. A pair is "all likely" when every target lies in a cell
whose prior reaches the search threshold (20 %): the cells the belief search samples first; else
at least one target sits where the belief search rejects goals until the rest of the map has
been lowered below the threshold. For each group: pairs, median find time per search, pairs the
belief search won, sign test.

    PYTHONPATH=. python experiments/sar/target_prior_split.py SWEEP_FOLDER [SWEEP_FOLDER...]
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

import numpy as np

from bbzide.worlds.m300 import (
    DEFAULT_CELLS,
    DEFAULT_THRESHOLD,
    LAUNCH_STRIP,
    draw_targets,
    generate_belief_map,
)
from bbzide.worlds.sar_experiment import TARGETS, sign_test


def least_likely_prior(seed: int, arena: float, targets_where: str = "anywhere") -> float:
    """The prior of the least likely target's cell, as the world drew map and targets."""
    rng = np.random.default_rng([int(seed), 0x300])
    belief = generate_belief_map(DEFAULT_CELLS, rng)
    floor = DEFAULT_THRESHOLD / 100 if targets_where == "likely" else 0.0
    targets = draw_targets(belief, arena, TARGETS, rng, keep_out=LAUNCH_STRIP + 1.0,
                           floor=floor)
    cells = np.clip((targets / arena * DEFAULT_CELLS).astype(int), 0, DEFAULT_CELLS - 1)
    return float(belief[cells[:, 1], cells[:, 0]].min())


def split(folder: Path) -> None:
    pairs: dict[tuple, dict[str, dict]] = {}
    for path in sorted((folder / "runs").glob("*.json")):
        run = json.loads(path.read_text())
        pairs.setdefault((run["arena"], run["drones"], run["trial"]), {})[run["search"]] = run
    groups: dict[str, list[tuple[int, int]]] = {"all targets likely": [],
                                                "a target under the threshold": []}
    for (arena, _, _), pair in sorted(pairs.items()):
        if set(pair) != {"random", "belief"} or min(
                r["found_all_step"] for r in pair.values()) < 0:
            continue
        prior = least_likely_prior(pair["belief"]["seed"], arena,
                                   pair["belief"].get("targets_where", "anywhere"))
        likely = prior >= DEFAULT_THRESHOLD / 100
        group = "all targets likely" if likely else "a target under the threshold"
        groups[group].append((pair["random"]["found_all_step"], pair["belief"]["found_all_step"]))
    print(f"{folder}:")
    for name, found in groups.items():
        if not found:
            continue
        wins = sum(b < r for r, b in found)
        losses = sum(b > r for r, b in found)
        print(f"  {name:30} {len(found):4} pairs: median find random "
              f"{statistics.median(r for r, _ in found):6g}, belief "
              f"{statistics.median(b for _, b in found):6g}; belief faster in {wins}, slower "
              f"in {losses} (sign test p = {sign_test(wins, losses):.2g})")


if __name__ == "__main__":
    for name in sys.argv[1:]:
        split(Path(name))
