"""YARP's typed values: the wire tags and the Python types that pin them.

:mod:`yarp_lite.bottle` explains the tags and holds Bottles and their binary
codec; :mod:`yarp_lite.bottle_text` their text form.  Both build on these
types, which depend on nothing else, so neither codec imports the other's
module to know what an ``Int8`` or a ``Vocab`` is.
"""

from __future__ import annotations

import struct
from enum import IntEnum
from typing import Any, Union

from yarp_lite.errors import LocalProtocolError

class Tag(IntEnum):
    """YARP 3.5 Bottle type tags (``BOTTLE_TAG_*`` in Bottle.h)."""

    INT8 = 32
    INT16 = 64
    INT32 = 1
    INT64 = 1 + 16
    VOCAB32 = 1 + 8
    FLOAT32 = 128
    FLOAT64 = 2 + 8
    STRING = 4
    BLOB = 4 + 8
    LIST = 256
    DICT = 512


UNIT_MASK = (Tag.INT8 | Tag.INT16 | Tag.INT32 | Tag.INT64 | Tag.FLOAT32 | Tag.FLOAT64
             | Tag.VOCAB32 | Tag.STRING | Tag.BLOB)
GROUP_MASK = Tag.LIST | Tag.DICT
DICT_CODE = Tag.LIST | Tag.DICT
#: Deepest nesting accepted from a peer; deeper input is an attack, not data.
MAX_DEPTH = 100

_INT32_MIN, _INT32_MAX = -(1 << 31), (1 << 31) - 1
_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1

_F32 = struct.Struct("<f")


# --------------------------------------------------------------------------
# Value types


def _checked_int(cls: type, value: Any, low: int, high: int) -> int:
    number = int(value)
    if not low <= number <= high:
        raise LocalProtocolError(f"{number} does not fit in {cls.__name__}")
    return number


class Int8(int):
    """An integer sent with the INT8 tag."""

    def __new__(cls, value: Any = 0) -> "Int8":
        return super().__new__(cls, _checked_int(cls, value, -128, 127))


class Int16(int):
    """An integer sent with the INT16 tag."""

    def __new__(cls, value: Any = 0) -> "Int16":
        return super().__new__(cls, _checked_int(cls, value, -(1 << 15), (1 << 15) - 1))


class Int32(int):
    """An integer sent with the INT32 tag (plain ints that fit get it anyway)."""

    def __new__(cls, value: Any = 0) -> "Int32":
        return super().__new__(cls, _checked_int(cls, value, _INT32_MIN, _INT32_MAX))


class Int64(int):
    """An integer sent with the INT64 tag even when it would fit in 32 bits."""

    def __new__(cls, value: Any = 0) -> "Int64":
        return super().__new__(cls, _checked_int(cls, value, _INT64_MIN, _INT64_MAX))


class Float32(float):
    """A float sent with the FLOAT32 tag; the value is rounded to single precision."""

    def __new__(cls, value: Any = 0.0) -> "Float32":
        return super().__new__(cls, _F32.unpack(_F32.pack(float(value)))[0])


class Float64(float):
    """A float sent with the FLOAT64 tag (plain floats get it anyway)."""


def vocab_encode(text: str) -> int:
    """Pack up to four characters into a vocab code, first character lowest."""
    raw = text.encode("utf-8", "surrogateescape")[:4]
    code = 0
    for shift, byte in enumerate(raw):
        code |= byte << (8 * shift)
    return code - (1 << 32) if code > _INT32_MAX else code


def vocab_decode(code: int) -> str:
    """Unpack a vocab code exactly as YARP's ``Vocab32::decode`` does.

    YARP divides the *signed* code by 256 and skips non-positive remainders,
    so for negative codes the result differs from a plain byte split; we
    follow it so that text output matches.
    """
    sign = -1 if code < 0 else 1
    magnitude = abs(code)
    chars = bytearray()
    for _ in range(4):
        if sign > 0 and magnitude % 256:  # C's % keeps the sign: negatives never print
            chars.append(magnitude % 256)
        magnitude //= 256
    return chars.decode("utf-8", "surrogateescape")


class Vocab(str):
    """A vocab: a short identifier sent as one int32 (``[add]``, ``[ok]``).

    The string value is the decoded text; :attr:`code` is the wire integer,
    kept exactly even when the text alone could not reproduce it.
    """

    code: int

    def __new__(cls, value: Union[str, int]) -> "Vocab":
        if isinstance(value, Vocab):
            code = value.code
        elif isinstance(value, str):
            code = vocab_encode(value)
        else:
            code = _checked_int(cls, value, _INT32_MIN, _INT32_MAX)
        self = super().__new__(cls, vocab_decode(code))
        self.code = code
        return self

    def __repr__(self) -> str:
        return f"Vocab({str(self)!r})"

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Vocab):
            return self.code == other.code
        return str.__eq__(self, other)

    def __hash__(self) -> int:
        return str.__hash__(self)


VOCAB_TRUE = Vocab(ord("1"))
VOCAB_FALSE = Vocab(0)
