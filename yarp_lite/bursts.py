"""When a recurring problem deserves a log line: one rule for every layer.

A flood of bad input must not flood the log, and a problem that comes back
after a calm spell must be reported at once.  :class:`Burst` counts one kind of
problem: the 1st, 10th, 100th ... occurrence of a burst is worth a line, and a
burst ends after ``quiet`` seconds without the problem.  The ports' refused
connections, the udp carrier's malformed datagrams and the bridge's drops
(:mod:`bridge.transport.drops`) all use it.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

#: Seconds without the problem after which the next occurrence starts a new burst.
QUIET_SECONDS = 10.0


class Burst:
    """Counts occurrences of one problem; :meth:`record` says which to log (thread-safe)."""

    def __init__(self, quiet: float = QUIET_SECONDS,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.quiet = quiet
        self.clock = clock
        self.count = 0          # occurrences in the current burst
        self.total = 0          # occurrences ever
        self._last = -float("inf")
        self._lock = threading.Lock()

    def record(self, occurrences: int = 1) -> bool:
        """Count ``occurrences``; True when a log line is due (1st, 10th, 100th ...)."""
        with self._lock:
            now = self.clock()
            if now - self._last > self.quiet:
                self.count = 0
            self._last = now
            before = self.count
            self.count += occurrences
            self.total += occurrences
            return _crosses_power_of_ten(before, self.count)


def _crosses_power_of_ten(before: int, after: int) -> bool:
    """True when (before, after] holds 1 or a power of ten."""
    mark = 1
    while mark <= after:
        if mark > before:
            return True
        mark *= 10
    return False
