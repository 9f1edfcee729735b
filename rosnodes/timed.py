"""Timed commands: the paper's QtTimedButton, for any pilot tool.

The pilot interface applied a *forgiveness* principle: a dangerous command
does not leave at once, it counts down (3 s by default) and pressing the
button again cancels it.  :class:`Countdowns` is that rule and nothing else --
no ROS, no clock of its own -- so the gateway drives it with ROS callbacks and
a timer, and tests drive it with plain numbers.

Each pending command is keyed by ``(module, text)``: the same command again
while it waits is the "second press" and cancels it; another command waits on
its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

DEFAULT_COUNTDOWN = 3.0
WAITING, SENT, CANCELLED = "waiting", "sent", "cancelled"

Key = Tuple[str, str]


@dataclass
class Pending:
    module: str
    text: str
    deadline: float
    payload: Any = None          # what to send when the countdown ends


@dataclass
class Event:
    pending: Pending
    state: str                   # WAITING, SENT or CANCELLED
    remaining: float


@dataclass
class Countdowns:
    default: float = DEFAULT_COUNTDOWN
    _pending: Dict[Key, Pending] = field(default_factory=dict)

    def request(self, module: str, text: str, now: float, payload: Any = None,
                countdown: float = 0.0) -> Event:
        """A dangerous command was asked for: start its countdown, or cancel it if waiting."""
        key = (module, text)
        waiting = self._pending.pop(key, None)
        if waiting is not None:
            return Event(waiting, CANCELLED, max(0.0, waiting.deadline - now))
        if countdown < 0:
            raise ValueError(f"a countdown cannot be negative ({countdown})")
        pending = Pending(module, text, now + (countdown or self.default), payload)
        self._pending[key] = pending
        return Event(pending, WAITING, pending.deadline - now)

    def tick(self, now: float) -> List[Event]:
        """Progress of every waiting command; the expired ones are returned as SENT, once."""
        events = []
        for key, pending in list(self._pending.items()):
            remaining = pending.deadline - now
            if remaining <= 0:
                del self._pending[key]
                events.append(Event(pending, SENT, 0.0))
            else:
                events.append(Event(pending, WAITING, remaining))
        return events

    def cancel_all(self, module: str) -> List[Event]:
        """Drop every command waiting for ``module`` (e.g. the pilot stopped it)."""
        events = []
        for key in [k for k in self._pending if k[0] == module]:
            pending = self._pending.pop(key)
            events.append(Event(pending, CANCELLED, 0.0))
        return events

    @property
    def waiting(self) -> int:
        return len(self._pending)
