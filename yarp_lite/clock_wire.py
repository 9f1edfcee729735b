"""The network clock's message: YARP's ``sec nsec`` tick (pure, no I/O).

A clock source (gazebo_yarp_clock, ``yarp clock``, ``walkman-hal --clock``) writes one
Bottle of two int32 per tick: whole seconds, then nanoseconds (binary ``257 2 sec nsec``,
text ``sec nsec``); its followers read ``sec + nsec * 1e-9`` (YARP's
``NetworkClock::Private::read``).  YARP reads whatever arrives with ``asInt32``, so a
malformed tick becomes time 0; here it is refused with a message naming what is wrong,
and the follower keeps the time it had.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from yarp_lite.bottle import Bottle, Value
from yarp_lite.errors import LocalProtocolError, RemoteProtocolError

NSEC_PER_SEC = 1_000_000_000
#: The largest time a tick can say: int32 seconds.
MAX_SECONDS = 2**31 - 1


@dataclass(frozen=True)
class Tick:
    """One clock message: ``sec`` whole seconds and ``nsec`` nanoseconds (0 ≤ nsec < 1e9)."""

    sec: int
    nsec: int

    @property
    def seconds(self) -> float:
        return self.sec + self.nsec * 1e-9

    @classmethod
    def at(cls, seconds: float) -> "Tick":
        """The tick for ``seconds`` (rounded to the nanosecond), as YARP's sources split it."""
        if not math.isfinite(seconds) or not 0 <= seconds <= MAX_SECONDS:
            raise LocalProtocolError(f"a clock tick holds 0 to {MAX_SECONDS} s, not {seconds!r}")
        total = round(seconds * NSEC_PER_SEC)
        sec, nsec = divmod(total, NSEC_PER_SEC)
        return cls(min(sec, MAX_SECONDS), nsec)


def encode_tick(seconds: float) -> Bottle:
    """The Bottle a clock source writes for ``seconds``."""
    tick = Tick.at(seconds)
    return Bottle([tick.sec, tick.nsec])


def decode_tick(bottle: Sequence[Value], where: str = "clock") -> Tick:
    """The tick ``bottle`` holds; :class:`RemoteProtocolError` naming the fault otherwise."""
    if len(bottle) != 2:
        raise RemoteProtocolError(f"a clock tick is two int32 (sec nsec), got {len(bottle)} "
                                  f"values: {Bottle(bottle).to_text()[:80]!r}", where)
    sec, nsec = bottle
    for name, value in (("sec", sec), ("nsec", nsec)):
        if type(value) is not int:
            raise RemoteProtocolError(f"a clock tick's {name} must be an int32, got "
                                      f"{type(value).__name__} {value!r}", where)
    if sec < 0:
        raise RemoteProtocolError(f"a clock tick's sec is negative ({sec})", where)
    if not 0 <= nsec < NSEC_PER_SEC:
        raise RemoteProtocolError(f"a clock tick's nsec must be 0 to 999999999, got {nsec}",
                                  where)
    return Tick(sec, nsec)
