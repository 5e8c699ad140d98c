"""Platform profiles: the compile-time configuration of one BittyBuzz build.

BittyBuzz is configured by CMake (``BittyBuzzConfig.cmake`` and the per-robot ``*.cmake``
files, spec §E.1 and §F.9). A :class:`Profile` records those values so the Python model
reproduces the exact RAM layout of the firmware it stands for. The object size is not a
free parameter: it is ``1 + max(2, pointer size)`` bytes (a packed union whose widest
members are the C function pointer and ``uintptr_t`` userdata, spec §E.2).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Profile:
    """One build configuration (the ``config`` line of a ``#BBZDUMP 1`` file)."""

    name: str
    heap_size: int              # BBZHEAP_SIZE: bytes of vm->heap.data
    ptr_size: int               # sizeof(void*) of the target: 2 AVR, 4 Cortex-M, 8 x86-64
    elems_per_tseg: int = 5     # BBZHEAP_ELEMS_PER_TSEG (E): key/value pairs per table segment
    rsv_actrec: int = 28        # BBZHEAP_RSV_ACTREC_MAX (R): slots for lambda records
    gcmark_depth: int = 8       # BBZHEAP_GCMARK_DEPTH: GC recursion limit (roots sit at level 2)
    stack_size: int = 96        # BBZSTACK_SIZE: stack entries (u16 heap indices)
    vstig_cap: int = 4          # BBZVSTIG_CAP: stigmergy entries kept
    neighbors_cap: int = 15     # BBZNEIGHBORS_CAP: neighbor ring-buffer slots (XTREME)
    xtreme: bool = False        # BBZ_XTREME_MEMORY: neighbors in a ring buffer, not in tables
    neighbors_floats: bool = True   # BBZ_NEIGHBORS_USE_FLOATS
    float_ops: bool = True      # BBZ_ENABLE_FLOAT_OPERATIONS
    bytewise_assignment: bool = False  # BBZ_BYTEWISE_ASSIGNMENT (Zooids): no semantic change here
    in_queue_cap: int = 10      # BBZINMSG_QUEUE_CAP
    out_queue_cap: int = 10     # BBZOUTMSG_QUEUE_CAP
    msg_in_proc_max: int = 10   # BBZMSG_IN_PROC_MAX: in-messages processed per step
    lamport_threshold: int = 50  # BBZLAMPORT_THRESHOLD
    neighbors_clr_period: int = 10  # BBZNEIGHBORS_CLR_PERIOD
    neighbors_mark_time: int = 4    # BBZNEIGHBORS_MARK_TIME

    @property
    def obj_size(self) -> int:
        """S = 1 metadata byte + the widest payload (at least the 2 bytes of an int16)."""
        return 1 + max(2, self.ptr_size)

    @property
    def tseg_size(self) -> int:
        """G = 4E + 2: E u16 keys, E u16 values, one u16 mdata word."""
        return 4 * self.elems_per_tseg + 2

    def config_line(self) -> str:
        """The ``config`` header line of a ``#BBZDUMP 1`` file for this profile."""
        return (
            f"config heap_size {self.heap_size} obj_size {self.obj_size} "
            f"tseg_size {self.tseg_size} elems_per_tseg {self.elems_per_tseg} "
            f"rsv_actrec {self.rsv_actrec} stack_size {self.stack_size} "
            f"vstig_cap {self.vstig_cap} neighbors_cap {self.neighbors_cap} "
            f"xtreme {int(self.xtreme)} neighbors_floats {int(self.neighbors_floats)} "
            f"float_ops {int(self.float_ops)} ptr_size {self.ptr_size}"
        )


#: The name ARCHITECTURE.md uses for a profile.
PlatformProfile = Profile

# The host (x86-64) build that produced the corpus `*.pc.dump` files.
PC = Profile(name="pc", heap_size=3264, ptr_size=8)

# Kilobot: ATmega328P, 2 KB SRAM; the corpus `*.avr.dump` configuration.
KILOBOT = Profile(
    name="kilobot", heap_size=1088, ptr_size=2, xtreme=True,
    neighbors_floats=False, float_ops=False,
)

# Zooids and Crazyflie: Cortex-M (4-byte pointers), deeper GC marking and a larger stack.
ZOOIDS = Profile(
    name="zooids", heap_size=2048, ptr_size=4, gcmark_depth=16, stack_size=128,
    neighbors_cap=10, bytewise_assignment=True,
)
CRAZYFLIE = Profile(
    name="crazyflie", heap_size=3500, ptr_size=4, gcmark_depth=16, stack_size=128,
    neighbors_cap=10,
)

# M300: a macro drone with an onboard computer (our own profile, not a BittyBuzz build).
# * heap_size 60000: measured, a drone of the search-and-rescue mission (examples/sar, 15
#   drones, 20 m arena, belief search) peaks at 9,845 bytes (835 objects, 119 table segments)
#   with its 100-cell belief map in the stigmergy (97 entries); a 20 x 20 map (400 cells, the
#   finest the keys' string table is meant for) needs about 4x that for the map, so 60000 keeps
#   GC headroom. The heap size does not change the step time (measured 54 vs 53 robot-steps/s
#   at 60000 and 16000 bytes: the collector walks live objects, not the free gap). Object
#   indices stay below the 15-bit limit (60000 / 9 ≈ 6667 slots) and segment indices below
#   the 14-bit one.
# * vstig_cap 512: a 400-cell map plus room for mission keys (local puts stop at the cap).
# * neighbors_cap 64: a large swarm in radio range; the Lamport byte wraps at 256 anyway.
# * gcmark_depth 16, stack_size 256: nested tables and deeper call chains than a Kilobot's.
# * Message queues. The paper's M300s run full Buzz inside ROSBuzz on a Manifold 2 onboard
#   computer (thesis §5.3.3): there the in- and out-queues are growable arrays in gigabytes of
#   RAM, and every step the VM processes all the messages that arrived, so nothing is dropped
#   for lack of room. A BittyBuzz ring needs a size: in_queue_cap 255 holds what one step can
#   bring in the largest swarm of the experiments (25 drones all in range: 24 senders x the
#   M300 radio's 10 transmissions per step = 240), and msg_in_proc_max = in_queue_cap
#   processes all of it in that step, as Buzz does; out_queue_cap 255 lets a script queue as
#   much in one step (the radio then sends 10 a step). 255 is the largest ring whose u8
#   indices wrap right: the ring has capacity + 1 = 256 slots and BittyBuzz wraps `start + i`
#   in a u8 before taking it modulo the slots, which is exact only when the slots divide 256
#   (or when start + i never passes 255, i.e. up to 128 slots): a 251-slot ring reads the
#   wrong records once start + i passes 255. With 10 (the microcontroller default) a
#   candidate at the meeting point missed the root's beacon among 14 arrivals and a second
#   root was elected.
M300 = Profile(
    name="m300", heap_size=60000, ptr_size=8, gcmark_depth=16, stack_size=256,
    vstig_cap=512, neighbors_cap=64, in_queue_cap=255, out_queue_cap=255,
    msg_in_proc_max=255,
)

#: A heap whose peak reaches this share of the profile's heap gets a warning (one robot's run
#: and a world's alike): the next allocation burst (a table, a message) may stop it with MEM.
HEAP_WARNING_SHARE = 0.85

PROFILES: dict[str, Profile] = {p.name: p for p in (PC, KILOBOT, ZOOIDS, CRAZYFLIE, M300)}


def get_profile(name: str) -> Profile:
    """The profile called ``name`` (KeyError names the valid choices)."""
    try:
        return PROFILES[name]
    except KeyError:
        raise KeyError(f"unknown profile {name!r}; choose one of {sorted(PROFILES)}") from None
