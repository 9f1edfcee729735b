"""When a GYM module's control loop ticks: on the robot's state rounds, or on the wall clock.

Theory of operation
-------------------
A module senses, computes and moves once a period.  On a wall-clock schedule alone
(the original GYM's ``RateThread``) the robot's newest state waits for the next
tick: anywhere from nothing to a whole period.  At 500 Hz over a robot streaming
at 500 Hz that wait was most of the sense->move latency (p99 4-6 ms against a
2 ms goal).

So when the robot's state *rounds* (every chain's state of one robot step)
arrive a whole number of times per period -- 500 Hz over 500 Hz or over 1 kHz,
as on the real robot's EtherCAT -- the schedule *locks* to them:

* the tick due at ``deadline`` runs as soon as a round arrives within a quarter
  period before it to a quarter after it (``LEAD``, ``SLACK``; never wider than
  one round, so a loop over several rounds a period cannot take the earliest
  each time and run fast); the next deadline moves a fifth of the way towards
  that round (``PHASE_GAIN``), so the schedule follows the robot's phase but
  not each round's jitter (following each round exactly, a round 0.4 ms late
  made the next, on time, look 0.4 ms early: a sixth fell outside the window);
* a round that does not come in that window (a robot late, silent, or
  restarting) and the tick runs on the wall clock at the window's end; the next
  deadline is then a whole number of rounds after the newest, so a loop that
  lost (or never had) the robot's phase finds it again -- never sooner than
  ``MIN_GAP`` of a period after this tick;
* far behind (``FAR_BEHIND``: ``run()`` or the whole machine stalled), the
  schedule starts again from now: no burst of ticks to catch up.

Only a robot that says its rounds come every robot step (the client reads every
state: see :attr:`walkman.hal.robot.Robot.round_period`) and a period within 3 %
of a whole number of them lock: a slower reader's rhythm is its own, not the
robot's, and a robot a little off the loop's rate would drag it out of its
window and back.

A tick's lateness is counted from its round when locked (from its deadline
otherwise); :attr:`TickSchedule.interval_errors` keeps how far each interval
between ticks was from the period, where the robot's own jitter shows.

A period that is not a whole number of rounds (or a robot whose round period is
not known yet) runs on the wall clock alone, as before.  The robot's rate is the
robot's real time: a locked loop runs at the robot's rate, which is what its
trajectories need (:mod:`walkman.hal.clock`).

:class:`TickSchedule` is the decision alone (times in, times out); ``wait``
is the only place it blocks, through the robot's ``wait_round`` or ``sleep_until``.
"""

from __future__ import annotations

import math
import os
import time
from collections import deque
from typing import Callable, Deque, Optional, Protocol

#: Wait for the round from this fraction of a period before the deadline ...
LEAD = 0.25
#: ... to this fraction after it; then tick on the wall clock.
SLACK = 0.25
#: How much of a round's offset from its deadline the next deadline takes on.
PHASE_GAIN = 0.2
#: A period is a whole number of rounds when within this fraction of one: less than the
#: schedule can follow in a tick (PHASE_GAIN x SLACK), or a robot a little slower than the
#: loop drags it out of its window and back, ticking faster than either.
MULTIPLE_TOLERANCE = 0.03
#: After a tick on the wall clock, the next comes at least this fraction of a period later.
MIN_GAP = 0.75
#: Further behind than this (s), the schedule starts again rather than bursting.
FAR_BEHIND = 0.1
#: The end of a wait on the wall clock that is spun, not slept (s): a little more than
#: ``time.sleep``'s overshoot, measured on a 2-core box for 1.8-ms sleeps: a SCHED_FIFO
#: thread (no timer slack) median 29 us, p99 58 us; a normal one (50 us of slack) median
#: 79 us, p99 118 us.  A fixed 0.2 ms (before) spun away 2 % of a core in a 100 Hz loop.
SPIN_REALTIME = 0.00008
SPIN_NORMAL = 0.00015


class StateRounds(Protocol):
    """What the schedule needs of the robot (:class:`walkman.hal.robot.WholeBody`)."""

    round_period: float   # s between rounds (0: not known)
    newest_round: float   # when the newest arrived (``time.monotonic``; 0: none yet)

    def wait_round(self, after: float, timeout: float) -> Optional[float]:
        """When the first round newer than ``after`` arrived; None if none within ``timeout``."""


