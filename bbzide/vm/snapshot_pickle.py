"""Pickling a VM's records for `VM.snapshot()` without slowing the live VM down afterwards.

Design: CPython 3.11 keeps an object's attributes as "inline values" and specialises attribute
reads and writes on them; asking for the object's `__dict__` turns them into a real dict for
good, and every later attribute access on that object takes a slower path. Plain `pickle`
asks every object for its `__dict__` (`object.__reduce_ex__`), so each `VM.snapshot()` left
the neighbour ring, the stigmergy, the message queues and their entries slower: a Kilobot
swarm stepped ~3 % slower for the rest of the run once each robot had been snapshotted once
(measured A/B, alternating order; the recorder keyframes every robot).

Here the VM room's record classes (dataclasses, and `messages.RingBuffer`) are reduced to
`(_rebuild, (class, names, values))` with the values read attribute by attribute, which leaves
the inline values alone, and rebuilt with `object.__setattr__` on a fresh instance (no dict
either). Before that, `gc.get_referents` checks that the object holds exactly those
attributes (inline values are what it reports; a materialised dict shows as one dict); if not,
e.g. a class gained an attribute these names do not know, plain pickling takes over, which is
correct, only slower. The bytes are as deterministic as plain pickling, and `_rebuild` is a
`bbzide.vm` function, which the recording's snapshot allow-list admits.
"""

from __future__ import annotations

import dataclasses
import gc
import io
import pickle
from typing import Any

from bbzide.vm.messages import RingBuffer

#: Attribute names of the non-dataclass records, in the order their `__init__` sets them.
_KNOWN_NAMES: dict[type, tuple[str, ...]] = {RingBuffer: ("records", "capacity", "start", "end")}
_names_cache: dict[type, tuple[str, ...] | None] = {}


def _names(cls: type) -> tuple[str, ...] | None:
    names = _names_cache.get(cls, ())
    if names == ():
        if cls in _KNOWN_NAMES:
            names = _KNOWN_NAMES[cls]
        elif dataclasses.is_dataclass(cls) and cls.__module__.startswith("bbzide.vm.") \
                and not hasattr(cls, "__slots__"):
            names = tuple(f.name for f in dataclasses.fields(cls))
        else:
            names = None
        _names_cache[cls] = names
    return names


def _rebuild(cls: type, names: tuple[str, ...], values: tuple[Any, ...]) -> Any:
    """An instance of `cls` with these attributes, set one by one (no `__dict__` made)."""
    obj = cls.__new__(cls)
    for name, value in zip(names, values, strict=True):
        object.__setattr__(obj, name, value)
    return obj


class _RecordPickler(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        cls = type(obj)
        names = _names(cls) if not isinstance(obj, type) else None
        if names is None:
            return NotImplemented
        values = tuple(getattr(obj, name, _MISSING) for name in names)
        held = gc.get_referents(obj)  # inline values + the class; a made dict shows as a dict
        if (len(held) != len(values) + 1 or _MISSING in values
                or sorted(map(id, held)) != sorted(map(id, (*values, cls)))):
            return NotImplemented  # not exactly these attributes: plain pickling
        return (_rebuild, (cls, names, values))


_MISSING = object()


def dumps(value: Any) -> bytes:
    """`pickle.dumps(value)`, with the VM's records reduced as described above."""
    out = io.BytesIO()
    _RecordPickler(out, protocol=pickle.DEFAULT_PROTOCOL).dump(value)
    return out.getvalue()
