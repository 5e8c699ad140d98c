"""The packed radio (send queues and deliveries as `PackedMessages` columns) against the
tuple-per-message radio it replaced (`reference_radio.py`): same traffic, same seeds, so the
same deliveries in the same order, counters, links and random draws."""

from __future__ import annotations

import numpy as np
import pytest

from bbzide.vm.messages import PAYLOAD_SIZE
from bbzide.vm.swarm_batch import PackedMessages
from bbzide.worlds.radio import Radio, TrafficCounters, group_ranks, merge_by_robot
from bbzide.worlds.world import RadioSettings
from tests.worlds.reference_radio import ReferenceRadio

COUNT = 40
SETTINGS = {
    "kilobot-like": RadioSettings(comm_range=0.1, loss_probability=0.05, messages_per_step=1,
                                  send_queue_cap=10, distance_noise=0.03, has_bearing=False,
                                  distance_unit=1000.0),
    "bearing, noise, cap": RadioSettings(comm_range=0.15, loss_probability=0.3,
                                         messages_per_step=2, send_queue_cap=3,
                                         receive_cap_per_step=3, distance_noise=0.1,
                                         bearing_noise=0.05),
    "loss by rate, latency 2": RadioSettings(comm_range=0.2, loss_by_rate=((2, 0.0), (20, 0.5)),
                                             messages_per_step=3, latency_steps=2),
}


def traffic(rng: np.random.Generator, step: int) -> list[list[bytes]]:
    """Each robot's outgoing messages this step: 0-4 of 1-12 bytes (some longer than the 9
    a VM reads: the wire length still counts), some robots silent for a while."""
    return [[bytes(rng.integers(0, 256, rng.integers(1, 13)).tolist())
             for _ in range(rng.integers(0, 5))] if (i + step) % 5 else []
            for i in range(COUNT)]


def as_rows(deliveries: PackedMessages) -> list[tuple]:
    return [(int(deliveries.robots[k]), int(deliveries.senders[k]), deliveries.payload(k),
             int(deliveries.lengths[k]), float(deliveries.distances[k]),
             float(deliveries.azimuths[k]), float(deliveries.elevations[k]))
            for k in range(len(deliveries))]


def reference_rows(per_receiver: list[list[tuple]]) -> list[tuple]:
    return [(receiver, sender, message[:PAYLOAD_SIZE], len(message), distance, azimuth,
             elevation)
            for receiver, items in enumerate(per_receiver)
            for sender, message, distance, azimuth, elevation in items]


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_packed_radio_equals_the_tuple_radio(name: str) -> None:
    settings = SETTINGS[name]
    radios = [kind(settings, COUNT, 0.1, np.random.default_rng(11), np.random.default_rng(12))
              for kind in (Radio, ReferenceRadio)]
    packed, reference = radios
    rng = np.random.default_rng(5)
    positions = np.column_stack([rng.uniform(0, 0.4, COUNT), rng.uniform(0, 0.4, COUNT),
                                 rng.uniform(0, 0.1, COUNT)])
    headings = rng.uniform(-np.pi, np.pi, COUNT)
    delivered = dropped = 0
    for step in range(25):
        assert as_rows(packed.due(step)) == reference_rows(reference.due(step))
        outgoing = traffic(rng, step)
        listening = rng.random(COUNT) > 0.1
        counters = [TrafficCounters.zeros(COUNT) for _ in radios]
        rows = [(i, i, m, 0.0, 0.0, 0.0) for i, batch in enumerate(outgoing) for m in batch]
        packed.queue_outbox(PackedMessages.from_rows(rows), counters[0])
        for sender, batch in enumerate(outgoing):
            if batch:
                reference.enqueue(sender, batch, counters[1])
        links = [radio.transmit(step, positions, headings, listening, c)
                 for radio, c in zip(radios, counters, strict=True)]
        assert np.array_equal(links[0], links[1])
        for column in ("sent", "received", "dropped", "bytes_sent", "bytes_received"):
            assert np.array_equal(getattr(counters[0], column), getattr(counters[1], column))
        assert [packed.queue_length(i) for i in range(COUNT)] == [
            len(q) for q in reference.send_queues]
        assert packed.loss_rng.bit_generator.state == reference.loss_rng.bit_generator.state
        assert packed.noise_rng.bit_generator.state == reference.noise_rng.bit_generator.state
        delivered += len(links[0])
        dropped += int(counters[0].dropped.sum())
        positions[:, :2] += rng.normal(0, 0.01, (COUNT, 2))
    assert delivered > 0 and dropped > 0     # the run exercised both


def test_group_ranks_and_merge_keep_order() -> None:
    assert group_ranks(np.array([0, 0, 2, 2, 2, 5])).tolist() == [0, 1, 0, 1, 2, 0]
    first = PackedMessages.from_rows([(0, 0, b"a", 0, 0, 0), (2, 2, b"b", 0, 0, 0)])
    second = PackedMessages.from_rows([(0, 0, b"c", 0, 0, 0), (1, 1, b"d", 0, 0, 0)])
    merged = merge_by_robot(first, second)
    assert [merged.payload(k) for k in range(len(merged))] == [b"a", b"c", b"d", b"b"]
