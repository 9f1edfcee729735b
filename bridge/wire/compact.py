"""A compact, lossless Bottle codec for the link, with deltas between messages.

Theory of operation
-------------------
YARP spends 4 bytes on every type tag and every length, so ``12 "a"`` costs 21
bytes on a tcp connection.  Here every value costs one kind byte plus its
content in varints, and a Bottle decoded from this form re-encodes to exactly
the bytes YARP sent (types are preserved: ``Int8``, ``Float32``, ``Vocab``...).

=====  =========  ===================================================
kind   value      content
=====  =========  ===================================================
0      INT32      zigzag varint
1..3   INT8/16/64 zigzag varint
4      VOCAB32    varint of the 32-bit code
5      FLOAT64    8 bytes, little endian
6      FLOAT64    4 bytes: the value is exactly a float32
7      FLOAT64    zigzag varint: the value is an exact small integer
8      FLOAT32    4 bytes
9/10   STRING     varint length + UTF-8 / BLOB: varint length + bytes
11/12  LIST/DICT  varint count + items
13     same-kind  element kind byte + varint count + contents (no per-item kind)
=====  =========  ===================================================

A top-level Bottle is ``varint count + items``.

Deltas: a status or a state changes a few numbers between two messages of the
same channel.  When the new Bottle has the same shape (kinds and list sizes)
as the previous one, :func:`encode_delta` sends a bitmap of the changed leaves,
integers as the zigzag difference, other leaves in full.  ``seq "a"`` where only
the sequence number moved costs 2 bytes.  Deltas are only valid between two
ends that agree on the previous message: the TCP channel keeps them per
connection and starts every new connection with full messages.

Hostile input: :func:`decode` and :func:`decode_delta` raise
:class:`BridgeProtocolError` naming the byte for anything malformed, and a
decoded Bottle always re-encodes as YARP (every integer fits its kind's
width, a vocab 32 bits, an integral float 53 bits).  Limits: lists nest at
most :data:`MAX_DEPTH` deep, and a count may not exceed the bytes left (each
item costs one at least), so memory stays proportional to the input, which
the link's frame limit bounds.
"""

from __future__ import annotations

import math
import struct
from typing import Any, List, Optional, Sequence, Tuple

from bridge.errors import BridgeProtocolError, NeedMoreData
from bridge.wire.varint import Buffer, get_svarint, get_varint, put_svarint, put_varint, take
from yarp_lite.bottle import (Bottle, Dict, Float32, Int8, Int16, Int64, Tag, Vocab, tag_of,
                              vocab_encode)

INT32, INT8, INT16, INT64, VOCAB, F64, F64_AS_F32, F64_AS_INT, F32, STRING, BLOB, LIST, DICT, \
    SAME_KIND = range(14)
_INTS = (INT32, INT8, INT16, INT64)
_INT_WRAP = {INT32: int, INT8: Int8, INT16: Int16, INT64: Int64}
_INT_BITS = {INT32: 32, INT8: 8, INT16: 16, INT64: 64}
_KIND_OF_TAG = {Tag.INT32: INT32, Tag.INT8: INT8, Tag.INT16: INT16, Tag.INT64: INT64,
                Tag.VOCAB32: VOCAB, Tag.FLOAT64: F64, Tag.FLOAT32: F32, Tag.STRING: STRING,
                Tag.BLOB: BLOB}
_F64 = struct.Struct("<d")
_F32 = struct.Struct("<f")
MAX_DEPTH = 64


def _kind_of(value: Any) -> int:
    if isinstance(value, Dict):
        return DICT
    if isinstance(value, (list, tuple)):
        return LIST
    return _KIND_OF_TAG[Tag(tag_of(value))]


def _vocab_code(value: Any) -> int:
    if isinstance(value, Vocab):
        return value.code
    if isinstance(value, bool):
        return ord("1") if value else 0
    return vocab_encode(str(value))


_CANONICAL_NAN = _F64.pack(math.nan)


def _f32_exact(value: float) -> bool:
    """True when float32 carries ``value`` bit for bit (the canonical NaN included)."""
    if value != value:
        return _F64.pack(value) == _CANONICAL_NAN
    try:
        return _F32.unpack(_F32.pack(value))[0] == value  # keeps -0.0 and infinities
    except OverflowError:
        return False


def _int_exact(value: float) -> bool:
    return value == value and not math.isinf(value) and value.is_integer() and \
        abs(value) < 2 ** 53 and not (value == 0 and math.copysign(1, value) < 0)


def _float_mode(value: float) -> int:
    """The cheapest exact representation of a float64."""
    if _int_exact(value):
        return F64_AS_INT
    if _f32_exact(value):
        return F64_AS_F32
    return F64


