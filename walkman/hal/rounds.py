"""The robot's step period, as a module's client reads it from the state rounds (sans-IO).

Theory of operation
-------------------
A *round* is every chain's state of one robot step (:class:`walkman.hal.robot.Robot`
says when one is complete).  The control loop locks to rounds only when its period is a
whole number of robot steps (:mod:`walkman.gym.pacing`), so the step period must be
right to a few per cent.  It is averaged over the last :data:`KEPT` rounds, divided by
the robot steps between them (the state count), so a round that missed a step does not
halve it.

Each spacing is timed by the robot's own clock where its states say it (our HAL's
``stateSI``): a reader held up by its machine and then handed a burst of states sees
them "arrive" a few microseconds apart, and an average over arrivals then said 0.71 ms
for a 1-ms robot (a fresh-clone run beside two CPU burners).  A plain YARP robot's
state does not say the robot's time (``fakeMotionControl`` stamps 0): its rounds are
timed by arrival, as before.  Rounds that do not come every step (a reader throttled
by ``state_interval``), too few rounds, or none for :data:`STALE_AFTER` say 0: not known.
"""

from __future__ import annotations

from collections import deque
from typing import Deque, Optional, Tuple

#: Rounds averaged over.
KEPT = 32
#: Fewer rounds than this: the period is not known yet.
AT_LEAST = 8
#: s without a round after which the period is not known (the robot went silent); the
#: robot client passes its own staleness (:data:`walkman.hal.robot.STALE_AFTER`).
STALE_AFTER = 0.5


class RoundPeriod:
    """Seconds per robot step, from the rounds' arrivals, counts and robot times."""

    def __init__(self, stale_after: float = STALE_AFTER) -> None:
        self.stale_after = stale_after
        #: per round: seconds since the last by arrival, by the robot's clock (None: it
        #: did not say), and robot steps
        self._rounds: Deque[Tuple[float, Optional[float], int]] = deque(maxlen=KEPT)
        self.newest: float = 0.0                         # when the newest arrived (monotonic)
        self._seq = 0
        self._robot_time: Optional[float] = None

    def round(self, now: float, seq: int, robot_time: Optional[float] = None) -> None:
        """A round arrived at ``now``: the robot's state count ``seq``, its time if said."""
        if now - self.newest < self.stale_after:
            before = self._robot_time
            by_robot = robot_time - before if robot_time is not None and before is not None \
                else None
            if by_robot is None or by_robot >= 0:       # back in time: a restarted robot
                self._rounds.append((now - self.newest, by_robot, seq - self._seq))
        self.newest, self._seq, self._robot_time = now, seq, robot_time

    def period(self, now: float) -> float:
        """The robot's step in seconds; 0 when not known (see the module's docstring)."""
        rounds = list(self._rounds)
        steps = [taken for _, _, taken in rounds]
        if len(steps) < AT_LEAST or now - self.newest >= self.stale_after or \
                sorted(steps)[len(steps) // 2] != 1 or sum(steps) <= 0:
            return 0.0
        # Chain by chain, a round may end on a chain that already said this step: 0 steps,
        # 0 s by the robot's clock (fc3 read 2.06 ms for a 2-ms robot chain by chain while
        # rounds were timed by arrival whenever the robot's time had not moved).
        by_robot = [spent for _, spent, _ in rounds]
        if None not in by_robot and sum(by_robot) > 0:
            return sum(by_robot) / sum(steps)
        return sum(arrived for arrived, _, _ in rounds) / sum(steps)
