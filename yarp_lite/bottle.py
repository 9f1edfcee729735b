"""Bottles: YARP's self-describing message, and its binary codec.

Theory of operation
-------------------
A Bottle is a list of typed values.  On the wire (``doc/data_rep.dox`` and
``Bottle.h``/``Storable.cpp`` of YARP 3.5) every value has a 32-bit type tag:

======== ===== =================================================
INT8      32   1 byte
INT16     64   2 bytes, little endian
INT32      1   4 bytes
INT64     17   8 bytes
VOCAB32    9   4 bytes, up to four characters packed low byte first
FLOAT32  128   IEEE 754 single
FLOAT64   10   IEEE 754 double
STRING     4   int32 length + bytes (no terminating NUL since YARP 3)
BLOB      12   int32 length + bytes
LIST     256   int32 count + elements; ``256 + T`` when every element has
               the primitive tag T (a "typed list": element tags omitted)
DICT     768   (LIST|DICT) followed by a complete Bottle of (key value) lists
======== ===== =================================================

A top-level Bottle starts with its list code, then the count.  A nested list's
code is its element tag inside the parent.  YARP picks the typed-list form
whenever all elements share one primitive tag; we do the same, so what we
encode is byte-identical to what real YARP encodes for the same values.

Python values map onto tags as YARP's own text parser would choose: ``int``
becomes INT32 when it fits and INT64 otherwise, ``float`` FLOAT64, ``str``
STRING, ``bytes`` BLOB, ``bool`` the vocabs YARP uses for true/false, and
``list``/``tuple``/:class:`Bottle` a LIST.  The wrapper types below
(:class:`Int8`, :class:`Float32`, :class:`Vocab`, ...) pin any other tag, and
decoding always returns them, so a decode/encode round trip is bit-identical.

The codec is pure: :func:`encode` returns bytes, :func:`decode` takes a buffer
and either returns a Bottle or raises :class:`RemoteProtocolError` naming the
offset and the problem.  No length read from the wire is trusted before it is
checked against the bytes actually present, so a bogus 4 GB length costs
nothing.

Limits: lists nest at most :data:`MAX_DEPTH` deep; a buffer is decoded
whole, so its size is bounded by whoever framed it (a connection's
``max_message``, 256 MiB by default, see :mod:`yarp_lite.framing`), and
every item costs at least 4 bytes of it, so the decoded Bottle stays
proportional to the bytes received.
"""

from __future__ import annotations

import math
import struct
from typing import Any, Iterable, Iterator, List, Optional, Sequence, Union

from yarp_lite.errors import LocalProtocolError, NeedMoreData, RemoteProtocolError
from yarp_lite.values import (_INT32_MAX, _INT32_MIN, _INT64_MAX, _INT64_MIN,  # noqa: F401
                              DICT_CODE, GROUP_MASK, MAX_DEPTH, UNIT_MASK, VOCAB_FALSE,
                              VOCAB_TRUE, Float32, Float64, Int8, Int16, Int32, Int64, Tag,
                              Vocab, vocab_decode, vocab_encode)


_S8 = struct.Struct("<b")
_S16 = struct.Struct("<h")
_S32 = struct.Struct("<i")
_S64 = struct.Struct("<q")
_F32 = struct.Struct("<f")
_F64 = struct.Struct("<d")
_TWO_INTS = struct.Struct("<ii")

# Fixed-size primitive tags: tag -> struct format character.
_FIXED = {Tag.INT8: "b", Tag.INT16: "h", Tag.INT32: "i", Tag.INT64: "q",
          Tag.VOCAB32: "i", Tag.FLOAT32: "f", Tag.FLOAT64: "d"}
_FIXED_SIZE = {tag: struct.calcsize("<" + fmt) for tag, fmt in _FIXED.items()}


