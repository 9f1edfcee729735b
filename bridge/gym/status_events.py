"""Which GYM statuses leave at once: the change a pilot waits for, not the drift of data.

A module's status streams every period (``seq state data...``); the link carries the newest
with the next frame.  A pilot who switched or commanded a module waits for its answer, so
:class:`StatusEvents` tells that answer apart -- a new state, or a change of its data just
after a command reached it -- and the bridge sends it at once (:mod:`bridge.core`).  GYM
policy, asked by the transport, never duplicated in it.
"""

from __future__ import annotations

import math
import time
from typing import Any, Callable, Dict, Optional, Set, Tuple

from yarp_lite.bottle import Bottle

#: Seconds after a pilot's command reaches a module during which its status changes are events.
COMMAND_WINDOW = 1.0


class StatusEvents:
    """Which GYM statuses leave at once (events) instead of with the next period.

    A status (``seq state data...``; the seq counts messages) is an event when
    its state changed, or when its state or data changed within
    :data:`COMMAND_WINDOW` of a switch or command delivered to that module:
    what a pilot waits to see.  Data that changes by itself (temperatures,
    positions) keeps the period, so a robot left alone costs what it did.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._previous: Dict[int, Tuple[Any, ...]] = {}
        self._commanded: Dict[int, float] = {}
        self._unanswered: Set[int] = set()      # modules commanded, no change seen since

    def commanded(self, module_id: int) -> None:
        self._commanded[module_id] = self._clock()
        self._unanswered.add(module_id)

    def is_event(self, module_id: int, status: Any) -> bool:
        return self.classify(module_id, status) is not None

    def classify(self, module_id: int, status: Any) -> Optional[str]:
        """``"state"`` (its state changed), ``"first answer"`` (the first change of its data
        after a command), ``"answer"`` (a later one within :data:`COMMAND_WINDOW` of the
        command) or None (periodic).  Call once per status."""
        body = tuple(status[1:]) if isinstance(status, Bottle) else ()
        previous = self._previous.get(module_id)
        self._previous[module_id] = body
        if previous is None or body == previous:
            return None
        if body[:1] != previous[:1]:
            self._unanswered.discard(module_id)
            return "state"
        if self._clock() - self._commanded.get(module_id, -math.inf) < COMMAND_WINDOW:
            if module_id in self._unanswered:
                self._unanswered.discard(module_id)
                return "first answer"
            return "answer"
        return None
