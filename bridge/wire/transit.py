"""How late a frame arrives: the sender's clock on every frame, the receiver's lowest offset.

Theory of operation
-------------------
A command's lifetime grows by the time each hop held it (:mod:`walkman.gym.validity`); the
link's share is half its round trip.  But a frame can take far longer than that: queued in
a TCP connection that retransmits it once a blackout ends, or unread in the socket of a
receiving bridge that was stalled (a stopped process, a machine swapping).  Neither
bridge's clock sees that alone, and the two PCs' clocks do not agree.

So every data frame carries the sender's monotonic clock (:func:`stamp`: milliseconds,
modulo :data:`MODULUS`), and the receiver keeps, per connection, the lowest ``read time -
send time`` it has seen (:class:`Lateness`): the clocks' offset plus the quickest crossing.
What a frame's difference exceeds that by is how much later than the quickest it came; the
journal counts that lateness in the age of the frame's messages.  Only the clocks' rates
must agree (two quartz clocks drift some 10 ppm apart: 36 ms an hour, against lifetimes of
seconds), and a new connection starts a new baseline, so a peer whose clock restarted (a
reboot) is never taken for a late one.  A frame quicker than any before becomes the new
baseline: the lateness errs toward too old, never too young.

Pure: stamps and times in, seconds out.
"""

from __future__ import annotations

from typing import Optional

from bridge.wire.frames import CLOCK_MODULUS

#: Stamps wrap every 2**28 ms (74 hours); a varint of at most 4 bytes.
MODULUS = CLOCK_MODULUS


def stamp(monotonic_s: float) -> int:
    """The sender's clock for a frame leaving at ``monotonic_s``."""
    return int(monotonic_s * 1000.0) % MODULUS


class Lateness:
    """One connection's frames: how much later than the quickest each one arrived."""

    def __init__(self) -> None:
        self._lowest: Optional[int] = None

    def of(self, sent: int, read_s: float) -> float:
        """Seconds the frame stamped ``sent`` and read at ``read_s`` (the receiver's
        monotonic clock) came later than the quickest frame of this connection."""
        offset = (int(read_s * 1000.0) - sent) % MODULUS
        if self._lowest is None:
            self._lowest = offset
            return 0.0
        excess = (offset - self._lowest) % MODULUS
        if excess >= MODULUS // 2:   # quicker than every frame before: the new baseline
            self._lowest = offset
            return 0.0
        return excess / 1000.0