class Bottle(list):
    """A YARP Bottle: a list whose items keep their wire types.

    Construct from values, ``Bottle([1, "hello", (2.5, 3)])``, or from text with
    :func:`yarp_lite.bottle_text.parse`.  ``str(bottle)`` is YARP's text form,
    the same text ``yarp read`` prints.
    """

    __slots__ = ()

    def to_text(self) -> str:
        return format_bottle(self)

    def __str__(self) -> str:
        return self.to_text()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({list.__repr__(self)})"

    def find(self, key: str, default: Any = None) -> Any:
        """The value after ``key``, or inside a ``(key value)`` group (YARP's find)."""
        for index, item in enumerate(self):
            if isinstance(item, list):
                if item and _key_text(item[0]) == key:
                    return item[1] if len(item) > 1 else default
            elif _key_text(item) == key and index + 1 < len(self):
                return self[index + 1]
        return default

    def find_group(self, key: str) -> "Bottle | None":
        """The first ``(key ...)`` sub-list, or None (YARP's findGroup)."""
        for item in self:
            if isinstance(item, list) and item and _key_text(item[0]) == key:
                return item if isinstance(item, Bottle) else Bottle(item)
        return None

    def check(self, key: str) -> bool:
        return self.find_group(key) is not None or any(
            _key_text(item) == key for item in self if not isinstance(item, list))


class Dict(Bottle):
    """A YARP Property on the wire: a Bottle of ``(key value...)`` groups.

    Real YARP sends dicts with keys in sorted order; building one from a
    Python dict does the same.
    """

    __slots__ = ()

    @classmethod
    def from_mapping(cls, mapping: dict) -> "Dict":
        return cls(Bottle([key, *(value if isinstance(value, (list, tuple)) else (value,))])
                   for key, value in sorted(mapping.items()))

    def to_mapping(self) -> dict:
        result = {}
        for group in self:
            if isinstance(group, list) and group:
                rest = group[1:]
                result[str(group[0])] = rest[0] if len(rest) == 1 else Bottle(rest)
        return result


def _key_text(value: Any) -> str:
    """How YARP's find() compares keys: by the value's plain text."""
    return value if isinstance(value, str) else str(value)


Value = Any  # one Bottle item: int, float, str, bytes, Vocab, Bottle, ...


# --------------------------------------------------------------------------
# Tags of Python values


def tag_of(value: Value) -> int:
    """The wire tag YARP would use for ``value`` (``Storable::getCode``)."""
    kind = type(value)
    if kind is int:
        if _INT32_MIN <= value <= _INT32_MAX:
            return Tag.INT32
        if _INT64_MIN <= value <= _INT64_MAX:
            return Tag.INT64
        raise LocalProtocolError(f"integer {value} does not fit in 64 bits")
    tag = _TAG_BY_TYPE.get(kind)
    if tag is not None:
        return tag
    if kind is Bottle or kind is list or kind is tuple:
        return Tag.LIST + _sub_code(value)
    if isinstance(value, Dict):
        return DICT_CODE
    if isinstance(value, (Bottle, list, tuple)):
        return Tag.LIST + _sub_code(value)
    if isinstance(value, bool):
        return Tag.VOCAB32
    for cls, cls_tag in _TAG_BY_SUBCLASS:
        if isinstance(value, cls):
            return tag_of(int(value)) if cls_tag is None else cls_tag
    if isinstance(value, dict):
        return DICT_CODE
    if hasattr(value, "__index__"):  # numpy integers and friends
        return tag_of(int(value.__index__()))
    if hasattr(value, "__float__"):
        return Tag.FLOAT64
    raise LocalProtocolError(f"cannot put a {kind.__name__} in a Bottle: {value!r}")


_TAG_BY_TYPE = {float: Tag.FLOAT64, str: Tag.STRING, bytes: Tag.BLOB, bytearray: Tag.BLOB,
                memoryview: Tag.BLOB, bool: Tag.VOCAB32, Int8: Tag.INT8, Int16: Tag.INT16,
                Int32: Tag.INT32, Int64: Tag.INT64, Float32: Tag.FLOAT32,
                Float64: Tag.FLOAT64, Vocab: Tag.VOCAB32}
# Subclass fallbacks, most specific first; None means "decide from the int value".
_TAG_BY_SUBCLASS: list = [(Vocab, Tag.VOCAB32), (Int8, Tag.INT8), (Int16, Tag.INT16),
                          (Int64, Tag.INT64), (Int32, Tag.INT32), (Float32, Tag.FLOAT32),
                          (float, Tag.FLOAT64), (str, Tag.STRING),
                          ((bytes, bytearray, memoryview), Tag.BLOB), (int, None)]


