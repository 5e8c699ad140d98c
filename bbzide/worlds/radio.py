"""Radio model: who hears whom in one control step.

Design: positions live in one (n, 3) numpy array; neighbour search bins robots into a uniform
grid whose cell side is the communication range, so each robot is compared only with the robots
of its own and the 26 (3D) adjacent cells instead of all n (the Kilobot table must scale to
1,000 robots). Loss is one Bernoulli draw per candidate link from the radio's own
`numpy.random.Generator`, seeded from the run seed, so a run is reproducible.

`Radio` routes the messages of a whole swarm for the engine: each sender has a send queue
(capacity `send_queue_cap`, overflow dropped and counted) drained by at most
`messages_per_step` transmissions per control step (bandwidth); every transmission reaches each
robot in range independently unless lost (a fixed probability, or one that grows with the
sender's broadcast rate over the last second, the Crazyflie's BLE); the situated data (distance,
azimuth, elevation, with Gaussian noise) are fixed at transmission time from the geometry and the
message arrives `latency_steps` later. Deliveries are ordered by receiver, then sender, then
message, so the order a VM sees is reproducible.

In lockstep the messages never become Python objects one by one: the send queues are one
`PackedMessages` table (`bbzide.vm.swarm_batch`: a row per message — sender, payload bytes,
wire length —, sorted by sender, each sender's rows in queue order), a step's transmissions
are its first `messages_per_step` rows per sender, and the deliveries are rows gathered from
them by index (receiver, sender, payload, situated data), sorted by receiver: what the engine
hands to `swarm_batch.control_steps` as it is. Ranks within a sender or a receiver come from
`group_ranks` over the sorted columns, counters from `np.bincount`. The loss and noise draws
are the same calls, in the same order, as the tuple-per-message radio it replaced (kept as a
test oracle: `tests/worlds/reference_radio.py`), so a seed gives the same run.

Asynchronous robots (the engine's `asynchronous=True`): real robots do not step in lockstep;
each has its own phase within the control period. Then the engine calls `begin_step` (the
step's links and situated data, computed once), `send_from(sender, time)` right after each
robot's control step, in phase order, and `take_due(receiver, time)` before each; a message
sent at time t (in steps, phase included) reaches a receiver at its first control step after
t + latency_steps - 1, i.e. within the same step when the receiver's phase is later.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bbzide.diagnostics import UserError

if TYPE_CHECKING:
    from bbzide.vm.swarm_batch import PackedMessages
    from bbzide.worlds.world import RadioSettings


class WorldConfigError(UserError):
    """A world or radio parameter the user gave is out of range (e.g. a negative range)."""


@dataclass(frozen=True, slots=True)
class RadioLinks:
    """Directed links (sender -> receiver) of one step, with the sender-receiver distance."""

    senders: np.ndarray    # int64 robot indices
    receivers: np.ndarray  # int64 robot indices
    distances: np.ndarray  # float64 metres


#: Up to this many robots `pairs_within_range` compares every robot's cell with every
#: other's (an n x n test) instead of the grid's 9-27 searchsorted passes: measured on a
#: loaded machine, 10-64 robots ~0.1-0.35 ms against ~0.4-0.9 ms; at 100 the two are even.
ALL_PAIRS_MAX = 64


def pairs_within_range(positions: np.ndarray, comm_range: float) -> RadioLinks:
    """Every ordered pair (i, j), i != j, with |p_i - p_j| <= comm_range (grid-binned search).

    Each robot's cell gets one integer key (cells padded by one on every side so that a
    neighbouring cell's key never aliases another row); robots are sorted by key and, for each
    of the 27 neighbour offsets (9 when every robot is in one z layer), `searchsorted` finds the
    run of robots in that cell. Everything is numpy: no Python loop over robots or cells.
    """
    if comm_range < 0:
        raise WorldConfigError(f"communication range must be >= 0, got {comm_range}")
    points = np.asarray(positions, dtype=np.float64)
    empty = np.empty(0, dtype=np.int64)
    n = len(points)
    if n < 2 or comm_range == 0:
        return RadioLinks(empty, empty, np.empty(0))
    cells = np.floor(points / comm_range).astype(np.int64)
    if n <= ALL_PAIRS_MAX:
        return _pairs_in_adjacent_cells(points, cells, comm_range)
    cells -= cells.min(axis=0)
    cells += 1
    dims = cells.max(axis=0) + 2
    keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    z_offsets = (0,) if dims[2] == 3 else (-1, 0, 1)
    senders: list[np.ndarray] = []
    receivers: list[np.ndarray] = []
    distances: list[np.ndarray] = []
    everyone = np.arange(n)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in z_offsets:
                shifted = keys + (dx * dims[1] + dy) * dims[2] + dz
                low = np.searchsorted(sorted_keys, shifted, side="left")
                counts = np.searchsorted(sorted_keys, shifted, side="right") - low
                total = int(counts.sum())
                if total == 0:
                    continue
                mine = np.repeat(everyone, counts)
                first = np.repeat(low - (np.cumsum(counts) - counts), counts)
                theirs = order[first + np.arange(total)]
                gaps = np.linalg.norm(points[mine] - points[theirs], axis=1)
                keep = (gaps <= comm_range) & (mine != theirs)
                senders.append(mine[keep])
                receivers.append(theirs[keep])
                distances.append(gaps[keep])
    return RadioLinks(np.concatenate(senders), np.concatenate(receivers),
                      np.concatenate(distances))


def hop_counts(positions: np.ndarray, comm_range: float, source: int = 0) -> list[int]:
    """Hops from robot `source` to every robot over the links within `comm_range` (-1: not
    connected): what a hop-count gradient converges to on a still swarm."""
    links = pairs_within_range(positions, comm_range)
    hops = [-1] * len(positions)
    hops[source] = 0
    queue = deque([source])
    while queue:
        sender = queue.popleft()
        for receiver in links.receivers[links.senders == sender].tolist():
            if hops[receiver] < 0:
                hops[receiver] = hops[sender] + 1
                queue.append(receiver)
    return hops


def _pairs_in_adjacent_cells(points: np.ndarray, cells: np.ndarray,
                             comm_range: float) -> RadioLinks:
    """`pairs_within_range` for a small swarm: every ordered pair at once, kept by the
    grid search's own two tests (cells at most one apart on each axis — what its 27 cell
    offsets reach —, then the distance, computed by the same expression): the same pairs
    and distances, in sender-major order instead of cell-offset order (callers sort them)."""
    near = (np.abs(cells[:, None, :] - cells[None, :, :]) <= 1).all(axis=2)
    np.fill_diagonal(near, False)
    mine, theirs = np.nonzero(near)
    gaps = np.linalg.norm(points[mine] - points[theirs], axis=1)
    keep = gaps <= comm_range
    return RadioLinks(mine[keep], theirs[keep], gaps[keep])


#: Skin of `NeighbourCache`, a fraction of the range: candidates are the pairs within
#: range * (1 + NEIGHBOUR_SKIN) when the list is built, good until some robot has moved half
#: the skin. A quarter of the range lets a Kilobot (1 cm/s, 10 cm range) go ~12 steps between
#: rebuilds for ~1.6x the candidates of an exact search.
NEIGHBOUR_SKIN = 0.25


class NeighbourCache:
    """`pairs_within_range` for bodies that move little per step (a Verlet neighbour list).

    The grid search costs ~6 ms a step for 1,000 Kilobots; yet a robot moves a millimetre a
    step against a 10 cm range. So the search runs with the range grown by a skin, and its
    pairs are kept as candidates; each step only the candidates' distances are computed (the
    same expression as the search's, so the same pairs and distances come out), until some
    robot has moved further than half the skin from where it was at the search (then no
    pair now within range can be missing: each end moved less than half the skin). The
    pairs come sorted by receiver, then sender.
    """

    def __init__(self, comm_range: float) -> None:
        if comm_range < 0:
            raise WorldConfigError(f"communication range must be >= 0, got {comm_range}")
        self.comm_range = comm_range
        self.skin = comm_range * NEIGHBOUR_SKIN
        self._anchor: np.ndarray | None = None
        self.searches = 0         # how many grid searches ran (tests and benchmarks read it)

    def pairs(self, positions: np.ndarray) -> RadioLinks:
        points = np.asarray(positions, dtype=np.float64)
        anchor = self._anchor
        if anchor is None or anchor.shape != points.shape or not self._fresh(points, anchor):
            self._search(points)
        senders, receivers = self._senders, self._receivers
        # np.linalg.norm(points[senders] - points[receivers], axis=1) (the search's
        # expression) column by column: the same sum, ((dx² + dy²) + dz²), the same bits,
        # without the (m, 3) temporaries
        x, y, z = points.T
        dx = x[senders] - x[receivers]
        dy = y[senders] - y[receivers]
        dz = z[senders] - z[receivers]
        gaps = np.sqrt(dx * dx + dy * dy + dz * dz)
        keep = gaps <= self.comm_range
        return RadioLinks(senders[keep], receivers[keep], gaps[keep])

    def _fresh(self, points: np.ndarray, anchor: np.ndarray) -> bool:
        moved = points - anchor
        # half the skin, a little less so that rounding in the distances cannot matter
        limit = 0.45 * self.skin
        return bool(np.einsum("ij,ij->i", moved, moved).max(initial=0.0) <= limit * limit)

    def _search(self, points: np.ndarray) -> None:
        wide = pairs_within_range(points, self.comm_range + self.skin)
        order = np.lexsort((wide.senders, wide.receivers))
        self._senders, self._receivers = wide.senders[order], wide.receivers[order]
        self._anchor = points.copy()
        self.searches += 1


def drop_lost(links: RadioLinks, loss_probability: float, rng: np.random.Generator) -> RadioLinks:
    """Keep each link independently with probability 1 - loss_probability."""
    if not 0.0 <= loss_probability <= 1.0:
        raise WorldConfigError(f"loss probability must be in [0, 1], got {loss_probability}")
    kept = rng.random(len(links.senders)) >= loss_probability
    return RadioLinks(links.senders[kept], links.receivers[kept], links.distances[kept])


#: One message arriving at one robot, with what the receiver senses of the sender:
#: (sender index, message, distance in the world's unit (Kilobot mm), azimuth in radians
#: counter-clockwise from the receiver's heading in (-pi, pi], elevation in radians): the
#: asynchronous mode's unit (lockstep deliveries are `PackedMessages` rows).
Delivery = tuple[int, bytes, float, float, float]


@dataclass
class TrafficCounters:
    """Per-robot message counts of one step (the engine turns them into `StepStats`)."""

    sent: np.ndarray            # transmissions
    received: np.ndarray        # deliveries handed to the VM
    dropped: np.ndarray         # lost in the air (counted at the receiver) or queue overflow
    bytes_sent: np.ndarray
    bytes_received: np.ndarray

    @classmethod
    def zeros(cls, count: int) -> TrafficCounters:
        return cls(*(np.zeros(count, dtype=np.int64) for _ in range(5)))


def interpolate_loss(table: tuple[tuple[float, float], ...], rates: np.ndarray) -> np.ndarray:
    """Loss probability at each rate, piecewise-linear through `table` (flat beyond its ends)."""
    xs = np.array([rate for rate, _ in table], dtype=np.float64)
    ys = np.array([loss for _, loss in table], dtype=np.float64)
    return np.interp(rates, xs, ys)


def group_ranks(keys: np.ndarray) -> np.ndarray:
    """Each row's rank within its run of equal keys (`keys` sorted): 0, 1, 2, ... per run."""
    n = len(keys)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    starts = np.flatnonzero(np.concatenate(([True], keys[1:] != keys[:-1])))
    return np.arange(n) - np.repeat(starts, np.diff(np.append(starts, n)))


