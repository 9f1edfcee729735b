"""A GYM module in lockstep with the robot's clock: its loop ticks on the robot's rounds.

Theory of operation
-------------------
``walkman-module NAME --lockstep`` (or ``WALKMAN_LOCKSTEP=1`` in its environment) joins the
clock ``YARP_CLOCK`` names (default ``/clock``: ``walkman-hal --clock``).  While the module
controls the robot, the HAL holds its physics at each of the module's ticks until the module
has handled it (:mod:`walkman.hal.lockstep`), so:

* the loop ticks on the round at the first robot time at or after its deadline (the tick
  before plus ``thread_period``), never on the wall clock, and reads that round's state and
  the sensor readings streamed at its step (:meth:`walkman.hal.robot.Robot.wait_round_at`);
* the module's clock (``self.now()``) is that round's robot time, exactly;
* after the tick it tells the HAL which chains it commanded and when its next tick is due,
  and the physics goes on once those commands are in.

A module that stops controlling (stopped, paused without balancing, the robot away) leaves
the barrier; back in control it joins again at the next round.  A run started with the robot
paused (``walkman-hal --clock --paused``) is then a function of its inputs: the same states,
the same commands, the same robot, at any load.

:class:`LockstepSchedule` stands where :class:`walkman.gym.pacing.TickSchedule` stands in the
control loop; the loop asks :meth:`round_ready` before each tick and calls :meth:`wait` after
it, which here only says the tick is done.
"""

from __future__ import annotations

import logging
import os
import threading
from collections import deque
from typing import TYPE_CHECKING, Callable, Deque, Optional

from walkman.hal import lockstep
from walkman.hal.lockstep import Join, Leave, Tick
from yarp_lite import time as yarp_time
from yarp_lite.errors import NetworkError, YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

if TYPE_CHECKING:
    from walkman.hal.robot import Robot

log = logging.getLogger("walkman.gym.lockstep")

#: The environment variable that puts every module started with it in lockstep.
ENVIRONMENT = "WALKMAN_LOCKSTEP"
#: The longest a wait for the next round lasts before the loop looks at its requests (wall s).
WAIT_SLICE_S = 0.05
#: A join holds the physics from this much robot time after the newest round (s): strictly
#: after it (a robot's rounds are at least 0.5 ms apart), so the first tick runs on a round
#: the robot holds at, never on one it already went past.
JOIN_AFTER = 1e-4
#: Waiting this long (wall s) for a round is worth a line in the log, once per wait.
SLOW_ROUND_S = 1.0


def wanted(flag: bool) -> bool:
    """Lockstep asked for on the command line or in the environment."""
    return flag or os.environ.get(ENVIRONMENT, "") not in ("", "0")


def clock_name() -> str:
    """The clock to join: the one ``YARP_CLOCK`` names, as every YARP program follows it."""
    return yarp_time.source_from_environment() or yarp_time.DEFAULT_SOURCE


class LockstepSchedule:
    """The ticks of a module in lockstep (see the module's docstring)."""

    def __init__(self, period: float, owner: str, robot: Callable[[], Optional["Robot"]],
                 clock: Optional[str] = None, nameclient: Optional[NameClient] = None) -> None:
        self.period = period
        self.owner = owner.rstrip("/")   # as the robot client names its ports (its commands)
        self._lock = threading.Lock()      # joined, and what is written: loop and close()
        self._robot = robot
        self.clock = clock or clock_name()
        self._nameclient = nameclient or NameClient()
        self.port = Port(nameclient=self._nameclient)
        self.joined = False
        self.due = 0.0             # robot time of the round the next tick runs on
        self.time = 0.0            # robot time of the round being handled
        self.seq = 0
        self._waited = 0.0          # wall seconds spent waiting for the round due
        self._said_slow = False
        # What the runner's statistics read (the loop is never late against the robot here).
        self.locked_ticks = 0
        self.interval_errors: Deque[float] = deque(maxlen=1)

    def open(self, wait: float) -> None:
        """Open ``OWNER/lockstep:o`` (waiting up to ``wait`` s for the name server, as the
        module's other ports) and keep it connected to the clock's ``NAME/lockstep:i``:
        persistently, so a HAL that starts after the module, or restarts, is found again."""
        self.port.open(f"{self.owner}/lockstep:o", wait=wait)
        target = lockstep.port_name(self.clock)
        if not self._nameclient.subscribe(self.port.name, target):
            raise NetworkError(f"the name server refused {self.port.name} -> {target}")

    def now(self) -> float:
        """The module's clock: the robot time of the round it handles."""
        robot = self._robot()
        if not self.joined and robot is not None and robot.round_time > self.time:
            return robot.round_time
        return self.time

    def round_ready(self, interrupted: Callable[[], bool]) -> bool:
        """Wait for the round the next tick runs on (joining the barrier first); False when
        ``interrupted`` said so first (a request for the loop, a quit)."""
        robot = self._robot()
        if robot is None:
            return False
        if not self.joined:
            robot.take_commanded()   # moves made out of a tick (a hold on stop) are not its
            with self._lock:
                self.time = max(robot.round_time, 0.0)   # (a restarted robot's time is new)
                self.due = self.time + JOIN_AFTER        # the next round
                self._write(Join(self.owner, self.due))
                self.joined = True
            self._waited = 0.0
            log.info("%s: in lockstep with %s", self.owner, self.clock)
        while not robot.wait_round_at(self.due, WAIT_SLICE_S):
            if robot.round_time < self.time - 1e-6 or not robot.connected:
                # The robot restarted (its time went back) or is silent: out of the barrier;
                # the loop sees the robot away, or joins the new one at its next round.
                self.restart()
                return False
            self._waited += WAIT_SLICE_S
            if self._waited >= SLOW_ROUND_S and not self._said_slow:
                self._said_slow = True
                log.warning("%s: no round at robot time %.4f s after %.1f s: %s", self.owner,
                            self.due, self._waited, robot.lockstep_view())
            if interrupted():
                return False
        self._waited, self._said_slow = 0.0, False
        self.time, self.seq = robot.round_time, robot.last_seq
        return True

    def wait(self) -> float:
        """The tick is done: name its commands' chains and the next tick's time."""
        robot = self._robot()
        chains = tuple(robot.take_commanded()) if robot is not None else ()
        with self._lock:
            if not self.joined:     # closed meanwhile: a tick now would join it again
                return 0.0
            self.due = self.time + self.period
            self._write(Tick(self.owner, self.seq, self.due, chains))
        self.locked_ticks += 1
        return 0.0

    def restart(self) -> None:
        """Not controlling (or the robot away): leave the barrier."""
        with self._lock:
            if not self.joined:
                return
            self._write(Leave(self.owner))
            self.joined = False
        log.info("%s: out of lockstep (not controlling the robot)", self.owner)

    def _write(self, message: lockstep.Message) -> None:
        self.port.write(lockstep.encode(message))

    def close(self) -> None:
        if not self.port.is_open:
            return
        self.restart()
        try:
            self._nameclient.unsubscribe(self.port.name, lockstep.port_name(self.clock))
        except YarpError as exc:  # the name server gone at shutdown: nothing left to undo
            log.debug("%s: lockstep connection not removed (%s)", self.owner, exc)
        self.port.close()
