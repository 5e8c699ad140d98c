"""The engine's synchronous radio written the slow, readable way: a test oracle.

Design: this is `bbzide/worlds/radio.py`'s `Radio` as it was before its send queues and
deliveries became numpy columns (`PackedMessages`): a deque of bytes per sender and
a tuple per delivery, built row by row. `test_packed_radio.py` drives it and the packed
`Radio` with the same traffic and the same seeds and requires the same deliveries (receiver,
sender, message order, situated data), counters, links and random draws.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bbzide.worlds.radio import (
    TrafficCounters,
    WorldConfigError,
    interpolate_loss,
    pairs_within_range,
)

if TYPE_CHECKING:
    from bbzide.worlds.world import RadioSettings

Delivery = tuple[int, bytes, float, float, float]


@dataclass
class ReferenceRadio:
    """The synchronous radio as it was before its queues and deliveries became columns."""

    settings: RadioSettings
    count: int
    step_seconds: float
    loss_rng: np.random.Generator
    noise_rng: np.random.Generator
    send_queues: list[deque[bytes]] = field(init=False)
    in_flight: dict[int, list[list[Delivery]]] = field(init=False)
    history: np.ndarray = field(init=False)

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
        self.send_queues = [deque() for _ in range(self.count)]
        self.in_flight = {}
        # Transmissions per sender over the last second (ring of steps), for the rate-dependent
        # loss: one second because the paper states its rates per second (2, 10, 20 Hz).
        window = max(1, round(1.0 / self.step_seconds))
        self.history = np.zeros((window, self.count), dtype=np.int64)

    def enqueue(self, sender: int, messages: list[bytes], counters: TrafficCounters) -> None:
        """Queue a robot's outgoing messages; what does not fit is dropped and counted."""
        queue = self.send_queues[sender]
        for message in messages:
            if len(queue) >= self.settings.send_queue_cap:
                counters.dropped[sender] += 1
            else:
                queue.append(message)

    def rates(self) -> np.ndarray:
        """Each sender's transmissions per second over the last second."""
        return self.history.sum(axis=0) / (len(self.history) * self.step_seconds)

    def due(self, step: int) -> list[list[Delivery]]:
        """Deliveries arriving at the start of `step`, per receiver (removed from the air)."""
        batches = [self.in_flight.pop(s) for s in sorted(self.in_flight) if s <= step]
        if len(batches) == 1:
            return batches[0]
        merged: list[list[Delivery]] = [[] for _ in range(self.count)]
        for batch in batches:
            for receiver, items in enumerate(batch):
                merged[receiver].extend(items)
        return merged

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
        per_step = settings.messages_per_step
        outgoing: list[list[bytes]] = []
        senders: list[int] = []
        for sender, queue in enumerate(self.send_queues):
            if queue:
                batch = [queue.popleft() for _ in range(min(per_step, len(queue)))]
                senders.append(sender)
                outgoing.append(batch)
        sent_now = np.zeros(self.count, dtype=np.int64)
        for sender, batch in zip(senders, outgoing, strict=True):
            sent_now[sender] = len(batch)
            counters.sent[sender] += len(batch)
            counters.bytes_sent[sender] += sum(len(m) for m in batch)
        self.history[step % len(self.history)] = sent_now
        no_links = np.empty((0, 2), dtype=np.int64)
        if not senders:
            return no_links
        links = pairs_within_range(positions, settings.comm_range)
        is_sender = sent_now > 0
        keep = is_sender[links.senders] & listening[links.receivers]
        s_idx, r_idx = links.senders[keep], links.receivers[keep]
        order = np.lexsort((s_idx, r_idx))
        s_idx, r_idx = s_idx[order], r_idx[order]
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
        np.add.at(counters.dropped, receivers[~arrived], 1)
        keep_links = link_of[arrived]
        unit = settings.distance_unit
        arriving = self._deliveries(senders, outgoing, s_idx[keep_links], message_no[arrived],
                                    receivers[arrived], distance[keep_links] * unit,
                                    azimuth[keep_links], elevation[keep_links])
        due_step = step + settings.latency_steps
        pending = self.in_flight.get(due_step)
        if pending is None:
            self.in_flight[due_step] = arriving
        else:
            for receiver, items in enumerate(arriving):
                pending[receiver].extend(items)
        # the used (sender, receiver) pairs, each once, sorted: np.unique over one int key
        # per pair (sender * count + receiver) is np.unique(axis=0) of the pairs, ~10x faster
        keys = np.unique(s_idx[keep_links] * self.count + r_idx[keep_links])
        return np.column_stack([keys // self.count, keys % self.count])

    def _deliveries(self, senders: list[int], outgoing: list[list[bytes]],
                    sender_of: np.ndarray, number: np.ndarray, receiver_of: np.ndarray,
                    distance: np.ndarray, azimuth: np.ndarray, elevation: np.ndarray
                    ) -> list[list[Delivery]]:
        """Each receiver's deliveries from the arriving (sender, message number, receiver,
        situated data) rows, which come sorted by receiver: the rows become tuples in one
        pass (``zip``), then each receiver gets its run of them (a slice) — the same lists,
        in the same order, as appending row by row (1,000 Kilobots: ~11,000 rows a step)."""
        flat = [message for batch in outgoing for message in batch]
        sizes = np.array([len(batch) for batch in outgoing], dtype=np.int64)
        first = np.zeros(self.count, dtype=np.int64)  # each sender's first message in flat
        first[senders] = np.cumsum(sizes) - sizes
        rows = list(zip(sender_of.tolist(),
                        map(flat.__getitem__, (first[sender_of] + number).tolist()),
                        distance.tolist(), azimuth.tolist(), elevation.tolist(), strict=True))
        ends = np.cumsum(np.bincount(receiver_of, minlength=self.count)).tolist()
        starts = [0, *ends[:-1]]
        return [rows[a:b] for a, b in zip(starts, ends, strict=True)]

    def _situation(
        self, positions: np.ndarray, headings: np.ndarray, s_idx: np.ndarray, r_idx: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance, azimuth (receiver frame) and elevation of each sender, with noise."""
        settings = self.settings
        offset = positions[s_idx] - positions[r_idx]
        horizontal = np.hypot(offset[:, 0], offset[:, 1])
        distance = np.sqrt(horizontal**2 + offset[:, 2] ** 2)
        if settings.distance_noise > 0:
            distance = distance * (1 + self.noise_rng.normal(0, settings.distance_noise,
                                                             len(distance)))
            distance = np.maximum(distance, 0.0)
        if not settings.has_bearing:
            zeros = np.zeros(len(distance))
            return distance, zeros, zeros
        azimuth = np.arctan2(offset[:, 1], offset[:, 0]) - headings[r_idx]
        elevation = np.arctan2(offset[:, 2], horizontal)
        if settings.bearing_noise > 0:
            azimuth = azimuth + self.noise_rng.normal(0, settings.bearing_noise, len(azimuth))
            elevation = elevation + self.noise_rng.normal(0, settings.bearing_noise,
                                                          len(elevation))
        azimuth = np.pi - np.mod(np.pi - azimuth, 2 * np.pi)   # wrap to (-pi, pi]
        return distance, azimuth, elevation
