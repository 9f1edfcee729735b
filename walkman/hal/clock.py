"""The robot's clock: the time a module's trajectories run on.

Theory of operation
-------------------
A module times its trajectories by the robot, not by the wall clock.  The simulated robot's
physics runs slower than real time whenever its machine is loaded (the HAL never bursts to
catch up); a module timed by the wall clock then runs its references ahead of the physics --
a walking robot's feet land late and the ZMP leaves the feet.  Real YARP does the same with a
network clock (``YARP_CLOCK``, published by the simulator), ROS with ``/use_sim_time``; on
the real robot the robot's time is real time and nothing changes.

Every state our HAL streams carries its time (``stateSI``); a plain YARP robot's state
(``stateExt``) is timed by when it arrived, since a device's stamp need not move
(``fakeMotionControl`` stamps time 0), and the module then runs on the wall clock as before.
The clock reads the newest robot time plus the wall time since it arrived, at most
``max_ahead``: it advances smoothly between two states and waits when the robot is slower
than the wall or silent.  It never goes backwards (the chains' states arrive one by one: a
slightly older one is ignored) and never leaps: when the robot is back from a silence,
restarted from time 0, or its time ran on further than the wall meanwhile (a connection
remade, a wall clock set forward), the clock goes on from where it stood -- a trajectory goes
on from where it paused instead of jumping ahead (an arm leaping along its path next to a
valve is a hazard).  Before the first state it is the wall clock.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Optional

#: A state this much older (s) than the newest comes from a restarted robot; less, from a
#: chain whose state was on its way while another's arrived.
RESTART_STEP_BACK = 0.5


class RobotClock:
    """Monotonic seconds that follow the robot's own time (see the module's docstring)."""

    def __init__(self, max_ahead: float, silence: float,
                 wall: Callable[[], float] = time.monotonic) -> None:
        self.max_ahead = max_ahead
        #: No state for this long (s) is a silence: the robot is lost until the next one.
        self.silence = silence
        self._wall = wall
        self._lock = threading.Lock()
        self._offset: Optional[float] = None  # clock = offset + robot time (+ extrapolation)
        self._robot_time = 0.0
        self._received_at = 0.0
        self._last = -float("inf")

    def observe(self, robot_time: float) -> None:
        """A state stamped ``robot_time`` (s) arrived now."""
        received_at = self._wall()
        with self._lock:
            if self._offset is None:
                self._offset = max(received_at, self._last) - robot_time
            else:
                step = robot_time - self._robot_time
                if -RESTART_STEP_BACK <= step <= 0:
                    return  # an older state (chains arrive one by one): the clock has it
                waited = received_at - self._received_at
                if step < 0 or waited > self.silence or step > waited + self.max_ahead:
                    # restarted, back from a silence, or its time ran on without us
                    self._offset = self._value(received_at) - robot_time
            self._robot_time, self._received_at = robot_time, received_at

    def now(self) -> float:
        wall = self._wall()
        with self._lock:
            return self._value(wall)

    def _value(self, wall: float) -> float:
        """The clock at ``wall``, never below what it said before (lock held)."""
        if self._offset is None:
            value = wall
        else:
            ahead = min(max(wall - self._received_at, 0.0), self.max_ahead)
            value = self._offset + self._robot_time + ahead
        self._last = max(self._last, value)
        return self._last
