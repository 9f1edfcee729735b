"""Forward error correction that follows the loss the link measures.

Theory of operation
-------------------
A fixed repair fraction is wrong twice: too much on a clean link (bandwidth
for nothing), too little on a bad one (at 30 % loss a fraction of 0.3 leaves
a fifth of each frame missing).  So the receiver measures and the sender
adapts:

* :class:`LossMeter` (receiving side) counts, over every message it finishes,
  the data datagrams it expected (the message's ``parts``) and those that came
  off the wire (before any repair).  Its totals only grow, and a report
  (:class:`bridge.wire.datagrams.Report`) carries them back every
  :data:`REPORT_INTERVAL`, sealed like any datagram: a lost report costs
  nothing, the next one covers it.
* :class:`FecAdapter` (sending side) turns the reports into a loss estimate --
  the Wilson upper bound of the loss over the last :data:`WINDOW` seconds, so a
  few lucky frames do not talk it down -- and gives each FEC group of ``k``
  data datagrams the fewest repairs ``m`` for which the group decodes (at most
  ``m`` of its ``k + m`` datagrams lost, binomially) with probability
  :data:`TARGET`: :func:`repairs_needed`.  Until the first report it assumes
  :data:`PRIOR_LOSS`.
* A stop-all is one datagram sent several times; :func:`copies_needed` sizes its copies
  from the same estimate.
* The link's rate budget caps it: repairs may add no more than the paced rate
  leaves free beyond the data the channel sends (measured, with headroom), so
  repairs never crowd the data out of the shaper.

Everything here is sans-IO: numbers in, numbers out, the clock passed in.
(The adapter holds a lock: the UDP channel's receiving thread feeds it reports
while its sending thread asks it for repairs.)
"""

from __future__ import annotations

import math
import threading
from collections import deque
from functools import lru_cache
from typing import Deque, Optional, Tuple

from bridge.wire.datagrams import Report

#: Probability that one FEC group decodes, which the adapter aims for.
TARGET = 0.995
#: Loss assumed until the receiver's first report.
PRIOR_LOSS = 0.10
#: Seconds of reports the loss estimate is made of.
WINDOW = 5.0
#: Seconds between two reports of the receiving side.
REPORT_INTERVAL = 0.5
#: Repairs per data datagram never exceed this, whatever the loss ...
MAX_FRACTION = 2.0
#: ... except that a group may always have this many (a message of one datagram needs four
#: repairs to arrive 99.5 % of the time at 30 % loss).
MIN_CAP = 4
#: Share of the paced rate that data and repairs together may use.
RATE_HEADROOM = 0.9
#: z of the Wilson bound (one-sided 97.5 %).
Z = 1.96
#: Probability that at least one copy of a stop-all arrives, which its copies aim for ...
COPIES_TARGET = 0.999
#: ... with at most this many.
MAX_COPIES = 8


@lru_cache(maxsize=4096)
def repairs_needed(k: int, loss: float, target: float = TARGET,
                   limit: Optional[int] = None) -> int:
    """Fewest repairs ``m`` such that a group of ``k`` data datagrams plus ``m`` repairs,
    each lost with probability ``loss``, loses at most ``m`` with probability >= ``target``
    (capped at ``limit``, by default ``k *`` :data:`MAX_FRACTION` or :data:`MIN_CAP`)."""
    if k <= 0 or loss <= 0:
        return 0
    cap = max(MIN_CAP, int(k * MAX_FRACTION)) if limit is None else limit
    loss = min(loss, 0.95)
    for m in range(cap + 1):
        n = k + m
        decodes = sum(math.comb(n, lost) * loss ** lost * (1 - loss) ** (n - lost)
                      for lost in range(m + 1))
        if decodes >= target:
            return m
    return cap


def copies_needed(loss: float, least: int, target: float = COPIES_TARGET,
                  most: int = MAX_COPIES) -> int:
    """Copies of a one-datagram message (the stop-all) for at least one to arrive with
    probability ``target`` when each is lost with probability ``loss``: never fewer than
    ``least`` (the configuration's), never more than ``most``.  At 30 % loss three copies
    all fail 2.7 % of the time, and the stop waits a resending."""
    if loss <= 0:
        return least
    if loss >= 1:
        return max(least, most)
    needed = math.ceil(math.log(1 - target) / math.log(loss))
    return max(least, min(most, needed))


