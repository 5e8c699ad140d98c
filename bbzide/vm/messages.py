"""Message queues of a BittyBuzz VM as plain data (spec §F.4).

Construct only initialises them (empty). The ring-buffer semantics (capacity slots, one
always unused) and the wire format belong to the runtime room (vm-runtime).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class MessageQueues:
    """``vm->inmsgs`` / ``vm->outmsgs``: lists of raw messages (bytes), oldest first."""

    in_capacity: int
    out_capacity: int
    inbox: list[bytes] = field(default_factory=list)
    outbox: list[bytes] = field(default_factory=list)

    def clear(self) -> None:
        self.inbox.clear()
        self.outbox.clear()
