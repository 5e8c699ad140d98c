"""The byte layout of BittyBuzz heap objects and table segments (spec §E.2, §E.4).

An object is S bytes: byte 0 is its metadata — type in bits 0-2, valid bit 3, permanent bit
4, GC mark bit 5, two type flags in bits 6-7 — and the payload follows, little-endian. A
table segment is E u16 keys, E u16 values and one u16 metadata word (valid bit 15, GC mark
bit 14, index of the next segment in bits 0-13). Element words carry valid in bit 15 and
a heap index in bits 0-14.

Constants only, importing nothing: the model (`heap.py` re-exports them) and the compiled
kernels (`compiled/`) read the same bytes through the same names.
"""

# Object types (bits 0-2 of the metadata byte).
NIL, INT, FLOAT, STRING, TABLE, CLOSURE, USERDATA = range(7)
TYPE_MASK = 0x07
VALID = 0x08
PERMANENT = 0x10
GC_MARK = 0x20
FLAG1 = 0x40   # table: darray; closure: native (bytecode) closure
FLAG2 = 0x80   # darray: has-self activation record; closure: lambda

# Segment words (spec §E.4).
ELEM_VALID = 0x8000
ELEM_INDEX = 0x7FFF
SEG_VALID = 0x8000
SEG_MARK = 0x4000
SEG_NEXT = 0x3FFF      # also the "no next segment" value
NO_ACTREC = 0xFF       # lambda byte 2: uses the default activation record
