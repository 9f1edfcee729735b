"""Small wire primitives shared by every bridge codec: varints and zigzag.

Varints are LEB128 (7 bits per byte, low group first) as in protobuf; signed
values go through zigzag so small negatives stay small.  (Frames and datagrams are
sealed by :mod:`bridge.wire.link`'s tags, which also catch what a CRC would.)
"""

from __future__ import annotations

from typing import Tuple, Union

from bridge.errors import BridgeProtocolError, NeedMoreData

Buffer = Union[bytes, bytearray, memoryview]

#: Longest varint accepted (64-bit values); longer input is garbage.
MAX_VARINT_BYTES = 10


def put_varint(out: bytearray, value: int) -> None:
    if value < 0:
        raise ValueError(f"varint of a negative number {value}")
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)


def varint(value: int) -> bytes:
    out = bytearray()
    put_varint(out, value)
    return bytes(out)


def get_varint(buf: Buffer, pos: int, what: str = "varint") -> Tuple[int, int]:
    """Read a varint at ``pos``: ``(value, next position)``.

    Raises :class:`NeedMoreData` when the buffer ends inside it and
    :class:`BridgeProtocolError` when it is longer than 64 bits.
    """
    value = shift = 0
    end = len(buf)
    for index in range(MAX_VARINT_BYTES):
        if pos + index >= end:
            raise NeedMoreData(f"{what} truncated at byte {pos + index}")
        byte = buf[pos + index]
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, pos + index + 1
        shift += 7
    raise BridgeProtocolError(f"{what} at byte {pos} is longer than {MAX_VARINT_BYTES} bytes")


def zigzag(value: int) -> int:
    return value * 2 if value >= 0 else -value * 2 - 1


def unzigzag(value: int) -> int:
    return value >> 1 if not value & 1 else -((value + 1) >> 1)


def put_svarint(out: bytearray, value: int) -> None:
    put_varint(out, zigzag(value))


def get_svarint(buf: Buffer, pos: int, what: str = "signed varint") -> Tuple[int, int]:
    value, pos = get_varint(buf, pos, what)
    return unzigzag(value), pos


def take(buf: Buffer, pos: int, count: int, what: str) -> Tuple[bytes, int]:
    """``count`` bytes at ``pos``; :class:`NeedMoreData` if the buffer is short."""
    if count < 0:
        raise BridgeProtocolError(f"negative length for {what}")
    if pos + count > len(buf):
        raise NeedMoreData(f"{what} needs {count} bytes at byte {pos}, "
                           f"{len(buf) - pos} present")
    return bytes(buf[pos:pos + count]), pos + count
