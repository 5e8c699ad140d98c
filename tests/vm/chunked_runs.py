"""A VM's top-level code run in both modes for comparison: whole, or in small chunks of
instructions with the VM observed after each (every register, the heap bytes, the errors),
so that a kernel that differs from the model is caught at the instruction where it does;
and a script's ``step`` called control step after control step, observed after each."""

from __future__ import annotations

from collections.abc import Iterator

from bbzide.vm.profiles import Profile
from bbzide.vm.states import Error
from bbzide.vm.vm import VM, State

#: chunk sizes (instructions) the runs are observed after, cycled
CHUNKS = (1, 2, 3, 5, 8, 13, 40)


def observe(vm: VM) -> tuple:
    return (vm.state, vm.error, vm.pc, list(vm.stack[:vm.stackptr + 1]), vm.blockptr,
            vm.lsyms, vm.heap.rtobj, vm.heap.ltseg, bytes(vm.heap.data),
            list(vm.error_events), vm.heap.gc_runs, vm.instructions_executed,
            vm.heap.peak_used)


def chunk_stops(bbo: bytes, profile: Profile, stress: bool, limit: int) -> Iterator[VM]:
    """The top-level code run in chunks of CHUNKS instructions (each run stopped by its
    budget and resumed): the VM before the first chunk and after each, until the code ends
    or ``limit`` chunks ran."""
    vm = VM(profile, stress_gc=stress)
    vm.construct()
    vm.set_bcode(bbo)
    yield vm
    for n in range(limit):
        if vm.state != State.READY:
            break
        vm.run(max_instructions=CHUNKS[n % len(CHUNKS)])
        yield vm
        if vm.state == State.ERROR and vm.error == Error.BUDGET:
            vm.state = State.READY


def run_in_chunks(bbo: bytes, profile: Profile, stress: bool, limit: int) -> list[tuple]:
    """The top-level code in chunks, observed after each, until it ends or ``limit``
    chunks."""
    return [observe(vm) for vm in chunk_stops(bbo, profile, stress, limit)]


def run_whole(bbo: bytes, profile: Profile, stress: bool) -> tuple:
    vm = VM(profile, stress_gc=stress)
    vm.construct()
    vm.set_bcode(bbo)
    vm.run(max_instructions=200_000)
    return observe(vm)


def observe_steps(vm: VM, step: int, steps: int) -> list[tuple]:
    """The global ``step`` (its string id) called ``steps`` times as the firmware's loop
    calls it (push nil, call, pop), the VM observed after each call, until an error."""
    states = []
    for _ in range(steps):
        vm.push_nil()
        vm.function_call(step, 0)
        states.append(observe(vm))
        if vm.state == State.ERROR:
            break
        vm.pop()
    return states


def assert_same_runs(stress: list[tuple], fast: list[tuple], what: str) -> None:
    """Two runs' observations equal one by one (``what`` names the run and its unit)."""
    assert len(stress) == len(fast)
    for k, (a, b) in enumerate(zip(stress, fast, strict=True)):
        assert a == b, f"{what}: differs after {k}"


def assert_modes_agree_in_chunks(bbo: bytes, profile: Profile, limit: int, name: str) -> None:
    """The reference and the fast mode observed equal after every chunk."""
    assert_same_runs(run_in_chunks(bbo, profile, True, limit),
                     run_in_chunks(bbo, profile, False, limit),
                     f"{name} on {profile.name}, chunk")


def assert_modes_agree(bbo: bytes, profile: Profile, limit: int, name: str) -> None:
    """The reference and the fast mode equal at the end of a whole run, and after every
    chunk of a run in chunks (``limit`` chunks at most)."""
    assert run_whole(bbo, profile, True) == run_whole(bbo, profile, False), \
        f"{name} on {profile.name}: differs at the end"
    assert_modes_agree_in_chunks(bbo, profile, limit, name)