def _sub_code(items: Sequence[Value]) -> int:
    """Element tag shared by every item, or 0 (YARP's ``subCoder``)."""
    if not items:
        return 0
    first = tag_of(items[0])
    if first & GROUP_MASK:
        return 0
    for item in items[1:] if len(items) > 1 else ():
        if tag_of(item) != first:
            return 0
    return first


# --------------------------------------------------------------------------
# Encoding


def encode(bottle: Sequence[Value]) -> bytes:
    """Encode a top-level Bottle exactly as YARP's ``Bottle::write`` does."""
    out = _Out()
    _encode_list(out, bottle, with_code=True)
    return bytes(out)


#: Blobs and strings at least this long are referenced, not copied, by encode_chunks.
ZERO_COPY_THRESHOLD = 16384


def encode_chunks(bottle: Sequence[Value]) -> List[Union[bytes, bytearray, memoryview]]:
    """Encode like :func:`encode`, but as a list of buffers to send in order.

    Large blobs stay where they are (a memoryview is listed instead of a
    copy), so a 1 MB image goes from the caller's buffer to the kernel in one
    copy.  ``b"".join(encode_chunks(b)) == encode(b)`` always.
    """
    out = _Out(chunked=True)
    _encode_list(out, bottle, with_code=True)
    return out.finish()


class _Out(bytearray):
    """The encoder's output: a bytearray that can also set large buffers aside."""

    def __init__(self, chunked: bool = False) -> None:
        super().__init__()
        self.chunks: Optional[list] = [] if chunked else None

    def big(self, data: Union[bytes, bytearray, memoryview]) -> None:
        if self.chunks is None or memoryview(data).nbytes < ZERO_COPY_THRESHOLD:
            self += data
            return
        self.chunks.append(bytes(self))
        self.chunks.append(memoryview(data).cast("B"))
        del self[:]

    def finish(self) -> list:
        assert self.chunks is not None
        if len(self) or not self.chunks:
            self.chunks.append(bytes(self))
        return self.chunks


def _encode_list(out: bytearray, items: Sequence[Value], with_code: bool) -> None:
    sub = _sub_code(items)
    if with_code:
        out += _TWO_INTS.pack(Tag.LIST + sub, len(items))
    else:
        out += _S32.pack(len(items))
    if sub:
        _encode_typed_items(out, sub, items)
        return
    for item in items:
        tag = tag_of(item)
        out += _S32.pack(tag)
        _encode_raw(out, tag, item)


def _encode_typed_items(out: bytearray, tag: int, items: Sequence[Value]) -> None:
    fmt = _FIXED.get(tag)
    if fmt is not None:
        if tag == Tag.VOCAB32:
            items = [_vocab_code(item) for item in items]
        out += struct.pack(f"<{len(items)}{fmt}", *items)
        return
    for item in items:
        _encode_raw(out, tag, item)


def _vocab_code(value: Value) -> int:
    if isinstance(value, Vocab):
        return value.code
    if isinstance(value, bool):
        return VOCAB_TRUE.code if value else VOCAB_FALSE.code
    return Vocab(value).code


def _encode_raw(out: bytearray, tag: int, value: Value) -> None:
    if tag == Tag.INT32:
        out += _S32.pack(value)
    elif tag == Tag.FLOAT64:
        out += _F64.pack(value)
    elif tag == Tag.STRING:
        raw = value.encode("utf-8", "surrogateescape")
        out += _S32.pack(len(raw))
        out += raw
    elif tag == Tag.BLOB:
        out += _S32.pack(len(value) if not isinstance(value, memoryview) else value.nbytes)
        out.big(value)
    elif tag == Tag.INT64:
        out += _S64.pack(value)
    elif tag == Tag.VOCAB32:
        out += _S32.pack(_vocab_code(value))
    elif tag == Tag.INT8:
        out += _S8.pack(value)
    elif tag == Tag.INT16:
        out += _S16.pack(value)
    elif tag == Tag.FLOAT32:
        out += _F32.pack(value)
    elif tag == DICT_CODE:
        group = value if isinstance(value, Dict) else Dict.from_mapping(value)
        _encode_list(out, group, with_code=True)
    else:  # LIST or typed LIST
        _encode_list(out, value, with_code=False)