def whole_multiple(period: float, round_period: float) -> bool:
    """True when ``period`` is a whole number (>= 1) of ``round_period``."""
    if round_period <= 0:
        return False
    rounds = period / round_period
    return round(rounds) >= 1 and abs(rounds - round(rounds)) <= MULTIPLE_TOLERANCE


def spin_lead() -> float:
    """How long before a deadline the calling thread stops sleeping and spins."""
    return SPIN_REALTIME if os.sched_getscheduler(0) == os.SCHED_FIFO else SPIN_NORMAL


def sleep_until(deadline: float, clock: Callable[[], float] = time.monotonic) -> None:
    """Sleep, then spin the last :func:`spin_lead`: ``time.sleep`` alone wakes up to a
    tenth of a millisecond late, too coarse for a 2 ms period."""
    lead = spin_lead()
    delay = deadline - clock()
    if delay > lead + 0.0001:
        time.sleep(delay - lead)
    while clock() < deadline:
        pass


class TickSchedule:
    """The deadlines of a loop of ``period`` seconds (see the module docstring)."""

    def __init__(self, period: float, robot: Callable[[], Optional[StateRounds]] = lambda: None,
                 clock: Callable[[], float] = time.monotonic,
                 sleep_until: Callable[[float], None] = sleep_until) -> None:
        self.period = period
        self._robot = robot
        self._clock = clock
        self._sleep_until = sleep_until
        self.deadline = clock()
        self.locked_ticks = 0
        self.wall_ticks = 0
        #: How far each interval between two ticks was from the period (s): a locked loop's
        #: lateness is counted from its round, so this is where the robot's jitter shows.
        self.interval_errors: Deque[float] = deque(maxlen=20000)
        self._last_tick: Optional[float] = None

    def restart(self) -> None:
        """Count the next deadline from now (after a pause, or the robot away)."""
        self.deadline = self._clock()
        self._last_tick = None

    def wait(self) -> float:
        """Block until the next tick is due; how late it starts (s) against its deadline."""
        late = self._wait()
        now = self._clock()
        if self._last_tick is not None:
            self.interval_errors.append(abs(now - self._last_tick - self.period))
        self._last_tick = now
        return late

    def _rounds(self) -> Optional[StateRounds]:
        """The robot, when its rounds fit this period (see the module docstring)."""
        robot = self._robot()
        if robot is not None and whole_multiple(self.period, robot.round_period):
            return robot
        return None

    def _wait(self) -> float:
        due = self.deadline + self.period
        now = self._clock()
        if now - due > FAR_BEHIND:  # run() or the whole box stalled: start again, no burst
            self.deadline = now
            self.wall_ticks += 1
            return now - due
        robot = self._rounds()
        if robot is None:
            self._sleep_until(due)
            now = self._clock()
            self.deadline = due if now - due < FAR_BEHIND else now
            self.wall_ticks += 1
            return now - due
        # The window holds one round at most: a loop over several rounds a period must not
        # take the earliest each time and run fast.
        rounds = robot.round_period
        lead = min(LEAD * self.period, 0.45 * rounds)
        slack = min(SLACK * self.period, 0.45 * rounds)
        arrived = robot.wait_round(due - lead, due + slack - now)
        if arrived is not None:
            # Follow the robot's phase, not each round's jitter: a round late by 0.4 ms
            # must not make the next (on time) look 0.4 ms early.  A round far past the
            # deadline means we were late (run() overran): count from it, no burst.
            offset = arrived - due
            self.deadline = arrived if offset > slack else due + PHASE_GAIN * offset
            self.locked_ticks += 1
            return self._clock() - arrived
        now = self._clock()
        earliest = now - (1 - MIN_GAP) * self.period  # the next tick no sooner than MIN_GAP
        newest = robot.newest_round
        if now - newest < self.period:
            # Find the robot's phase again: the next tick on a round, a whole number of
            # rounds after the newest, and not too soon.
            skipped = max(0, math.ceil((earliest - newest) / rounds))
            self.deadline = newest + skipped * rounds
        else:
            self.deadline = max(due, earliest)
        self.wall_ticks += 1
        return now - due
