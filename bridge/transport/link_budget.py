"""What the radio can take now: the link's rate minus what this bridge already handed it.

Theory of operation
-------------------
A radio sends one frame at a time at its rate and keeps the rest in a FIFO.  Whatever a
bridge hands it beyond what it can send at once waits there, in front of whatever comes
next: the stop-all and its acknowledgement too, which no priority inside the bridge can move
ahead of bytes already in the radio's queue.  On the DRC's 9600 bit/s link a robot that
handed its radio 2 KB of telemetry made every stop's acknowledgement wait 2-4 s, and the
radio's queue overflowed (``bench/bench_stop_all.py``, issue 66).

So each bridge keeps its radio's queue short.  One :class:`LinkBudget` per bridge, shared by
its TCP and UDP channels, counts the bytes they hand the link, as they go on the wire
(headers included), and lets them drain at the link's rate: a model of the radio's queue.
Streaming data -- the robot state's periodic frames, perception's datagrams -- leaves only
while the model's queue has room (:attr:`LinkBudget.limit`: the rate times
:data:`TARGET_DELAY`); a datagram larger than the limit waits for an empty queue.  What must
arrive -- the stop-all and its acknowledgement, commands, receipts -- always leaves, and
counts.  The TCP channel also holds its streaming data back while its socket holds more
than the limit for the peer, sent or not: those bytes are in the radio's queue, or will be
before the next frame.  (Not so for the datagrams: bytes a lossy link lost wait in the
socket for their retransmission, and a stop's datagrams must not wait for them.)  The
peer's TCP acknowledgements share the link too: the target leaves room for them.

Pure arithmetic over a clock passed in; a lock, because both channels' threads spend.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

#: Seconds of the link's rate the radio's queue may hold of streaming data: a stop handed
#: to the radio behind it waits at most this, plus the frame being sent -- or one datagram
#: larger than the limit, which goes alone into an empty queue (at 9600 bit/s perception's
#: datagrams of about 600 bytes: 0.5 s; its 1472-byte most, 1.3 s).
TARGET_DELAY = 0.15
#: The smallest limit, bytes: one small frame (a status, a robot state's delta) and its headers.
MIN_LIMIT = 300
#: What a UDP datagram adds on the wire: IPv4 (20), UDP (8) and Ethernet (14) headers.
DATAGRAM_OVERHEAD = 42
#: What each TCP segment adds: IPv4 (20), TCP with timestamps (32) and Ethernet (14).
SEGMENT_OVERHEAD = 66
#: Payload bytes per TCP segment on an Ethernet path (1500 - 20 - 32).
SEGMENT_PAYLOAD = 1448


class LinkBudgetError(ValueError):
    """A link budget was asked for with a rate or target it cannot use."""


def datagram_bytes(size: int) -> int:
    """A datagram of ``size`` bytes (its UDP payload) as it goes on the wire."""
    return size + DATAGRAM_OVERHEAD


def tcp_bytes(size: int) -> int:
    """``size`` bytes written to a TCP socket as they go on the wire (full segments)."""
    return size + SEGMENT_OVERHEAD * max(1, math.ceil(size / SEGMENT_PAYLOAD))


@dataclass
class LinkBudget:
    """The radio's queue as this bridge filled it; ``rate`` in bit/s, times in seconds."""

    rate: float
    target: float = TARGET_DELAY
    _queued: float = 0.0
    _at: float = -math.inf
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    #: bytes spent in all, and of them those that left although the queue was full
    spent: int = 0
    spent_over: int = 0

    def __post_init__(self) -> None:
        if not (isinstance(self.rate, (int, float)) and math.isfinite(self.rate) and
                self.rate > 0):
            raise LinkBudgetError(f"a link budget needs a rate above 0 bit/s, got {self.rate!r}")
        if not (math.isfinite(self.target) and self.target > 0):
            raise LinkBudgetError(f"a link budget's target delay must be above 0 s, got "
                                  f"{self.target!r}")

    @property
    def limit(self) -> float:
        """Bytes of streaming data the radio's queue may hold."""
        return max(MIN_LIMIT, self.rate * self.target / 8)

    def queued(self, now: float) -> float:
        """Bytes still in the radio's queue at ``now``, as far as this bridge knows."""
        with self._lock:
            return self._drain(now)

    def full(self, now: float) -> bool:
        """No room for streaming data: hold it back (it will be newer next time)."""
        return self.queued(now) >= self.limit

    def wait_for(self, size: int, now: float) -> float:
        """Seconds until ``size`` wire bytes of streaming data may go: 0 if they fit now.
        More than the limit at once waits for an empty queue."""
        queued = self.queued(now)
        over = queued + size - self.limit if size <= self.limit else queued
        return max(0.0, over) * 8 / self.rate

    def spend(self, size: int, now: float) -> None:
        """``size`` wire bytes were handed to the link at ``now``."""
        with self._lock:
            queued = self._drain(now)
            if queued >= self.limit:
                self.spent_over += size
            self._queued = queued + size
            self.spent += size

    def _drain(self, now: float) -> float:
        if now > self._at:
            self._queued = max(0.0, self._queued - (now - self._at) * self.rate / 8)
            self._at = now
        return self._queued
