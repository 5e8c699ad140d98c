"""The byte layout of BittyBuzz messages, in one place for the Python queues and the kernels.

A queued message is a record laid out like the firmware's packed C union (``bbzmsg_t``;
:mod:`messages` explains why the bytes matter):

    byte 0 type · 1-2 rid · broadcast: 3-4 topic, 5.. value object
                          · vstig:     3 lamport, 4-5 key, 6.. data object

The Python reference (:mod:`messages`) and the compiled paths (:mod:`fastreceive`,
:mod:`fasthost`, :mod:`fastinbox`, :mod:`fastbatch`) all read these names from here. This
module imports nothing, so every kernel can use it: :mod:`messages` itself imports the
kernels, which therefore cannot import it.
"""

from __future__ import annotations

#: message types (``bbzmsg_payload_type_t``), the record's byte 0 and the payload's byte 0
BROADCAST, VSTIG_PUT, VSTIG_QUERY, SWARM = 0, 1, 2, 3

#: bytes of a wire payload: Kilobot ``message_t.data[9]`` (spec §F.4)
PAYLOAD_SIZE = 9
#: capacity of the payload ring buffer a payload is serialised into (11 slots, one unused:
#: ``bbzkilobot.c``), so a serialised payload can never exceed 10 bytes
PAYLOAD_RING_CAPACITY = 11

#: field offsets inside a record: type, sender robot id (u16), broadcast topic (u16) and
#: value object, vstig lamport clock (u8), key (u16) and data object
TYPE, RID, BC_TOPIC, BC_VALUE = 0, 1, 3, 5
VS_LAMPORT, VS_KEY, VS_DATA = 3, 4, 6
