"""The row count a Parquet file's footer records, read without pyarrow: a cache hit checks every part's row count
against its manifest (``store.Run.part_problem``), and importing pyarrow (and numpy, which it loads) for that
took 0.1 s of a 0.35 s cache hit.

A Parquet file ends with its FileMetaData (Thrift compact protocol), the metadata's length (4 bytes, little
endian) and ``PAR1`` (apache/parquet-format, ``parquet.thrift``: FileMetaData's field 3 is ``num_rows``, an i64;
field 2, the schema, comes before it). The compact protocol (apache/thrift, ``doc/specs/thrift-compact-protocol.md``):
a field header byte holds the field id's delta (high nibble; 0: a zigzag varint id follows) and the type (low
nibble); integers are zigzag varints; binary is a varint length and the bytes; a list or set header holds the size
(high nibble; 15: a varint size follows) and the element type; a map a varint size, then the key and value types.
Held to pyarrow's ``read_metadata`` in ``tests/test_parquet_footer.py``.
"""
from __future__ import annotations

MAGIC = b"PAR1"
STOP, TRUE, FALSE, BYTE, I16, I32, I64, DOUBLE, BINARY, LIST, SET, MAP, STRUCT, UUID = range(14)
#: Deeper nesting than Parquet's metadata has is refused (a crafted footer cannot recurse without bound).
MAX_DEPTH = 32
NUM_ROWS_FIELD = 3


class Malformed(ValueError):
    """Bytes that are not a Thrift compact FileMetaData."""


class _Reader:
    def __init__(self, data: bytes):
        self.data, self.pos = data, 0

    def byte(self) -> int:
        if self.pos >= len(self.data):
            raise Malformed("ends inside the metadata")
        b = self.data[self.pos]
        self.pos += 1
        return b

    def skip_bytes(self, n: int) -> None:
        if n < 0 or self.pos + n > len(self.data):
            raise Malformed("a length past the metadata's end")
        self.pos += n

    def varint(self) -> int:
        shift = out = 0
        while True:
            b = self.byte()
            out |= (b & 0x7F) << shift
            if not b & 0x80:
                return out
            shift += 7
            if shift > 63:
                raise Malformed("a varint longer than 64 bits")

    def zigzag(self) -> int:
        n = self.varint()
        return (n >> 1) ^ -(n & 1)

    def skip(self, kind: int, depth: int) -> None:
        """Past one value of this compact type."""
        if depth > MAX_DEPTH:
            raise Malformed("nested deeper than a Parquet footer is")
        if kind in (TRUE, FALSE):
            return  # a field's bool is in its header (a list's bools are bytes: ``skip_element``)
        if kind == BYTE:
            self.skip_bytes(1)
        elif kind in (I16, I32, I64):
            self.varint()
        elif kind == DOUBLE:
            self.skip_bytes(8)
        elif kind == BINARY:
            self.skip_bytes(self.varint())
        elif kind == UUID:
            self.skip_bytes(16)
        elif kind in (LIST, SET):
            head = self.byte()
            size, element = head >> 4, head & 0x0F
            if size == 15:
                size = self.varint()
            for _ in range(size):
                self.skip_element(element, depth + 1)
        elif kind == MAP:
            size = self.varint()
            if size:
                types = self.byte()
                for _ in range(size):
                    self.skip_element(types >> 4, depth + 1)
                    self.skip_element(types & 0x0F, depth + 1)
        elif kind == STRUCT:
            for _ in self.fields(depth + 1):
                pass
        else:
            raise Malformed(f"unknown compact type {kind}")

    def skip_element(self, kind: int, depth: int) -> None:
        """Past one element of a list, set or map (a bool there is a byte)."""
        if kind in (TRUE, FALSE):
            self.skip_bytes(1)
        else:
            self.skip(kind, depth)

    def fields(self, depth: int):
        """(field id, type) of each field of a struct, the reader left at its value; the caller reads it or not
        (an unread value is skipped)."""
        last = 0
        while True:
            head = self.byte()
            kind = head & 0x0F
            if kind == STOP:
                return
            delta = head >> 4
            last = last + delta if delta else self.zigzag()
            start = self.pos
            yield last, kind
            if self.pos == start:
                self.skip(kind, depth)


def footer_num_rows(data: bytes) -> int | None:
    """FileMetaData.num_rows of a whole Parquet file's bytes, or None when its footer cannot be read as one."""
    if len(data) < 12 or data[-4:] != MAGIC:
        return None
    length = int.from_bytes(data[-8:-4], "little")
    if length <= 0 or length > len(data) - 12:
        return None
    reader = _Reader(data[len(data) - 8 - length:len(data) - 8])
    try:
        for field, kind in reader.fields(0):
            if field == NUM_ROWS_FIELD and kind == I64:
                return reader.zigzag()
    except Malformed:
        return None
    return None