def wilson_upper(lost: int, total: int, z: float = Z) -> float:
    """Upper bound of a loss rate seen as ``lost`` of ``total`` (Wilson score interval)."""
    if total <= 0:
        return 1.0
    p = lost / total
    centre = p + z * z / (2 * total)
    spread = z * math.sqrt(p * (1 - p) / total + z * z / (4 * total * total))
    return min(1.0, (centre + spread) / (1 + z * z / total))


class LossMeter:
    """Receiving side: data datagrams expected and received, over finished messages."""

    def __init__(self) -> None:
        self.expected = 0
        self.received = 0
        self._reported: Tuple[int, int] = (0, 0)

    def record(self, received: int, expected: int) -> None:
        self.received += received
        self.expected += expected

    def late(self) -> None:
        """A data datagram of a message already counted arrived after all."""
        self.received += 1

    @property
    def loss(self) -> float:
        return 1 - self.received / self.expected if self.expected else 0.0

    def report(self) -> Optional[Report]:
        """The report to send now, or None when nothing was counted since the last one."""
        totals = (self.received, self.expected)
        if totals == self._reported:
            return None
        self._reported = totals
        return Report(received=self.received, expected=self.expected)


class FecAdapter:
    """Sending side: repairs per group from the receiver's reports, within the rate."""

    def __init__(self, rate: Optional[float] = None, prior: float = PRIOR_LOSS) -> None:
        self.rate = rate
        self.prior = prior
        self._last: Optional[Report] = None
        self._deltas: Deque[Tuple[float, int, int]] = deque()   # (when, lost, expected)
        self._sent: Deque[Tuple[float, int]] = deque()          # (when, data bytes)
        self._lock = threading.Lock()

    def on_report(self, report: Report, now: float) -> None:
        with self._lock:
            self._on_report(report, now)

    def _on_report(self, report: Report, now: float) -> None:
        last = self._last
        self._last = report
        if last is None or report.expected < last.expected or report.received < last.received:
            # The first report, or the peer restarted and counts from zero again.
            expected, received = report.expected, report.received
        else:
            expected, received = report.expected - last.expected, report.received - last.received
        if expected > 0:
            self._deltas.append((now, max(0, expected - received), expected))
        self._trim(now)

    def _trim(self, now: float) -> None:
        while self._deltas and now - self._deltas[0][0] > WINDOW:
            self._deltas.popleft()
        while self._sent and now - self._sent[0][0] > WINDOW:
            self._sent.popleft()

    def measured(self) -> Optional[Tuple[int, int]]:
        """(lost, expected) over the window, None before the first report."""
        with self._lock:
            if not self._deltas:
                return None
            return (sum(d[1] for d in self._deltas), sum(d[2] for d in self._deltas))

    def loss_bound(self) -> float:
        """The loss the repairs are sized for: the window's upper bound, or the prior."""
        seen = self.measured()
        if seen is None:
            return self.prior
        return wilson_upper(*seen)

    def note_sent(self, data_bytes: int, now: float) -> None:
        """Data (not repair) bytes that left, for the rate budget."""
        with self._lock:
            self._sent.append((now, data_bytes))
            self._trim(now)

    def fraction_cap(self, now: float) -> float:
        """Repairs per data byte the rate budget leaves room for."""
        with self._lock:
            if not self.rate or not self._sent:
                return MAX_FRACTION
            span = max(1.0, now - self._sent[0][0])
            data_rate = 8 * sum(size for _, size in self._sent) / span
        if data_rate <= 0:
            return MAX_FRACTION
        return max(0.0, min(MAX_FRACTION, RATE_HEADROOM * self.rate / data_rate - 1))

    def repairs(self, k: int, now: float) -> int:
        """Repairs for a group of ``k`` data datagrams sent now."""
        cap = self.fraction_cap(now)
        limit = None if cap >= MAX_FRACTION else math.floor(k * cap)
        return repairs_needed(k, round(self.loss_bound(), 3), TARGET, limit)
