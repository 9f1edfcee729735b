"""What a widget says about the age of what it shows while the link is down (pure, no Qt).

Every widget of the PI shows something the robot sent: a state, a chart, a camera frame.
While the link is down nothing new can cross, so what is on the screen is as old as the cut
or older; a value shown as if it were live is the one thing a pilot must never read.
:class:`LinkCut` follows ``/bridge/link`` (:class:`pilot.link.LinkEvent`) and words the banner
each widget shows; widgets call it with their own clock (``time.monotonic``), tests with theirs.
"""

from __future__ import annotations

import time
from typing import Callable, Optional, Sequence, Tuple


def age_text(seconds: float) -> str:
    """``0.4 s`` under 10 s, ``18 s`` under two minutes, ``3 min`` beyond."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min"


class LinkCut:
    """Since when the link is down (None: up, direct or never heard of)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.down_at: Optional[float] = None

    def on_link(self, event) -> None:
        """A :class:`pilot.link.LinkEvent`: ``down`` since ``event.since`` seconds."""
        self.down_at = self.clock() - event.since if event.state == "down" else None

    @property
    def down_for(self) -> Optional[float]:
        return None if self.down_at is None else max(0.0, self.clock() - self.down_at)

    def banner(self, what: str, last: Optional[float]) -> str:
        """``link down for 18 s: <what> as of 21 s ago`` (``last``: when what is shown
        arrived, on this clock; None: nothing arrived), or "" while the link is up."""
        return self.banner_of([(what, last)])

    def banner_of(self, shown: Sequence[Tuple[str, Optional[float]]]) -> str:
        """The same for several things one widget shows, each with its own age:
        ``link down for 18 s: the robot as of 18 s ago, the cloud as of 21 s ago``."""
        down = self.down_for
        if down is None:
            return ""
        now = self.clock()
        ages = [f"{what}: nothing received yet" if last is None else
                f"{what} as of {age_text(now - last)} ago" for what, last in shown]
        if len(ages) == 1 and shown[0][1] is None:
            ages = ["nothing received yet"]
        return f"link down for {age_text(down)}: {', '.join(ages)}"
