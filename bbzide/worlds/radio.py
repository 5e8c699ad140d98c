"""Radio model: who hears whom in one control step.

Design: positions live in one (n, 3) numpy array; neighbour search bins robots into a uniform
grid whose cell side is the communication range, so each robot is compared only with the robots
of its own and the 26 (3D) adjacent cells instead of all n (the Kilobot table must scale to
1,000 robots). Loss is one Bernoulli draw per candidate link from the radio's own
`numpy.random.Generator`, seeded from the run seed, so a run is reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bbzide.diagnostics import UserError


class WorldConfigError(UserError):
    """A world or radio parameter the user gave is out of range (e.g. a negative range)."""


@dataclass(frozen=True, slots=True)
class RadioLinks:
    """Directed links (sender -> receiver) of one step, with the sender-receiver distance."""

    senders: np.ndarray    # int64 robot indices
    receivers: np.ndarray  # int64 robot indices
    distances: np.ndarray  # float64 metres


def pairs_within_range(positions: np.ndarray, comm_range: float) -> RadioLinks:
    """Every ordered pair (i, j), i != j, with |p_i - p_j| <= comm_range (grid-binned search)."""
    if comm_range < 0:
        raise WorldConfigError(f"communication range must be >= 0, got {comm_range}")
    points = np.asarray(positions, dtype=np.float64)
    empty = np.empty(0, dtype=np.int64)
    if len(points) < 2 or comm_range == 0:
        return RadioLinks(empty, empty, np.empty(0))
    cells = np.floor(points / comm_range).astype(np.int64)
    order = np.lexsort(cells.T[::-1])
    sorted_cells = cells[order]
    keys, starts, counts = np.unique(sorted_cells, axis=0, return_index=True, return_counts=True)
    where = {tuple(k): (s, c) for k, s, c in zip(keys.tolist(), starts, counts, strict=True)}
    senders: list[np.ndarray] = []
    receivers: list[np.ndarray] = []
    offsets = [(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)]
    for key, start, count in zip(keys.tolist(), starts, counts, strict=True):
        mine = order[start:start + count]
        for dx, dy, dz in offsets:
            other = where.get((key[0] + dx, key[1] + dy, key[2] + dz))
            if other is None:
                continue
            theirs = order[other[0]:other[0] + other[1]]
            gaps = np.linalg.norm(points[mine][:, None, :] - points[theirs][None, :, :], axis=2)
            i, j = np.nonzero((gaps <= comm_range) & (mine[:, None] != theirs[None, :]))
            senders.append(mine[i])
            receivers.append(theirs[j])
    if not senders:
        return RadioLinks(empty, empty, np.empty(0))
    s = np.concatenate(senders)
    r = np.concatenate(receivers)
    d = np.linalg.norm(points[s] - points[r], axis=1)
    return RadioLinks(s, r, d)


def drop_lost(links: RadioLinks, loss_probability: float, rng: np.random.Generator) -> RadioLinks:
    """Keep each link independently with probability 1 - loss_probability."""
    if not 0.0 <= loss_probability <= 1.0:
        raise WorldConfigError(f"loss probability must be in [0, 1], got {loss_probability}")
    kept = rng.random(len(links.senders)) >= loss_probability
    return RadioLinks(links.senders[kept], links.receivers[kept], links.distances[kept])
