"""The link as a side sees it: its bridge's status reduced to up, down or direct.

Theory of operation
-------------------
Each side's bridge writes its status on ``/bridge/<side>/status:o`` every half
second (:mod:`bridge.node`): its TCP channel's phase and how long it has not
heard the other side's bridge.  Two programs follow it: the pilot gateway
(``/bridge/pilot/status:o``: ``/bridge/link``, so a pilot tells "link down" from
"module dead") and every GYM module on the robot (``/bridge/robot/status:o``: its
link-loss policy, :mod:`walkman.gym.link_loss`).  The link is **down** when the
channel is not up, or when the other side's bridge has been silent for
:data:`SILENT_DOWN` (it sends at least once a second, so a silence says the
link is gone seconds before the channel's timeout drops the connection), or
when this side's bridge itself has said nothing for :data:`BRIDGE_QUIET` after
having spoken (it died: nothing crosses either way).  Until the bridge's first
word it is **unknown**, and stays so where no bridge ever speaks: in the lab
nothing is down.  A program told there is no bridge (the gateway's ``--link
direct``) reads **direct** for ever.

A pilot must never read "module not running" when only the link is down: the
widgets take this state from ``/bridge/link`` and say "link down for 12 s;
module last heard running" instead.  Pure: statuses and times in, states out;
:func:`status_fields` reads what :class:`LinkWatch` needs from the status's Bottle.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum
from typing import Any, Dict, Optional, Sequence

class LinkPhase(str, Enum):
    """What a reader sees of the link (equal to its word: ``LinkPhase.UP == "up"``)."""

    UP = "up"
    DOWN = "down"
    DIRECT = "direct"
    UNKNOWN = "unknown"

    def __str__(self) -> str:
        return self.value


UP, DOWN, DIRECT, UNKNOWN = LinkPhase.UP, LinkPhase.DOWN, LinkPhase.DIRECT, LinkPhase.UNKNOWN
#: Seconds without a frame from the other side's bridge after which the link counts as down.
SILENT_DOWN = 1.5
#: Seconds without a status from this side's bridge after which it counts as gone.
BRIDGE_QUIET = 2.0
#: The two sides of the link, each named by the other.
PEER = {"pilot": "robot", "robot": "pilot"}


@dataclass(frozen=True)
class LinkState:
    state: LinkPhase
    since: float            # the watcher's clock when it entered this state
    reason: str = ""
    round_trip_ms: float = 0.0
    queued: int = 0


class LinkWatch:
    """Follows one side's bridge statuses; says when what its readers should see changes.

    ``side`` is where the watcher is (``pilot``: the gateway; ``robot``: a module):
    it names the bridges in the reasons.
    """

    def __init__(self, direct: bool, now: float, side: str = "pilot") -> None:
        if side not in PEER:
            raise ValueError(f"LinkWatch: side must be one of {', '.join(PEER)}, got {side!r}")
        self.side, self.peer = side, PEER[side]
        self.state = LinkState(DIRECT if direct else UNKNOWN, now,
                               "" if direct else f"no word from the {side} bridge yet")
        self._direct = direct
        self._last_status: Optional[float] = None

    def on_status(self, status: Dict[str, Any], now: float) -> Optional[LinkState]:
        """A status of this side's bridge; the new state if its readers should see a change."""
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
            return self._become(DOWN, now, f"the {self.peer}'s bridge silent for {silent:.1f} s",
                                0.0, queued)
        return self._become(UP, now, "", _number(status.get("round_trip_ms"), 0.0), queued)

    def tick(self, now: float) -> Optional[LinkState]:
        """The time passing; the new state if this side's bridge went quiet."""
        if self._direct or self._last_status is None or \
                now - self._last_status <= BRIDGE_QUIET:
            return None
        return self._become(DOWN, now, f"no status from the {self.side} bridge for "
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


def status_fields(bottle: Sequence[Any]) -> Dict[str, Any]:
    """The top-level ``(key value)`` pairs of a bridge status Bottle (:mod:`bridge.status`
    writes it: a property list), nested values as they came; what :meth:`LinkWatch.on_status`
    reads.  Anything else raises ``ValueError`` (it came from a port: the peer's mistake).

    The bridge's own decoder is :func:`bridge.status.from_bottle`; this one is here because
    the robot's modules read the status too and ``walkman`` sits below ``bridge``.
    """
    fields: Dict[str, Any] = {}
    for pair in bottle:
        if not (isinstance(pair, (list, tuple)) and len(pair) == 2 and isinstance(pair[0], str)):
            raise ValueError(f"not a bridge status: {str(bottle)[:80]!r}")
        fields[pair[0]] = pair[1]
    return fields
