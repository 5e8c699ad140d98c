"""Pickling a VM's records for `VM.pickled_snapshot()` without slowing the live VM down afterwards.

A snapshot is pickled only when the state is outside the flat layout's shape
(`snapshot_layout`); recordings of formats 2 and 3 hold pickled snapshots, which still restore.

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
import operator
import pickle
from collections.abc import Callable
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
    def __init__(self, out: io.BytesIO, plain_lists: frozenset[int]) -> None:
        super().__init__(out, protocol=pickle.DEFAULT_PROTOCOL)
        #: ids of the lists to write as lists (shared within the graph: see `dumps`)
        self.plain_lists = plain_lists
        #: what was written as rows: (list, its items), to check for sharing afterwards
        self.flattened: list[tuple[list[Any], list[Any]]] = []

    def reducer_override(self, obj: Any) -> Any:
        # Called for every record of a snapshot (~150 in an M300 drone's), so kept lean: one
        # cached C getter per class, and the attribute check by count (see `_exactly`).
        cls = type(obj)
        reader = _readers.get(cls)
        if reader is None:
            if isinstance(obj, type) or (reader := _reader(cls)) is None:
                return NotImplemented
        names, get = reader
        try:
            values = get(obj)
        except AttributeError:
            return NotImplemented  # an attribute missing: plain pickling
        if not _exactly(obj, names, values):
            return NotImplemented  # not exactly these attributes: plain pickling
        if any(type(value) is list for value in values):
            values = tuple(self._rows(value) if type(value) is list else value
                           for value in values)
        return (_rebuild, (cls, names, values))

    def _rows(self, items: list[Any]) -> list[Any] | _Rows:
        """`items` as `_Rows` when they are all exactly-known records of one class, else as
        is (and as is when `dumps` found this list or one of its items shared)."""
        if not items or id(items) in self.plain_lists:
            return items
        cls = type(items[0])
        reader = _readers.get(cls) or _reader(cls)
        if reader is None:
            return items
        names, get = reader
        flat: list[Any] = []
        for item in items:
            if type(item) is not cls:
                return items
            try:
                values = get(item)
            except AttributeError:
                return items
            if not _exactly(item, names, values):
                return items
            flat.extend(values)
        self.flattened.append((items, list(items)))
        return _Rows(cls, names, tuple(flat))


class _Rows:
    """A list of records of one class, written as one flat tuple of their attribute values
    (`_rebuild_rows`): the neighbour ring and the stigmergy entries are ~130 small records in
    an M300 drone's snapshot, and a reduce per record was most of the pickling time. Used only
    where every item passes the same check as a single record, and never for a list that
    something else in the pickled value also holds, or whose items it holds (`dumps`)."""

    __slots__ = ("cls", "names", "flat")

    def __init__(self, cls: type, names: tuple[str, ...], flat: tuple[Any, ...]) -> None:
        self.cls, self.names, self.flat = cls, names, flat

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild_rows, (self.cls, self.names, self.flat))


def _shared(pickler: _RecordPickler) -> set[int]:
    """ids of the lists `pickler` wrote as rows that the pickled value shares: the list or
    one of its items was also written as itself (then it is in the pickle memo, which holds
    every object written as itself), or appears in two rows. Only the pickled value counts,
    not who else holds these objects: the choice, and so the bytes, follow from the value."""
    if not pickler.flattened:
        return set()
    memo = pickler.memo.copy()  # id -> (memo index, object); ~15 us for an M300 drone's
    seen: set[int] = set()
    shared: set[int] = set()
    for items, members in pickler.flattened:
        ids = [id(items), *map(id, members)]
        if any(i in memo or i in seen for i in ids):
            shared.add(id(items))
        seen.update(ids)
    return shared


def _rebuild_rows(cls: type, names: tuple[str, ...], flat: tuple[Any, ...]) -> list[Any]:
    """The records of `_Rows`, rebuilt like `_rebuild` (no `__dict__` made)."""
    width = len(names)
    if width == 0 or len(flat) % width:
        raise ValueError("damaged record rows")
    return [_rebuild(cls, names, flat[at:at + width]) for at in range(0, len(flat), width)]


#: class -> (attribute names, a getter of their values as a tuple), for the known records
_readers: dict[type, tuple[tuple[str, ...], Callable[[Any], tuple[Any, ...]]]] = {}


def _reader(cls: type) -> tuple[tuple[str, ...], Callable[[Any], tuple[Any, ...]]] | None:
    names = _names(cls)
    if names is None:
        return None
    get = operator.attrgetter(*names)
    # attrgetter of one name returns the value itself, not a 1-tuple
    found = (names, get if len(names) > 1 else (lambda obj: (get(obj),)))
    _readers[cls] = found
    return found


def _exactly(obj: Any, names: tuple[str, ...], values: tuple[Any, ...]) -> bool:
    """Whether `obj` holds exactly the attributes `names` (all read already) as inline values.
    `gc.get_referents` reports the inline values that are set, plus the class; an object whose
    dict was made reports that dict instead. With every name present, a count of len(names) + 1
    leaves no room for an extra attribute. Only for one name could a made dict match that
    count, so one-name records compare the referents themselves."""
    held = gc.get_referents(obj)
    if len(held) != len(names) + 1:
        return False
    return len(names) > 1 or sorted(map(id, held)) == sorted(map(id, (*values, type(obj))))


def dumps(value: Any) -> bytes:
    """`pickle.dumps(value)`, with the VM's records reduced as described above.

    Lists of records are written as rows unless the value itself shares the list or one of
    its items (then rows would unpickle as copies): the dump is checked afterwards and, if
    any are shared, done again with those lists written as lists (a VM's never are, so
    that is one dump). Deciding from the value alone makes equal states give equal bytes
    whatever else holds their objects (it was decided by `sys.getrefcount`, which counts
    outside holders too: a garbage cycle not yet collected could change a snapshot's bytes).
    """
    plain: frozenset[int] = frozenset()
    while True:
        out = io.BytesIO()
        pickler = _RecordPickler(out, plain)
        pickler.dump(value)
        shared = _shared(pickler)
        if not shared:
            return out.getvalue()
        plain = plain | shared
