"""``#BBZDUMP 1`` export of a VM (conformance README §4), so the model's runs can be diffed
with the reference dumps by the corpus's own ``bbzconf.py diff``.

One function per line kind; :func:`dump_block` writes the block from ``dump K LABEL`` to
``end``. Everything is read from the VM record and heap bytes (nothing is recomputed), so
a difference in a dump is a difference in the model's state. ``format_value`` renders an
argument of the harness's ``print`` closure (the ``out`` lines).
"""

from __future__ import annotations

from bbzide.compiler import bbzfloat
from bbzide.vm.heap import CLOSURE, FLAG1, FLAG2, FLOAT, INT, NIL, STRING, TABLE
from bbzide.vm.profiles import Profile
from bbzide.vm.table_library import table_size_live
from bbzide.vm.vm import VM

#: FNV-1a 64-bit parameters (the ``heapfnv`` line)
_FNV_OFFSET = 0xCBF29CE484222325
_FNV_PRIME = 0x100000001B3
_MASK64 = (1 << 64) - 1


def fnv1a64(data: bytes) -> int:
    h = _FNV_OFFSET
    for b in data:
        h = ((h ^ b) * _FNV_PRIME) & _MASK64
    return h


def header_lines(profile: Profile, bbo_name: str, bbo_size: int, bo_name: str,
                 nstrings: int, robot: int, steps: int, loop: str) -> list[str]:
    return [
        "#BBZDUMP 1",
        profile.config_line(),
        f"input bbo {bbo_name} size {bbo_size} bo {bo_name} nstrings {nstrings} "
        f"robot {robot} steps {steps} loop {loop}",
    ]


def _neighbors_line(vm: VM) -> str:
    n = vm.neighbors
    head = f"neighbors hpos {n.hpos} listeners {n.listeners} clear_counter {n.clear_counter}"
    if not vm.profile.xtreme:
        return f"{head} count {n.count}"
    parts = [f"{head} rbsize {n.ring.size()}"]
    for e in n.entries():
        parts.append(f"[rid={e.robot} d={e.distance} az={e.azimuth} el={e.elevation} "
                     f"m={e.mark}]")
    return " ".join(parts)


def dump_block(vm: VM, number: int, label: str) -> list[str]:
    """The lines ``dump K LABEL`` .. ``end`` for the VM's current state."""
    h = vm.heap
    s = h.obj_size
    stack = " ".join(str(x) for x in vm.stack[:vm.stackptr + 1])
    vstig = " ".join(f"[key={e.key} val={e.value} ts={e.timestamp} rid={e.robot}]"
                     for e in vm.vstig.entries)
    vst = f"vstig hpos {vm.vstig.hpos} size {len(vm.vstig.entries) & 0xFF}"
    heap = bytes(h.data)
    return [
        f"dump {number} {label}",
        f"state {vm.state.name} error {vm.error.name} pc {vm.pc}",
        f"rtobj {h.rtobj} nobj {h.rtobj // s} ltseg {h.ltseg} "
        f"nseg {(h.size - h.ltseg) // h.seg_size}",
        f"stackptr {vm.stackptr} blockptr {vm.blockptr}",
        f"stack {stack}" if stack else "stack",
        f"vm lsyms {vm.lsyms} gsyms {vm.gsyms} nil {vm.nil} dflt_actrec {vm.dflt_actrec} "
        f"flist {vm.flist}",
        f"swarm hpos {vm.swarm.hpos} swarmstack {vm.swarm.swarmstack} "
        f"my_swarmlist {vm.swarm.my_swarmlist:02x}",
        f"{vst} {vstig}" if vstig else vst,
        _neighbors_line(vm),
        f"queues in {vm.queues.inbox.size()} out {vm.queues.outbox.size()}",
        f"heapfnv {fnv1a64(heap):016x}",
        f"heap {heap.hex()}",
        "end",
    ]


def format_value(vm: VM, o: int, strings: list[str]) -> str:
    """One argument as the harness's ``print`` closure writes it."""
    h = vm.heap
    m = h.mdata(o)
    t = m & 7
    if t == NIL:
        return "nil"
    if t == INT:
        return str(h.int_value(o))
    if t == FLOAT:
        bits = h.u16(o)
        if vm.profile.float_ops:
            return f"{bbzfloat.to_float(bits):g}[f:{bits:04x}]"
        return f"[f:{bits:04x}]"
    if t == STRING:
        sid = h.u16(o)
        return f'"{strings[sid]}"' if sid < len(strings) else f'"#{sid}"'
    if t == TABLE:
        return f"[t:{table_size_live(vm, o)}@{o}]"
    if t == CLOSURE:
        base = o * h.obj_size
        if m & FLAG2:
            return f"[cl:ref={h.data[base + 1]},ar={h.data[base + 2]}]"
        if m & FLAG1:
            return f"[cn:{h.ptr_value(o) & 0xFFFF}]"
        call = vm.host.lookup(h.ptr_value(o))
        return f"[cc:{call.symbol if call else '?'}]"
    return f"[u:{h.ptr_value(o):x}]"