def _put_content(out: bytearray, kind: int, value: Any, depth: int) -> None:
    if kind in _INTS:
        put_svarint(out, int(value))
    elif kind == VOCAB:
        put_svarint(out, _vocab_code(value))
    elif kind == F64:
        out += _F64.pack(value)
    elif kind == F64_AS_F32 or kind == F32:
        out += _F32.pack(value)
    elif kind == F64_AS_INT:
        put_svarint(out, int(value))
    elif kind == STRING or kind == BLOB:
        data = value.encode("utf-8", "surrogateescape") if kind == STRING else bytes(value)
        put_varint(out, len(data))
        out += data
    else:  # LIST / DICT
        _put_items(out, value, depth + 1)


def _put_value(out: bytearray, value: Any, depth: int) -> None:
    kind = _kind_of(value)
    if kind == F64:
        kind = _float_mode(float(value))
    out.append(kind)
    _put_content(out, kind, value, depth)


def _put_items(out: bytearray, items: Sequence[Any], depth: int) -> None:
    if depth > MAX_DEPTH:
        raise BridgeProtocolError(f"Bottle nested deeper than {MAX_DEPTH}")
    if len(items) >= 3:
        kinds = {_kind_of(item) for item in items}
        if len(kinds) == 1:
            kind = kinds.pop()
            if kind not in (LIST, DICT):
                if kind == F64:
                    values = [float(item) for item in items]
                    if all(_int_exact(value) for value in values):
                        kind = F64_AS_INT
                    elif all(_f32_exact(value) for value in values):
                        kind = F64_AS_F32
                put_varint(out, len(items))
                out.append(SAME_KIND)
                out.append(kind)
                for item in items:
                    _put_content(out, kind, item, depth)
                return
    put_varint(out, len(items))
    for item in items:
        _put_value(out, item, depth)


def encode(bottle: Sequence[Any]) -> bytes:
    """A Bottle in compact form."""
    out = bytearray()
    _put_items(out, bottle, 0)
    return bytes(out)


def _integer(kind: int, value: int, what: str) -> int:
    """``value`` wrapped in its kind's type; out of its width is the peer's error."""
    half = 1 << (_INT_BITS[kind] - 1)
    if not -half <= value < half:
        raise BridgeProtocolError(f"{what}: {value} does not fit in {_INT_BITS[kind]} bits")
    return _INT_WRAP[kind](value)


class _Reader:
    def __init__(self, data: Buffer) -> None:
        self.data = data
        self.pos = 0

    def content(self, kind: int, depth: int) -> Any:
        data = self.data
        if kind in _INTS:
            value, self.pos = get_svarint(data, self.pos, "integer")
            return _integer(kind, value, f"integer at byte {self.pos}")
        if kind == VOCAB:
            value, self.pos = get_svarint(data, self.pos, "vocab")
            if not -(1 << 31) <= value < 1 << 31:
                raise BridgeProtocolError(f"vocab code {value} exceeds 32 bits")
            return Vocab(value)
        if kind == F64:
            raw, self.pos = take(data, self.pos, 8, "float64")
            return _F64.unpack(raw)[0]
        if kind == F64_AS_F32 or kind == F32:
            raw, self.pos = take(data, self.pos, 4, "float32")
            value = _F32.unpack(raw)[0]
            return Float32(value) if kind == F32 else float(value)
        if kind == F64_AS_INT:
            value, self.pos = get_svarint(data, self.pos, "float")
            if abs(value) >= 2 ** 53:
                raise BridgeProtocolError(f"integral float {value} out of range")
            return float(value)
        if kind == STRING or kind == BLOB:
            length, self.pos = get_varint(data, self.pos, "length")
            raw, self.pos = take(data, self.pos, length, "string")
            return raw.decode("utf-8", "surrogateescape") if kind == STRING else raw
        if kind == LIST or kind == DICT:
            return self.items(depth + 1, Dict() if kind == DICT else Bottle())
        raise BridgeProtocolError(f"unknown value kind {kind} at byte {self.pos - 1}")

    def value(self, depth: int) -> Any:
        kind, self.pos = self.kind()
        return self.content(kind, depth)

    def kind(self) -> Tuple[int, int]:
        if self.pos >= len(self.data):
            raise NeedMoreData(f"value kind missing at byte {self.pos}")
        return self.data[self.pos], self.pos + 1

    def items(self, depth: int, out: Bottle) -> Bottle:
        if depth > MAX_DEPTH:
            raise BridgeProtocolError(f"Bottle nested deeper than {MAX_DEPTH}")
        count, self.pos = get_varint(self.data, self.pos, "count")
        if count > len(self.data) - self.pos:  # every item takes at least one byte
            raise BridgeProtocolError(f"count {count} at byte {self.pos} exceeds the "
                                      f"{len(self.data) - self.pos} bytes left")
        if count >= 3 and self.pos < len(self.data) and self.data[self.pos] == SAME_KIND:
            self.pos += 1
            kind, self.pos = self.kind()
            if kind in (LIST, DICT, SAME_KIND) or kind > SAME_KIND:
                raise BridgeProtocolError(f"bad element kind {kind} in a same-kind list")
            for _ in range(count):
                out.append(self.content(kind, depth))
            return out
        for _ in range(count):
            out.append(self.value(depth))
        return out


