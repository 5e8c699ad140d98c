"""A minimal corpus driver for the vm-core tests (until vm-runtime's harness exists).

Runs one ``bbz/NAME`` script the way ``bbzharness-pc`` does (corpus README §"Run loop"):
construct + set_bcode, the ``--reg`` closures, the top-level script, ``init``, then the
control steps, and records after each phase what the ``#BBZDUMP 1`` dump records
(state, pc, stack, rtobj/ltseg, heap bytes). Injections and the neighbors data GC are the
runtime room's; scripts that need them are reported, not hidden.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from bbzide.vm.heap import CLOSURE
from bbzide.vm.profiles import KILOBOT, PC
from bbzide.vm.tables import compare
from bbzide.vm.vm import VM, State


@dataclass
class Snapshot:
    label: str
    state: str
    error: str
    pc: int
    stack: list[int]
    rtobj: int
    ltseg: int
    heap: bytes
    errors: list[tuple[str, int]] = field(default_factory=list)


def parse_reference(path: Path) -> tuple[dict[str, str], list[Snapshot], str]:
    """The dumps of a reference ``#BBZDUMP 1`` file, the input line and the end word."""
    dumps: list[Snapshot] = []
    info: dict[str, str] = {}
    end = ""
    cur: Snapshot | None = None
    for line in path.read_text().splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == "input":
            info = dict(zip(w[1::2], w[2::2], strict=False))
        elif w[0] == "dump":
            cur = Snapshot(" ".join(w[2:]), "", "", 0, [], 0, 0, b"")
            dumps.append(cur)
        elif cur is not None and w[0] == "state":
            cur.state, cur.error, cur.pc = w[1], w[3], int(w[5])
        elif cur is not None and w[0] == "stack":
            cur.stack = [int(x) for x in w[1:]]
        elif cur is not None and w[0] == "rtobj":
            cur.rtobj, cur.ltseg = int(w[1]), int(w[5])
        elif cur is not None and w[0] == "heap":
            cur.heap = bytes.fromhex(w[1])
        elif w[0] in ("halt", "finished"):
            end = w[0]
    return info, dumps, end


def heap_differences(ref: Snapshot, mine: Snapshot, obj_size: int) -> list[int]:
    """Offsets of differing heap bytes under the level (a) mask (README §5)."""
    bad = []
    for i, (a, b) in enumerate(zip(ref.heap, mine.heap, strict=True)):
        if a == b:
            continue
        if i < ref.ltseg:
            slot, off = divmod(i, obj_size)
            m = ref.heap[slot * obj_size]
            if off > 0 and ((m & 7) == CLOSURE and not m & 0xC0 or off >= 3):
                continue
        bad.append(i)
    return bad


def _kind_function(kind: str, vm: VM, seed: int = 0):  # noqa: ANN202 - closure factory
    rng = {"x": seed}

    if kind in ("print", "log", "ret0"):
        return ("h_print" if kind in ("print", "log") else "h_ret0"), lambda v: v.ret0()
    m = re.fullmatch(r"ret0/(\d)", kind)
    if m:
        n = int(m.group(1))

        def ret0n(v: VM) -> None:
            if v.assert_lnum(n):
                v.ret0()
        return f"h_ret0_a{n}", ret0n
    if kind == "retnil":
        def retnil(v: VM) -> None:
            v.push_nil()
            v.ret1()
        return "h_retnil", retnil
    if kind == "rand":
        def rand(v: VM) -> None:
            rng["x"] = (rng["x"] * 1103515245 + 12345) & 0xFFFFFFFF
            v.push_int((rng["x"] >> 16) & 0x7FFF)
            v.ret1()
        return "h_rand", rand
    if kind == "min":
        def hmin(v: VM) -> None:
            if not v.assert_lnum(2):
                return
            a, b = v.lsym(1), v.lsym(2)
            v.push(b if compare(v.heap, b, a) < 0 else a)
            v.ret1()
        return "h_min", hmin
    m = re.fullmatch(r"reti:(-?\d+)", kind)
    if m:
        val = int(m.group(1))

        def reti(v: VM) -> None:
            v.push_int(val)
            v.ret1()
        return "h_reti", reti
    raise ValueError(kind)


