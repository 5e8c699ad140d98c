"""The VM's state and error numbers (``bbzvm_state``, ``bbzvm_error``; spec §C.2, §F.1).

BittyBuzz keeps both in the VM record: ``state`` says whether the VM has code, is ready,
stopped, done or failed; ``error`` says which check failed (a stack overflow, a type error,
a full heap, ...). Every part of the model sets them — the instructions, the table library,
swarms, stigmergy, neighbours, messages — so they live here, below all of those, and
``vm.py`` re-exports them.

Both classes keep ``bbzide.vm.vm`` as their module name: a pickled VM state names its
classes by module (the snapshots of recordings in formats 2 and 3 hold such pickles, and
`Robot.comparable` compares two robots' pickled states), so the name a state is pickled
under stays what it always was.
"""

from __future__ import annotations

from enum import IntEnum

#: the module a pickled state names these classes by (see the module comment)
PICKLED_MODULE = "bbzide.vm.vm"


class State(IntEnum):
    """``bbzvm_state`` (BittyBuzz numbering)."""

    NOCODE = 0
    READY = 1
    STOPPED = 2
    DONE = 3
    ERROR = 4


class Error(IntEnum):
    """``bbzvm_error``; BUDGET is our own addition (instruction budget exhausted)."""

    NONE = 0
    INSTR = 1
    STACK = 2
    LNUM = 3
    PC = 4
    FLIST = 5
    TYPE = 6
    OUTOFRANGE = 7
    NOTIMPL = 8
    RET = 9
    STRING = 10
    SWARM = 11
    VSTIG = 12
    MEM = 13
    MATH = 14
    BUDGET = 15


State.__module__ = Error.__module__ = PICKLED_MODULE
