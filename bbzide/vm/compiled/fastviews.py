"""Arrays the compiled swarm step reaches by address: a robot's buffers without typed lists.

The compiled swarm step (:func:`fastbatch.swarm_step`) needs, for every robot, the arrays
the VM already owns — heap bytes, stack, bytecode, collector scratch, packed queues —
without copying them. numba's typed lists would carry them, but each element type of a
typed list is compiled at first use in every process and cannot be cached: ~4-7 s before
a swarm's first step (measured), which a short CLI run or the IDE would feel. Instead the
Python side records each array's **data address and length** once per swarm
(``swarm_batch_fast._SwarmTables``, which also keeps the arrays alive), and the kernel
rebuilds a view with :func:`view_u8` etc.: ``numba.carray`` over a pointer made from the
address by :func:`_pointer` (an LLVM ``inttoptr``). Views made this way own nothing; they
are valid while the arrays live and are not moved, which holds here: a heap ``bytearray``
and a stack ``array`` with an exported buffer (the VM's ``np.frombuffer`` views) cannot be
resized, ``bytes`` never move, and the packed arrays are re-recorded whenever one is
replaced (``packed_queues.arrays_changed``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bbzide.vm.compiled.fastgc import COMPILED, _compile_owning

__all__ = ["COMPILED", "view_u8", "view_u16", "view_i32", "view_i64", "view_i64_rows",
           "address_of"]

if COMPILED:
    from numba import carray, types
    from numba.extending import intrinsic

    def _make_pointer(element: Any) -> Any:
        @intrinsic
        def pointer(typingctx: Any, address: Any) -> Any:
            """The int ``address`` as a ``element *`` (LLVM ``inttoptr``)."""
            signature = types.CPointer(element)(types.int64)

            def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
                return builder.inttoptr(args[0], context.get_value_type(sig.return_type))

            return signature, codegen

        return pointer

    _pointer_u8 = _make_pointer(types.uint8)
    _pointer_u16 = _make_pointer(types.uint16)
    _pointer_i32 = _make_pointer(types.int32)
    _pointer_i64 = _make_pointer(types.int64)

    @_compile_owning
    def view_u8(address: int, length: int) -> Any:
        return carray(_pointer_u8(address), (length,))

    @_compile_owning
    def view_u16(address: int, length: int) -> Any:
        return carray(_pointer_u16(address), (length,))

    @_compile_owning
    def view_i32(address: int, length: int) -> Any:
        return carray(_pointer_i32(address), (length,))

    @_compile_owning
    def view_i64(address: int, length: int) -> Any:
        return carray(_pointer_i64(address), (length,))

    @_compile_owning
    def view_i64_rows(address: int, rows: int, columns: int) -> Any:
        return carray(_pointer_i64(address), (rows, columns))
else:  # pragma: no cover - without numba the swarm step is not compiled at all
    view_u8 = view_u16 = view_i32 = view_i64 = view_i64_rows = None  # type: ignore[assignment]


def address_of(array: np.ndarray) -> int:
    """The data address of a C-contiguous array (0 for an empty one: never read)."""
    if not array.flags.c_contiguous:
        raise ValueError("a compiled view needs a C-contiguous array")
    return int(array.__array_interface__["data"][0]) if array.size else 0