# --------------------------------------------------------------------------
# Decoding


def decode(buffer: Union[bytes, bytearray, memoryview], where: str = "bottle") -> Bottle:
    """Decode one top-level Bottle that fills ``buffer`` exactly.

    Raises :class:`RemoteProtocolError` (naming the byte offset) for a
    truncated, oversized or malformed buffer.
    """
    view = memoryview(buffer).cast("B") if not isinstance(buffer, bytes) else buffer
    bottle, end = decode_prefix(view, 0, where)
    if end != len(view):
        raise RemoteProtocolError(
            f"{len(view) - end} unexpected bytes after the Bottle (it ends at offset {end})", where)
    return bottle


def decode_prefix(buffer: Union[bytes, memoryview], offset: int = 0,
                  where: str = "bottle") -> "tuple[Bottle, int]":
    """Decode a top-level Bottle starting at ``offset``; return it and where it ends."""
    reader = _Reader(buffer, offset, where)
    code = reader.int32("list code")
    if code & ~(UNIT_MASK | GROUP_MASK):
        reader.fail(f"invalid top-level list code {code}", reader.pos - 4)
    bottle = Bottle()  # YARP reads any top-level code as a plain list too
    reader.list_body(bottle, code & UNIT_MASK, depth=0)
    return bottle, reader.pos


class _Reader:
    """Cursor over a buffer; every read checks the bytes are really there."""

    __slots__ = ("buf", "pos", "end", "where")

    def __init__(self, buf: Union[bytes, memoryview], pos: int, where: str) -> None:
        self.buf, self.pos, self.end, self.where = buf, pos, len(buf), where

    def fail(self, message: str, at: int | None = None) -> None:
        raise RemoteProtocolError(f"{message} at offset {self.pos if at is None else at}",
                                  self.where)

    def need(self, count: int, what: str) -> None:
        if self.pos + count > self.end:
            self.truncated(f"{what} needs {count} bytes, {self.end - self.pos} left")

    def truncated(self, message: str) -> None:
        """Input ends early: fatal for a whole buffer, "wait" for a stream."""
        raise NeedMoreData(f"truncated: {message} at offset {self.pos}", self.where)

    def int32(self, what: str) -> int:
        self.need(4, what)
        value = _S32.unpack_from(self.buf, self.pos)[0]
        self.pos += 4
        return value

    def list_body(self, out: list, sub: int, depth: int) -> None:
        if depth > MAX_DEPTH:
            self.fail(f"lists nested deeper than {MAX_DEPTH}")
        count = self.int32("list length")
        if count < 0:
            self.fail(f"negative list length {count}", self.pos - 4)
        if sub:
            if sub not in _FIXED and sub not in (Tag.STRING, Tag.BLOB):
                self.fail(f"typed list of unknown element type {sub}", self.pos - 8)
            size = _FIXED_SIZE.get(sub, 4)
            if count * size > self.end - self.pos:
                self.truncated(f"{count} items of type {sub} need at least "
                               f"{count * size} bytes, {self.end - self.pos} left")
            fmt = _FIXED.get(sub)
            if fmt is not None:
                values = struct.unpack_from(f"<{count}{fmt}", self.buf, self.pos)
                self.pos += count * size
                wrap = _WRAP[sub]
                out.extend(values if wrap is None else map(wrap, values))
            else:
                for _ in range(count):
                    out.append(self.raw(sub, depth))
            return
        if count * 4 > self.end - self.pos:
            self.truncated(f"{count} tagged items need at least {count * 4} bytes, "
                           f"{self.end - self.pos} left")
        for _ in range(count):
            out.append(self.raw(self.int32("item tag"), depth))

    def raw(self, tag: int, depth: int) -> Value:
        fmt = _FIXED.get(tag)
        if fmt is not None:
            size = _FIXED_SIZE[tag]
            self.need(size, f"value of type {tag}")
            value = struct.unpack_from("<" + fmt, self.buf, self.pos)[0]
            self.pos += size
            wrap = _WRAP[tag]
            return value if wrap is None else wrap(value)
        if tag == Tag.STRING or tag == Tag.BLOB:
            length = self.int32("string length" if tag == Tag.STRING else "blob length")
            if length < 0:
                self.fail(f"negative length {length}", self.pos - 4)
            self.need(length, "string" if tag == Tag.STRING else "blob")
            data = bytes(self.buf[self.pos:self.pos + length])
            self.pos += length
            return data.decode("utf-8", "surrogateescape") if tag == Tag.STRING else data
        if tag & GROUP_MASK and not tag & ~(UNIT_MASK | GROUP_MASK):
            if tag & Tag.DICT:
                code = self.int32("dict list code")
                if code & ~(UNIT_MASK | GROUP_MASK):
                    self.fail(f"invalid dict list code {code}", self.pos - 4)
                nested: list = Dict()
                self.list_body(nested, code & UNIT_MASK, depth + 1)
                return nested
            nested = Bottle()
            self.list_body(nested, tag & UNIT_MASK, depth + 1)
            return nested
        self.fail(f"unknown type tag {tag}", self.pos - 4)
        raise AssertionError  # unreachable: fail() raises