def take_rows(messages: PackedMessages, rows: np.ndarray) -> PackedMessages:
    """The rows `rows` (indices or a boolean mask) of `messages`, columns kept together."""
    return type(messages)(messages.robots[rows], messages.payloads[rows],
                          messages.lengths[rows], messages.senders[rows],
                          messages.distances[rows], messages.azimuths[rows],
                          messages.elevations[rows])


def merge_by_robot(first: PackedMessages, second: PackedMessages) -> PackedMessages:
    """Both tables as one, sorted by robot; each robot's rows of `first` come before its rows
    of `second` (a stable sort: what appending `second`'s rows robot by robot gives)."""
    if len(second) == 0:
        return first
    if len(first) == 0:
        return second
    joined = type(first)(*(np.concatenate((getattr(first, name), getattr(second, name)))
                           for name in _COLUMNS))
    return take_rows(joined, np.argsort(joined.robots, kind="stable"))


_COLUMNS = ("robots", "payloads", "lengths", "senders", "distances", "azimuths", "elevations")


@dataclass
class Radio:
    """The swarm's radio: send queues, bandwidth, range, loss, noise and latency.

    Lockstep (the engine's `step`): `queue_outbox` takes the step's outbox, `transmit`
    sends, `due` hands a step's deliveries over — all as `PackedMessages` columns, with no
    Python loop over robots or messages (1,000 Kilobots: ~1,000 sent, ~11,000 delivered a
    step). Asynchronous robots (`begin_step`, `enqueue`, `send_from`, `take_due`) keep a
    deque of bytes per sender and a tuple per delivery; one `Radio` serves one of the two.
    """

    settings: RadioSettings
    count: int
    step_seconds: float
    loss_rng: np.random.Generator
    noise_rng: np.random.Generator
    queued: PackedMessages = field(init=False)          # send queues, outbox rows (lockstep)
    in_flight: dict[int, PackedMessages] = field(init=False)   # due step -> deliveries
    history: np.ndarray = field(init=False)
    neighbours: NeighbourCache = field(init=False)
    send_queues: list[deque[bytes]] = field(init=False)  # asynchronous mode
    pending: list[list[tuple[float, Delivery]]] = field(init=False)   # asynchronous mode

    def __post_init__(self) -> None:
        settings = self.settings
        if settings.comm_range < 0:
            raise WorldConfigError(f"communication range must be >= 0, got {settings.comm_range}")
        if not 0.0 <= settings.loss_probability <= 1.0:
            raise WorldConfigError(
                f"loss probability must be in [0, 1], got {settings.loss_probability}")
        if settings.messages_per_step < 1:
            raise WorldConfigError("the radio must send at least 1 message per step")
        if settings.latency_steps < 1:
            raise WorldConfigError("latency must be at least 1 step (sent after the VMs ran)")
        # the VM room's columns; imported here, not at the top: the registry imports this
        # module for WorldConfigError and `bbzide --help` must not load the VM (numba)
        from bbzide.vm.swarm_batch import PackedMessages

        self.queued = PackedMessages.empty()
        self.in_flight = {}
        self.neighbours = NeighbourCache(settings.comm_range)
        self.send_queues = [deque() for _ in range(self.count)]
        self.pending = [[] for _ in range(self.count)]
        # Transmissions per sender over the last second (ring of steps), for the rate-dependent
        # loss: one second because the paper states its rates per second (2, 10, 20 Hz).
        window = max(1, round(1.0 / self.step_seconds))
        self.history = np.zeros((window, self.count), dtype=np.int64)

    def _pairs(self, positions: np.ndarray) -> RadioLinks:
        """The pairs within range now, sorted by receiver then sender (the cache follows a
        range changed in `settings`)."""
        if self.neighbours.comm_range != self.settings.comm_range:
            self.neighbours = NeighbourCache(self.settings.comm_range)
        return self.neighbours.pairs(positions)

    def queue_outbox(self, outbox: PackedMessages, counters: TrafficCounters) -> None:
        """Append each sender's outgoing rows to its send queue, in order; what finds the
        queue full (`send_queue_cap`) is dropped and counted at the sender."""
        if len(outbox) == 0:
            return
        merged = merge_by_robot(self.queued, outbox)
        fits = group_ranks(merged.robots) < self.settings.send_queue_cap
        if not fits.all():
            counters.dropped += np.bincount(merged.robots[~fits], minlength=self.count)
            merged = take_rows(merged, fits)
        self.queued = merged

    def queue_length(self, sender: int) -> int:
        """Messages waiting in `sender`'s send queue."""
        waiting = np.count_nonzero(self.queued.robots == sender)
        return int(waiting) + len(self.send_queues[sender])

    def enqueue(self, sender: int, messages: list[bytes], counters: TrafficCounters) -> None:
        """Queue a robot's outgoing messages (asynchronous mode); what does not fit is
        dropped and counted."""
        queue = self.send_queues[sender]
        for message in messages:
            if len(queue) >= self.settings.send_queue_cap:
                counters.dropped[sender] += 1
            else:
                queue.append(message)

    def rates(self) -> np.ndarray:
        """Each sender's transmissions per second over the last second."""
        return self.history.sum(axis=0) / (len(self.history) * self.step_seconds)

    def due(self, step: int) -> PackedMessages:
        """Deliveries arriving at the start of `step`, sorted by receiver, each receiver's
        in arrival order (removed from the air)."""
        arrived = self.queued.empty()
        for due_step in sorted(s for s in self.in_flight if s <= step):
            arrived = merge_by_robot(arrived, self.in_flight.pop(due_step))
        return arrived

    def transmit(
        self,
        step: int,
        positions: np.ndarray,
        headings: np.ndarray,
        listening: np.ndarray,
        counters: TrafficCounters,
    ) -> np.ndarray:
        """Send what the queues allow this step; returns the (sender, receiver) index pairs
        that carried at least one message, as an (M, 2) array."""
        settings = self.settings
        queued = self.queued
        now = group_ranks(queued.robots) < settings.messages_per_step
        if now.all():                                    # every queue empties (the usual)
            out, self.queued = queued, queued.empty()
        else:
            out = take_rows(queued, now)                 # sorted by sender, queue order
            self.queued = take_rows(queued, ~now)
        sent_now = np.bincount(out.robots, minlength=self.count)
        counters.sent += sent_now
        counters.bytes_sent += np.bincount(out.robots, weights=out.lengths,
                                           minlength=self.count).astype(np.int64)
        self.history[step % len(self.history)] = sent_now
        no_links = np.empty((0, 2), dtype=np.int64)
        if len(out) == 0:
            return no_links
        links = self._pairs(positions)      # sorted by receiver, then sender
        is_sender = sent_now > 0
        keep = is_sender[links.senders] & listening[links.receivers]
        s_idx, r_idx = links.senders[keep], links.receivers[keep]
        if len(s_idx) == 0:
            return no_links
        distance, azimuth, elevation = self._situation(positions, headings, s_idx, r_idx)
        # One loss draw per (link, message), in a fixed order: link-major, message-minor.
        per_link = sent_now[s_idx]
        total = int(per_link.sum())
        if settings.loss_by_rate:
            link_loss = interpolate_loss(settings.loss_by_rate, self.rates()[s_idx])
        else:
            link_loss = np.full(len(s_idx), settings.loss_probability)
        lost = self.loss_rng.random(total) < np.repeat(link_loss, per_link)
        # Expand links into (link, message) pairs, link-major, as the loss draws.
        link_of = np.repeat(np.arange(len(s_idx)), per_link)
        message_no = np.arange(total) - np.repeat(np.cumsum(per_link) - per_link, per_link)
        receivers = r_idx[link_of]
        arrived = ~lost
        cap = settings.receive_cap_per_step
        if cap is not None:
            # Rank of each arriving message at its receiver (pairs are sorted by receiver).
            rank = np.cumsum(arrived) - 1
            boundaries = np.flatnonzero(np.diff(receivers, prepend=-1))
            base = np.repeat(np.concatenate([[0], rank])[boundaries],
                             np.diff(np.append(boundaries, total)))
            arrived &= (rank - base) < cap
        counters.dropped += np.bincount(receivers[~arrived], minlength=self.count)
        keep_links = link_of[arrived]
        senders = s_idx[keep_links]
        # each sender's first row in `out`, plus the message number: the delivered row
        first = np.cumsum(sent_now) - sent_now
        rows = first[senders] + message_no[arrived]
        arriving = type(out)(receivers[arrived], out.payloads[rows], out.lengths[rows],
                             senders, distance[keep_links] * settings.distance_unit,
                             azimuth[keep_links], elevation[keep_links])
        due_step = step + settings.latency_steps
        pending = self.in_flight.get(due_step)
        self.in_flight[due_step] = (arriving if pending is None
                                    else merge_by_robot(pending, arriving))
        # the used (sender, receiver) pairs, each once, sorted by sender then receiver: the
        # links that delivered a message, sorted by one int key (sender * count + receiver)
        used = np.zeros(len(s_idx), dtype=bool)
        used[keep_links] = True
        keys = np.sort(s_idx[used] * self.count + r_idx[used])
        return np.column_stack([keys // self.count, keys % self.count])

    def _situation(
        self, positions: np.ndarray, headings: np.ndarray, s_idx: np.ndarray, r_idx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance, azimuth (receiver frame) and elevation of each sender, with noise."""
        settings = self.settings
        x, y, z = positions.T      # columns gathered one by one: no (m, 3) temporaries
        dx, dy, dz = x[s_idx] - x[r_idx], y[s_idx] - y[r_idx], z[s_idx] - z[r_idx]
        horizontal = np.hypot(dx, dy)
        distance = np.sqrt(horizontal**2 + dz**2)
        if settings.distance_noise > 0:
            distance = distance * (1 + self.noise_rng.normal(0, settings.distance_noise,
                                                             len(distance)))
            distance = np.maximum(distance, 0.0)
        if not settings.has_bearing:
            zeros = np.zeros(len(distance))
            return distance, zeros, zeros
        azimuth = np.arctan2(dy, dx) - headings[r_idx]
        elevation = np.arctan2(dz, horizontal)
        if settings.bearing_noise > 0:
            azimuth = azimuth + self.noise_rng.normal(0, settings.bearing_noise, len(azimuth))
            elevation = elevation + self.noise_rng.normal(0, settings.bearing_noise,
                                                          len(elevation))
        azimuth = np.pi - np.mod(np.pi - azimuth, 2 * np.pi)   # wrap to (-pi, pi]
        return distance, azimuth, elevation

    # ---- asynchronous robots ---------------------------------------------------------------
    def begin_step(self, step: int, positions: np.ndarray, headings: np.ndarray,
                   listening: np.ndarray) -> None:
        """Links and situated data of this step, grouped by sender (asynchronous mode)."""
        links = self._pairs(positions)
        keep = listening[links.receivers]
        s_idx, r_idx = links.senders[keep], links.receivers[keep]
        order = np.lexsort((r_idx, s_idx))
        s_idx, r_idx = s_idx[order], r_idx[order]
        distance, azimuth, elevation = self._situation(positions, headings, s_idx, r_idx)
        self._step = step
        self._starts = np.searchsorted(s_idx, np.arange(self.count + 1))
        self._receivers = r_idx.tolist()
        self._distance = (distance * self.settings.distance_unit).tolist()
        self._azimuth = azimuth.tolist()
        self._elevation = elevation.tolist()
        self._taken = np.zeros(self.count, dtype=np.int64)
        self._used: set[tuple[int, int]] = set()
        self.history[step % len(self.history)] = 0

    def send_from(self, sender: int, time: float, counters: TrafficCounters) -> None:
        """Transmit what `sender`'s queue allows now; receivers get it at their next step."""
        settings = self.settings
        queue = self.send_queues[sender]
        if not queue:
            return
        batch = [queue.popleft() for _ in range(min(settings.messages_per_step, len(queue)))]
        counters.sent[sender] += len(batch)
        counters.bytes_sent[sender] += sum(len(m) for m in batch)
        self.history[self._step % len(self.history), sender] += len(batch)
        first, last = int(self._starts[sender]), int(self._starts[sender + 1])
        if first == last:
            return
        if settings.loss_by_rate:
            rate = self.rates()[sender:sender + 1]
            loss = float(interpolate_loss(settings.loss_by_rate, rate)[0])
        else:
            loss = settings.loss_probability
        lost = (self.loss_rng.random((last - first) * len(batch)) < loss).tolist()
        arrival = time + settings.latency_steps - 1
        cap = settings.receive_cap_per_step
        k = 0
        for link in range(first, last):
            receiver = self._receivers[link]
            for message in batch:
                if lost[k] or (cap is not None and self._taken[receiver] >= cap):
                    counters.dropped[receiver] += 1
                else:
                    self._taken[receiver] += 1
                    self.pending[receiver].append((arrival, (
                        sender, message, self._distance[link], self._azimuth[link],
                        self._elevation[link])))
                    self._used.add((sender, receiver))
                k += 1

    def take_due(self, receiver: int, time: float) -> list[Delivery]:
        """Deliveries that reached `receiver` before `time`, in order of arrival."""
        pending = self.pending[receiver]
        if not pending:
            return []
        due = [d for t, d in pending if t < time]
        if due:
            self.pending[receiver] = [(t, d) for t, d in pending if t >= time]
        return due

    def step_links(self) -> np.ndarray:
        """(sender, receiver) pairs that carried a message in this asynchronous step."""
        if not self._used:
            return np.empty((0, 2), dtype=np.int64)
        return np.array(sorted(self._used), dtype=np.int64)
