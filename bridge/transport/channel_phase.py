"""The TCP channel's phase -- down, handshake, up -- changed by one table under one lock.

Theory of operation
-------------------
Everything that moves the phase lives in this file.  The listening side runs up to
``MAX_HANDSHAKES`` handshakes at once, beside an established link that a proven peer may
replace, so the phase is not one connection's: it tells whether a link is up and, if not,
whether any handshake is under way.  Each event of :data:`EFFECTS` changes those two facts
and the phase follows from them, all under one lock: two handshake threads cannot both
read "down" and both move, and a second handshake that succeeds while another link is up
replaces it instead of hitting an illegal transition.  An event the facts forbid (a
handshake ending that never began, a link lost that was not up) is the channel's own bug:
:class:`~bridge.errors.BridgeUsageError` names the event, the phase and the facts.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Dict, Optional, Tuple

from bridge.errors import BridgeUsageError

PHASE_NAMES = ("down", "handshake", "up")

#: Event -> (change in the handshakes under way, whether a link is up after it: None keeps it).
EFFECTS: Dict[str, Tuple[int, Optional[bool]]] = {
    "connected": (+1, None),   # a connection began its handshake
    "failed": (-1, None),      # ... and failed; a link that is up stays up
    "hello_ok": (-1, True),    # ... and succeeded: its link is up (replacing any other)
    "lost": (0, False),        # the link that was up is gone
}


class ChannelPhase:
    """``phase`` is "up" while a link is, else "handshake" while one is under way, else
    "down"; ``since`` is when it last changed, or when the latest link came up."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self.handshakes = 0
        self.link_up = False
        self.phase = "down"
        self.since = clock()

    def move(self, event: str) -> str:
        """Apply ``event`` atomically; the phase after it."""
        with self._lock:
            effect = EFFECTS.get(event)
            if effect is None:
                raise BridgeUsageError(f"TCP channel: unknown phase event {event!r}")
            change, link_up = effect
            handshakes = self.handshakes + change
            if handshakes < 0 or (event == "lost" and not self.link_up):
                raise BridgeUsageError(
                    f"TCP channel: event {event!r} is illegal in phase {self.phase} "
                    f"({self.handshakes} handshakes under way, link "
                    f"{'up' if self.link_up else 'not up'})")
            self.handshakes = handshakes
            if link_up is not None:
                self.link_up = link_up
            phase = "up" if self.link_up else "handshake" if handshakes else "down"
            if phase != self.phase or event == "hello_ok":
                self.phase, self.since = phase, self._clock()
            return phase
