"""The emulated radio as a schedule: when each Ethernet frame comes out at the far end, or why
it never will.  Pure: the caller owns the clock, the random source and the frames' bytes.

Theory of operation
-------------------
Everything about how the emulated link treats a frame lives in this file; the link stage
(:mod:`netem.radio_stage`) only moves bytes.  One :class:`RadioChannel` per direction, the
far end of a radio modem's transmit queue.  A frame offered at ``now``:

1. **blackout** -- dropped: the radio is gone.  When a blackout begins, every frame queued or
   in the air is lost with it, and the link comes back empty.
2. **queue** -- waits behind the frames offered before it for the transmitter, in a FIFO of at
   most :attr:`RadioSettings.queue_limit` bytes (the frame being sent included).  A frame
   that does not fit is dropped (tail drop), as by a router whose buffer is full.
3. **serialisation** -- the transmitter sends one frame at a time, at ``rate`` bit/s: a frame
   of N bytes occupies it N * 8 / rate seconds, from the moment the previous one has left.
   N is the frame as the interface holds it (Ethernet header, no preamble, FCS or gap: a real
   radio's framing only adds to it).  No rate: an instant transmitter, and no queue forms.
4. **loss** -- a frame sent is lost with probability ``loss``: it has used its airtime (a
   corrupted frame still occupied the channel), so the frames behind it wait just the same.
5. **delay** -- it reaches the far end ``delay`` seconds after its last bit left.

Frames come out in the order they went in (a link does not reorder, even when its delay is
made shorter while frames are under way).  Settings change at once for the frames offered
after the change; frames already scheduled keep their times.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import random
from collections import Counter, deque
from dataclasses import dataclass
from typing import Any, Callable, Deque, Dict, List, Mapping, Optional, Tuple, Union

#: The biggest frame a 1500-byte MTU Ethernet carries, as the interface holds it.
MAX_FRAME = 1514
#: A transmit buffer holds what the link sends in this long ...
QUEUE_SECONDS = 0.5
#: ... but never fewer full-size frames (at 9600 bit/s half a second is 600 bytes).
QUEUE_MIN_FRAMES = 3


class RadioSettingsError(ValueError):
    """Settings no radio can have; the text names the field."""


class Drop(enum.Enum):
    """Why a frame never comes out."""

    BLACKOUT = "blackout"
    QUEUE_FULL = "queue_full"
    LOSS = "loss"


@dataclass(frozen=True)
class RadioSettings:
    """One direction of the radio.  ``rate`` in bit/s (None: unlimited), ``delay`` one-way in
    seconds, ``loss`` a probability, ``queue_bytes`` the transmit buffer (None: from the
    rate, see :attr:`queue_limit`)."""

    rate: Optional[float] = None
    delay: float = 0.0
    loss: float = 0.0
    queue_bytes: Optional[int] = None
    blackout: bool = False

    def __post_init__(self) -> None:
        if self.rate is not None and not (isinstance(self.rate, (int, float))
                                          and math.isfinite(self.rate) and self.rate > 0):
            raise RadioSettingsError(f"rate {self.rate!r} must be a positive bit/s or None")
        if not (isinstance(self.delay, (int, float)) and 0 <= self.delay <= 3600):
            raise RadioSettingsError(f"delay {self.delay!r} must be 0..3600 s")
        if not (isinstance(self.loss, (int, float)) and 0 <= self.loss <= 1):
            raise RadioSettingsError(f"loss {self.loss!r} must be a probability 0..1")
        if self.queue_bytes is not None and not (isinstance(self.queue_bytes, int)
                                                 and self.queue_bytes >= MAX_FRAME):
            raise RadioSettingsError(f"queue_bytes {self.queue_bytes!r} must hold a full "
                                     f"frame ({MAX_FRAME} bytes) or be None")
        if not isinstance(self.blackout, bool):
            raise RadioSettingsError(f"blackout {self.blackout!r} must be true or false")

    @property
    def ideal(self) -> bool:
        """A plain cable: nothing for a link stage to do."""
        return (self.rate is None and self.delay == 0 and self.loss == 0
                and not self.blackout)

    @property
    def queue_limit(self) -> float:
        """Bytes the transmit buffer holds (infinite without a rate: nothing waits)."""
        if self.queue_bytes is not None:
            return self.queue_bytes
        if self.rate is None:
            return math.inf
        return max(self.rate * QUEUE_SECONDS / 8, QUEUE_MIN_FRAMES * MAX_FRAME)

    def updated(self, changes: Mapping[str, Any]) -> "RadioSettings":
        """These settings with ``changes`` (a control request's fields) applied."""
        known = {field.name for field in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise RadioSettingsError(f"unknown setting(s) {', '.join(unknown)} "
                                     f"(known: {', '.join(sorted(known))})")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)


class RadioChannel:
    """One direction of the radio: frames offered with their time, due frames taken out."""

    def __init__(self, settings: RadioSettings = RadioSettings(),
                 random_source: Callable[[], float] = random.random) -> None:
        self.settings = settings
        self._random = random_source
        self._in_air: Deque[Tuple[float, bytes]] = deque()   # (arrival, frame), in order
        self._sending: Deque[Tuple[float, int]] = deque()    # (last bit leaves, size)
        self._backlog = 0                                     # bytes of ``_sending``
        self._free_at = -math.inf                             # when the transmitter is idle
        self._last_arrival = -math.inf
        self.counters: Counter = Counter(
            dict.fromkeys(["offered", "delivered", *(drop.value for drop in Drop)], 0))

    def configure(self, settings: RadioSettings, now: float) -> None:
        """New settings from ``now`` on; a blackout starting loses everything under way."""
        if settings.blackout and not self.settings.blackout:
            self.counters[Drop.BLACKOUT.value] += len(self._in_air)
            self.clear(now)
        self.settings = settings

    def clear(self, now: float) -> List[bytes]:
        """Empty the link (nothing queued or in the air); returns what was under way."""
        frames = [frame for _, frame in self._in_air]
        self._in_air.clear()
        self._sending.clear()
        self._backlog = 0
        self._free_at = now
        self._last_arrival = now
        return frames

    def backlog(self, now: float) -> int:
        """Bytes waiting for, or being sent by, the transmitter at ``now``."""
        while self._sending and self._sending[0][0] <= now:
            self._backlog -= self._sending.popleft()[1]
        return self._backlog

    def offer(self, frame: bytes, now: float) -> Union[float, Drop]:
        """A frame handed to the radio at ``now``: when it comes out at the far end, or why
        it never will (see the module's docstring for the order of the checks)."""
        settings = self.settings
        self.counters["offered"] += 1
        if settings.blackout:
            return self._drop(Drop.BLACKOUT)
        if settings.rate is None:
            sent = now
        else:
            size = len(frame)
            backlog = self.backlog(now)
            if backlog and backlog + size > settings.queue_limit:
                return self._drop(Drop.QUEUE_FULL)
            sent = max(now, self._free_at) + size * 8 / settings.rate
            self._free_at = sent
            self._sending.append((sent, size))
            self._backlog += size
        if settings.loss and self._random() < settings.loss:
            return self._drop(Drop.LOSS)
        arrival = max(sent + settings.delay, self._last_arrival)
        self._last_arrival = arrival
        self._in_air.append((arrival, frame))
        return arrival

    def _drop(self, reason: Drop) -> Drop:
        self.counters[reason.value] += 1
        return reason

    def under_way(self) -> int:
        """Frames accepted and not yet taken out."""
        return len(self._in_air)

    def next_due(self) -> Optional[float]:
        """When the next frame comes out, None when none is under way."""
        return self._in_air[0][0] if self._in_air else None

    def take_due(self, now: float) -> List[bytes]:
        """The frames that have come out by ``now``, in order."""
        due = []
        while self._in_air and self._in_air[0][0] <= now:
            due.append(self._in_air.popleft()[1])
        self.counters["delivered"] += len(due)
        return due