def decode(data: Buffer) -> Bottle:
    """The Bottle in ``data``; :class:`BridgeProtocolError` says where it is malformed."""
    reader = _Reader(data)
    try:
        bottle = reader.items(0, Bottle())
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"truncated compact Bottle: {exc}") from None
    if reader.pos != len(data):
        raise BridgeProtocolError(f"{len(data) - reader.pos} bytes after the compact Bottle")
    return bottle


# -- deltas -------------------------------------------------------------------------


def _flatten(items: Sequence[Any], shape: List[Any], leaves: List[Tuple[int, Any]]) -> None:
    for item in items:
        kind = _kind_of(item)
        if kind == LIST or kind == DICT:
            shape.append((kind, len(item)))
            _flatten(item, shape, leaves)
        else:
            shape.append(kind)
            leaves.append((kind, item))


def shape_and_leaves(bottle: Sequence[Any]) -> Tuple[tuple, List[Tuple[int, Any]]]:
    shape: List[Any] = [len(bottle)]
    leaves: List[Tuple[int, Any]] = []
    _flatten(bottle, shape, leaves)
    return tuple(shape), leaves


def _same(kind: int, a: Any, b: Any) -> bool:
    if kind == F64 or kind == F32:
        return _F64.pack(a) == _F64.pack(b)
    return a == b and type(a) is type(b)


def encode_delta(bottle: Sequence[Any], previous: Sequence[Any]) -> Optional[bytes]:
    """``bottle`` as changes against ``previous``; None when their shapes differ."""
    shape, leaves = shape_and_leaves(bottle)
    old_shape, old_leaves = shape_and_leaves(previous)
    if shape != old_shape:
        return None
    bitmap = bytearray((len(leaves) + 7) // 8)
    body = bytearray()
    for index, ((kind, value), (_, old)) in enumerate(zip(leaves, old_leaves)):
        if _same(kind, value, old):
            continue
        bitmap[index // 8] |= 1 << (index % 8)
        if kind in _INTS:
            put_svarint(body, int(value) - int(old))
        elif kind == F64:
            mode = _float_mode(float(value))
            body.append(mode)
            _put_content(body, mode, value, 0)
        else:
            _put_content(body, kind, value, 0)
    return bytes(bitmap + body)


def decode_delta(data: Buffer, previous: Sequence[Any]) -> Bottle:
    """Apply a delta from :func:`encode_delta` to ``previous``."""
    shape, old_leaves = shape_and_leaves(previous)
    width = (len(old_leaves) + 7) // 8
    if len(data) < width:
        raise BridgeProtocolError(f"delta of {len(data)} bytes is shorter than its "
                                  f"{width}-byte bitmap")
    reader = _Reader(data)
    reader.pos = width
    new_leaves: List[Any] = []
    try:
        for index, (kind, old) in enumerate(old_leaves):
            if not data[index // 8] & (1 << (index % 8)):
                new_leaves.append(old)
            elif kind in _INTS:
                change, reader.pos = get_svarint(data, reader.pos, "integer delta")
                new_leaves.append(_integer(kind, int(old) + change,
                                           f"integer delta {change} of leaf {index}"))
            elif kind == F64:
                mode, reader.pos = reader.kind()
                if mode not in (F64, F64_AS_F32, F64_AS_INT):
                    raise BridgeProtocolError(f"bad float mode {mode} in a delta")
                new_leaves.append(reader.content(mode, 0))
            else:
                new_leaves.append(reader.content(kind, 0))
    except NeedMoreData as exc:
        raise BridgeProtocolError(f"truncated delta: {exc}") from None
    if reader.pos != len(data):
        raise BridgeProtocolError(f"{len(data) - reader.pos} bytes after the delta")
    spare = len(old_leaves) % 8
    if spare and data[width - 1] >> spare:
        raise BridgeProtocolError("delta bitmap marks leaves that do not exist")
    return _rebuild(previous, iter(new_leaves))


def _rebuild(template: Sequence[Any], leaves) -> Bottle:
    out: Bottle = Dict() if isinstance(template, Dict) else Bottle()
    for item in template:
        if isinstance(item, (list, tuple)):
            out.append(_rebuild(item, leaves))
        else:
            out.append(next(leaves))
    return out
