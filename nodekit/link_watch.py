"""The link as a side sees it: its bridge's status reduced to up, down or direct.

Theory of operation
-------------------
The pilot bridge writes its status on ``/bridge/pilot/status:o`` every half
second (:mod:`bridge.node`): its TCP channel's phase and how long it has not
heard the robot's bridge.  The link is **down** when the channel is not up, or
when the robot's bridge has been silent for :data:`SILENT_DOWN` (it sends at
least once a second, so a silence says the link is gone seconds before the
channel's timeout drops the connection), or when the pilot bridge itself has
said nothing for :data:`BRIDGE_QUIET` (it died: nothing crosses either way).
In the lab there is no bridge: the gateway is told so and the link is
**direct** for ever.  Until the bridge's first word it is **unknown**.

A pilot must never read "module not running" when only the link is down: the
widgets take this state from ``/bridge/link`` and say "link down for 12 s;
module last heard running" instead.  Pure: statuses and times in, states out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Dict, Optional

UP, DOWN, DIRECT, UNKNOWN = "up", "down", "direct", "unknown"
#: Seconds without a frame from the robot's bridge after which the link counts as down.
SILENT_DOWN = 1.5
#: Seconds without a status from the pilot bridge after which it counts as gone.
BRIDGE_QUIET = 2.0


@dataclass(frozen=True)
class LinkState:
    state: str
    since: float            # the watcher's clock when it entered this state
    reason: str = ""
    round_trip_ms: float = 0.0
    queued: int = 0


class LinkWatch:
    """Follows the pilot bridge's statuses; says when what a pilot should see changes."""

    def __init__(self, direct: bool, now: float) -> None:
        self.state = LinkState(DIRECT if direct else UNKNOWN, now,
                               "" if direct else "no word from the pilot bridge yet")
        self._direct = direct
        self._last_status: Optional[float] = None

    def on_status(self, status: Dict[str, Any], now: float) -> Optional[LinkState]:
        """A status of the pilot bridge; the new state if a pilot should see a change."""
        if self._direct:
            return None
        self._last_status = now
        phase = str(status.get("link", ""))
        silent = _number(status.get("silent_s"), -1.0)
        queued = int(_number(status.get("queued_commands"), 0))
        if phase != "up":
            return self._become(DOWN, now, f"the bridge's link is {phase or 'not up'}", 0.0,
                                queued)
        if silent > SILENT_DOWN:
            return self._become(DOWN, now, f"the robot's bridge silent for {silent:.1f} s", 0.0,
                                queued)
        return self._become(UP, now, "", _number(status.get("round_trip_ms"), 0.0), queued)

    def tick(self, now: float) -> Optional[LinkState]:
        """The time passing; the new state if the pilot bridge went quiet."""
        if self._direct or self._last_status is None or \
                now - self._last_status <= BRIDGE_QUIET:
            return None
        return self._become(DOWN, now, f"no status from the pilot bridge for "
                                       f"{now - self._last_status:.0f} s",
                            0.0, self.state.queued)

    def _become(self, state: str, now: float, reason: str, round_trip_ms: float,
                queued: int) -> Optional[LinkState]:
        old = self.state
        if state != old.state:
            self.state = LinkState(state, now, reason, round_trip_ms, queued)
            return self.state
        if queued != old.queued:      # what is held for the link: worth a message
            self.state = replace(old, queued=queued, reason=reason or old.reason)
            return self.state
        # Same state: the round trip refreshes silently (readers ask when they need it).
        self.state = replace(old, round_trip_ms=round_trip_ms)
        return None


def _number(value: Any, default: float) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else default
