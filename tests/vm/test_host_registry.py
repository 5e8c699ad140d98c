"""The host-function registry: addresses handed out once, the same registration a no-op, and
`register_all`'s answer reused only while no registration changed the registry."""

from __future__ import annotations

from bbzide.vm.host import HostRegistry
from bbzide.vm.vm import VM


def _first(vm: VM) -> None:
    vm.ret0()


def _second(vm: VM) -> None:
    vm.ret0()


METHODS = (("bbzneighbors_foreach", _first), ("made_up_method", _second))


def test_register_all_gives_each_functions_address_and_changes_nothing_twice() -> None:
    registry = HostRegistry(ptr_size=2)
    addresses = registry.register_all(METHODS)
    assert [registry.lookup(int(a)).function for a in addresses] == [_first, _second]
    assert int(addresses[0]) == 0x408351 & registry.mask  # the reference's address
    version = registry.version
    again = registry.register_all(METHODS)
    assert again is addresses and registry.version == version


def test_register_all_asks_again_after_another_registration() -> None:
    registry = HostRegistry(ptr_size=2)
    addresses = registry.register_all(METHODS)
    registry.register("made_up_method", _first)  # the same symbol, another function
    again = registry.register_all(METHODS)
    assert again is not addresses
    assert [registry.lookup(int(a)).function for a in again] == [_first, _second]
    assert registry.by_symbol["made_up_method"].function is _second