# Decoded fixed-size values get their wrapper type so re-encoding keeps the tag.
_WRAP = {Tag.INT8: Int8, Tag.INT16: Int16, Tag.INT32: None, Tag.INT64: Int64,
         Tag.VOCAB32: Vocab, Tag.FLOAT32: Float32, Tag.FLOAT64: None}


def iter_leaves(bottle: Iterable[Value]) -> Iterator[Value]:
    """Every non-list value in a Bottle, depth first (handy in tests and tools)."""
    for item in bottle:
        if isinstance(item, list):
            yield from iter_leaves(item)
        else:
            yield item


# --------------------------------------------------------------------------
# Text form (``BottleImpl::toString``; parsing is in :mod:`yarp_lite.bottle_text`)


def format_bottle(items: Iterable[Value]) -> str:
    """Text form of a top-level Bottle (``BottleImpl::toString``)."""
    return " ".join(format_value(item) for item in items)


def format_value(value: Value) -> str:
    """Text form of one item as it appears inside a Bottle (``toStringNested``)."""
    tag = tag_of(value)
    if tag in (Tag.INT32, Tag.INT64, Tag.INT8, Tag.INT16):
        return str(int(value))
    if tag == Tag.FLOAT64 or tag == Tag.FLOAT32:
        return format_double(float(value))
    if tag == Tag.STRING:
        return quote_string(value)
    if tag == Tag.VOCAB32:
        code = value.code if isinstance(value, Vocab) else (ord("1") if value else 0)
        if code == 0:
            return "false"
        if code == ord("1"):
            return "true"
        return "[" + Vocab(code) + "]"
    if tag == Tag.BLOB:
        return "{" + " ".join(str(byte) for byte in bytes(value)) + "}"
    if isinstance(value, dict) and not isinstance(value, Dict):
        value = Dict.from_mapping(value)
    return "(" + format_bottle(value) + ")"


def format_double(value: float) -> str:
    """``yarp::conf::numeric::to_string`` for doubles: ``%.21g``, then ``.0``."""
    if math.isnan(value):
        text = "-nan" if math.copysign(1.0, value) < 0 else "nan"
    else:
        text = "%.21g" % value
    if "." not in text and "e" not in text and text not in ("inf", "-inf", "nan"):
        text += ".0"
    return text


def quote_string(text: str) -> str:
    """``StoreString::quotedString``: quote and escape only when needed."""
    need_quote = not text or text in ("true", "false")
    for index, ch in enumerate(text):
        if ("a" <= ch <= "z") or ("A" <= ch <= "Z") or ch == "_":
            continue
        if ("0" <= ch <= "9") or ch in ".-":
            if index == 0:
                need_quote = True
                break
            continue
        need_quote = True
        break
    if not need_quote:
        return text
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") \
        .replace("\r", "\\r").replace("\0", "\\0")
    return '"' + escaped + '"'