def _snap(vm: VM, label: str) -> Snapshot:
    return Snapshot(label, vm.state.name, vm.error.name, vm.pc,
                    list(vm.stack[:vm.stackptr + 1]), vm.heap.rtobj, vm.heap.ltseg,
                    bytes(vm.heap.data), list(vm.error_events))


def call_global(vm: VM, sid: int) -> bool:
    """The harness's ``call f``: pushs f, look up, pushnil, push closure, closure_call(0)."""
    from bbzide.vm.tables import table_get

    s = vm.new_string_obj(sid)
    c = table_get(vm.heap, vm.gsyms, s)
    if c is None:
        return False
    vm.push_nil()
    vm.push(c)
    vm.closure_call(0)
    return True


def run_script(bbz_dir: Path, dump_name: str, stress_gc: bool = True) -> list[Snapshot]:
    """Run the reference run ``dump_name`` with the model; one Snapshot per dump."""
    cmd = (bbz_dir / (dump_name.split(".")[0] + ".cmd")).read_text()
    info, ref, _ = parse_reference(bbz_dir / dump_name)
    line = next(x for x in cmd.splitlines() if x.endswith("> " + dump_name))
    words = line.split()
    regs = [words[i + 1] for i, w in enumerate(words) if w == "--reg"]
    loop = words[words.index("--loop") + 1] if "--loop" in words else "pop"
    steps = int(info["steps"])
    seed = int(words[words.index("--seed") + 1]) if "--seed" in words else 0
    robot = int(info["robot"])
    name = info["bbo"][:-4]
    strings = (bbz_dir / (name + ".bst")).read_text().splitlines()
    sid = {s: i for i, s in enumerate(strings)}
    profile = PC if dump_name.endswith(".pc.dump") else KILOBOT
    vm = VM(profile, robot=robot, stress_gc=stress_gc)
    vm.construct()
    vm.set_bcode((bbz_dir / info["bbo"]).read_bytes())
    out = [_snap(vm, "construct+set_bcode")]
    if vm.state == State.ERROR:
        return out
    # setup: --reg closures; consecutive tbl.field entries form one table
    i = 0
    while i < len(regs):
        nm, kind = regs[i].split("=", 1)
        if "." in nm:
            tbl = nm.split(".")[0]
            t = vm.push_table()
            while i < len(regs) and regs[i].split("=", 1)[0].startswith(tbl + "."):
                fnm, fkind = regs[i].split("=", 1)
                sym, fn = _kind_function(fkind, vm, seed)
                vm.add_function(t, sid[fnm.split(".", 1)[1]], sym, fn)
                i += 1
            vm.gsym_register(sid[tbl], t)
            vm.pop()
            continue
        sym, fn = _kind_function(kind, vm, seed)
        vm.function_register(sid[nm], sym, fn)
        i += 1
    out.append(_snap(vm, "setup"))
    vm.run(max_instructions=2_000_000)
    out.append(_snap(vm, "script"))
    if vm.state == State.ERROR:
        return out
    vm.state = State.READY
    if call_global(vm, sid["init"]) and loop == "pop" and vm.state == State.READY:
        vm.pop()
    out.append(_snap(vm, "init"))
    if vm.state == State.ERROR:
        return out
    for s in range(1, steps + 1):
        if call_global(vm, sid["step"]) and loop == "pop" and vm.state == State.READY:
            vm.pop()
        n = vm.neighbors
        if n.clear_counter == 0:
            n.clear_counter = profile.neighbors_clr_period
            vm.gc()  # TODO(vm-runtime): bbzneighbors_data_gc
        else:
            n.clear_counter -= 1
        out.append(_snap(vm, f"step {s}"))
        if vm.state == State.ERROR:
            break
    return out
