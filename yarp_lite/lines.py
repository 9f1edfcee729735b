"""Text lines as YARP reads them (``InputStream::readLine``), as a pure function.

YARP's text carriers and the name server read lines byte by byte: CR and NUL
are dropped, and a backslash right before the newline continues the line (the
backslash vanishes, other backslashes are kept).  :func:`split_line` finds one
such line at the start of a buffer without any I/O, so the socket layer and
the tests share one definition.

It is total (any bytes give a line or None, never an exception) and keeps no
state; the limit on how much a peer may send without a newline belongs to
the reader that buffers it (``yarp_lite.stream.MAX_LINE``, 1 MiB).
"""

from __future__ import annotations

from typing import Optional, Tuple, Union

Buffer = Union[bytes, bytearray, memoryview]


def split_line(buffer: Buffer, start: int = 0,
               terminal: int = 0x0A) -> Optional[Tuple[str, int]]:
    """Return ``(line, end)`` for the first complete line at ``start``, or None.

    ``end`` is the offset just past the terminating byte.
    """
    data = bytes(buffer[start:]) if not isinstance(buffer, bytes) or start else buffer
    newline = data.find(bytes((terminal,)))
    if newline < 0:
        return None
    if b"\\" not in data[:newline]:
        # Fast path: no escapes, so the first terminator ends the line.
        raw = data[:newline]
        return _clean(raw), start + newline + 1
    out = bytearray()
    escapes = 0
    for index, byte in enumerate(data):
        if byte == 0x5C:  # backslash
            escapes += 1
        if byte not in (0, 0x0D, 0x0A):
            if byte != 0x5C or escapes >= 2:
                out += b"\\" * escapes
                escapes = 0
            if byte != 0x5C:
                out.append(byte)
        if byte == terminal:
            if escapes == 0:
                return out.decode("utf-8", "surrogateescape"), start + index + 1
            escapes = 0
    return None


def _clean(raw: bytes) -> str:
    if b"\r" in raw or b"\0" in raw:
        raw = raw.replace(b"\r", b"").replace(b"\0", b"")
    return raw.decode("utf-8", "surrogateescape")
