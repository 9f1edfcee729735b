"""Duplicate datagrams for the loss tail: a command, its receipt and the status answering it.

Theory of operation
-------------------
A pilot's command crosses the TCP channel, journalled, exactly once.  When the link
loses a segment, TCP waits for its retransmission timer (200 ms at least on Linux,
doubling after a second loss) and everything behind the segment waits with it: that is
the tail of command -> status at a few percent of loss.  So each reliable message of a
flow configured with copies (``<datagram_copies commands="N">``: a pilot's switch or
command, and the module's receipt coming back) also leaves, with the frame that carries
it, as N datagrams on the UDP channel, sealed with the link's key like every datagram.

The receiver hands a copy (:class:`ReliableCopy`: the sending journal's session, the
message's number, its payload) to the same journal the TCP channel fills, and only when
it is the next number it expects from that session on the current connection
(:meth:`bridge.transport.frame_session.FrameSession.accept_copy`).  Whichever comes first -- the
copy or the frame -- is journalled, the other is a repeat: the journal's numbering keeps
it exactly once and in order.  A copy that comes ahead of a gap is not taken: TCP brings
its number in order.  Copies leave only with a frame, so a command queued during a
blackout is sent (and claimed, :meth:`bridge.transport.journal.Journal.cancel`) no earlier than
without them.

A GYM status answering a command (a status *event*, :class:`bridge.gym.status_events.StatusEvents`)
goes the same two ways, ``<datagram_copies statuses="N">``.  Statuses are not
journalled, so the receiver remembers what it last wrote per flow
(:class:`FirstStatus`): the same status again is the other copy, and one with an older
``seq`` soon after is a late one that a newer overtook; neither is written.

Pure: bytes and values in, decisions out; the node and the channels do the I/O.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import Any, Callable, Dict, Hashable, Optional, Tuple

from bridge.errors import BridgeProtocolError
from bridge.wire.frames import CLOCK_MODULUS

_HEAD = struct.Struct(">QII")
#: Seconds during which a status with an older ``seq`` than the one written is a late copy
#: (a module restarted within this time has its first statuses held back until it passes).
OVERTAKEN = 2.0


@dataclass(frozen=True)
class ReliableCopy:
    """A reliable message as a datagram copy: whose journal, which number, what, and the
    clock stamp of the frame that carried it (:mod:`bridge.wire.transit`)."""

    session: int
    seq: int
    payload: bytes
    clock: int = 0


def encode_copy(copy: ReliableCopy) -> bytes:
    """``session`` (8 bytes) ``seq`` (4) ``clock`` (4, big-endian) and the payload."""
    if not 0 < copy.session < 1 << 64 or not 0 < copy.seq < 1 << 32:
        raise ValueError(f"a reliable copy needs a session and a number > 0, got "
                         f"{copy.session}, {copy.seq}")
    if not 0 <= copy.clock < CLOCK_MODULUS:
        raise ValueError(f"a reliable copy's clock is 0..{CLOCK_MODULUS - 1}, got {copy.clock}")
    return _HEAD.pack(copy.session, copy.seq, copy.clock) + copy.payload


def decode_copy(data: bytes) -> ReliableCopy:
    """The copy in ``data``; :class:`BridgeProtocolError` names what is wrong."""
    if len(data) <= _HEAD.size:
        raise BridgeProtocolError(f"a reliable copy is a {_HEAD.size}-byte head and a "
                                  f"payload, got {len(data)} bytes")
    session, seq, clock = _HEAD.unpack_from(data)
    if session == 0 or seq == 0:
        raise BridgeProtocolError(f"a reliable copy names session {session} and number "
                                  f"{seq}; neither may be 0")
    if clock >= CLOCK_MODULUS:
        raise BridgeProtocolError(f"a reliable copy's clock {clock} exceeds "
                                  f"{CLOCK_MODULUS - 1}")
    return ReliableCopy(session, seq, bytes(data[_HEAD.size:]), clock)


class ReliableCopyCodec:
    """The UDP channel's codec of a flow's reliable copies (one message, not tiled)."""

    tiled = False

    def encode(self, value: ReliableCopy) -> bytes:
        return encode_copy(value)

    def decode(self, data: bytes, completeness: float) -> ReliableCopy:
        return decode_copy(data)


def _status_seq(status: Any) -> Optional[int]:
    head = status[0] if isinstance(status, (list, tuple)) and len(status) else None
    return head if isinstance(head, int) and not isinstance(head, bool) else None


class FirstStatus:
    """Which copy of a status to write: the first; never an older one after a newer."""

    def __init__(self, clock: Callable[[], float] = time.monotonic,
                 overtaken: float = OVERTAKEN) -> None:
        self._clock = clock
        self._overtaken = overtaken
        self._written: Dict[Hashable, Tuple[Any, Optional[int], float]] = {}
        #: copies not written: the other copy of one written, or overtaken by a newer one
        self.repeats = 0
        self.overtaken = 0

    def first(self, flow: Hashable, status: Any) -> bool:
        """True: write ``status`` (and remember it); False: a repeat or a late one."""
        now = self._clock()
        seq = _status_seq(status)
        written = self._written.get(flow)
        if written is not None:
            value, last_seq, at = written
            if status == value:
                self.repeats += 1
                return False
            if seq is not None and last_seq is not None and seq < last_seq and \
                    now - at < self._overtaken:
                self.overtaken += 1
                return False
        self._written[flow] = (status, seq, now)
        return True

    def forget(self, flow: Hashable) -> None:
        """The flow's module left: its next status is new whatever its number."""
        self._written.pop(flow, None)
