"""The robot's clock as gazebo_yarp_clock serves it: ``/clock`` ticks and the ``/clock/rpc`` verbs.

Theory of operation
-------------------
``walkman-hal --clock /clock`` is the clock source of the simulated robot, wire for wire
what gazebo-yarp-plugins' clock plugin is for Gazebo:

* after the physics steps of each wake-up (2 ms of simulated time at most) it writes the
  simulated time on ``/clock`` as YARP's network-clock tick (:mod:`yarp_lite.clock_wire`),
  which every YARP program started with ``YARP_CLOCK=/clock`` follows;
* ``/clock/rpc`` answers the thrift service ``ClockServer`` (``clock_rpc.thrift``) on its
  wire: a call is a Bottle ``[verb args...]``; a two-way call's reply is a list of its
  result (``[t]`` for the doubles, ``[]`` for ``stepSimulationAndWait``); a one-way call
  asked through ``yarp rpc`` is answered ``[done]``, as YARP's ``writeOnewayResponse``.
  What the thrift server would drop without a word (an unknown verb, a bad count) is
  answered ``[fail] "why"`` here.

Simulated time is ``EPOCH`` plus the steps taken since start (or the last
``resetSimulationTime``) times the step: counted, not summed, so 50 steps advance it by
exactly 50 steps.  It starts at ``EPOCH``, above zero, because ROS reads a time of 0 as
"no clock yet".

:class:`StepGate` is what the physics thread passes before each step: open while the
simulation runs; while paused it lets through only the steps granted by
``stepSimulation``/``stepSimulationAndWait``.  The physics thread never waits for anyone
inside a step; it waits at the gate, between steps, in slices short enough to notice a
shutdown.  A caller of ``stepSimulationAndWait`` waits (on the wall clock, in slices) for
the physics to take its steps; closing the gate releases every waiter.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Callable, Dict, Optional

from yarp_lite.bottle import Bottle, Vocab

#: Simulated time at step 0 (s): above zero, since ROS reads 0 as "no clock yet".
EPOCH = 1.0
#: The most simulated time one ``stepSimulation``/``stepSimulationAndWait`` may ask for (s):
#: a count beyond it is a typo or garbage, not a plan (``stepSimulationAndWait 1000000000``
#: would hold its caller for days).
MAX_STEP_SPAN_S = 60.0
#: How long the physics thread or a waiter sleeps at once before looking again (wall s).
WAIT_SLICE_S = 0.1

ONEWAY = [Vocab("done")]


class StepGate:
    """Pause, run, or let through a counted number of steps (see the module's docstring)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.paused = False
        self._granted = 0            # steps still allowed while paused
        self.taken = 0               # steps taken since start (never reset)
        self.closed = False
        self._stepping = False       # between may_step() and stepped()

    def pause(self) -> None:
        """Pause at the next step boundary: returns once no step is under way, so the time
        read after a pause is the time it stays at."""
        with self._cond:
            self.paused = True
            while self._stepping and not self.closed:
                self._cond.wait(WAIT_SLICE_S)

    def resume(self) -> None:
        with self._cond:
            self.paused, self._granted = False, 0
            self._cond.notify_all()

    def grant(self, steps: int) -> int:
        """Let ``steps`` more steps happen; return the step count they end at."""
        with self._cond:
            if self.paused:
                self._granted += steps
            self._cond.notify_all()
            return self.taken + self._granted if self.paused else self.taken + steps

    def wait_for(self, target: int, still_wanted: Callable[[], bool] = lambda: True) -> bool:
        """Wait until ``target`` steps were taken (False: the gate closed first)."""
        with self._cond:
            while self.taken < target:
                if self.closed or not still_wanted():
                    return False
                self._cond.wait(WAIT_SLICE_S)
            return True

    def may_step(self) -> bool:
        """The physics thread asks before a step; waits one slice at most while held."""
        with self._cond:
            if not (not self.paused or self._granted > 0):
                self._cond.wait(WAIT_SLICE_S)
            self._stepping = not self.paused or self._granted > 0
            return self._stepping

    def stepped(self) -> None:
        with self._cond:
            self.taken += 1
            self._stepping = False
            if self.paused and self._granted > 0:
                self._granted -= 1
            self._cond.notify_all()

    @property
    def held(self) -> bool:
        """Paused with no step left to take."""
        with self._cond:
            return self.paused and self._granted == 0

    def close(self) -> None:
        with self._cond:
            self.closed, self.paused = True, False
            self._cond.notify_all()


class ClockError(ValueError):
    """A ClockServer call the server refuses; the message says which and why."""


@dataclass
class SimulationTime:
    """Simulated time from counted steps (``EPOCH + (taken - base) * step``)."""

    step: float
    base: int = 0

    def at(self, taken: int) -> float:
        return EPOCH + (taken - self.base) * self.step


class ClockServer:
    """The ``ClockServer`` verbs over a :class:`StepGate` (the ``/clock/rpc`` handler)."""

    def __init__(self, gate: StepGate, time: SimulationTime,
                 on_reset: Optional[Callable[[], Optional[str]]] = None,
                 published: Optional[Callable[[int], bool]] = None) -> None:
        self.gate = gate
        self.time = time
        #: Called before a time reset; returns why it must be refused, or None.
        self.on_reset = on_reset
        #: Waits until the tick of a step count is written on the clock port, so the reply
        #: to ``stepSimulationAndWait`` leaves after the tick that ends it.
        self.published = published
        self.max_steps = max(1, int(round(MAX_STEP_SPAN_S / time.step)))
        self._verbs: Dict[str, Callable[[Bottle], Bottle]] = {
            "pauseSimulation": self._pause, "continueSimulation": self._continue,
            "stepSimulation": self._step, "stepSimulationAndWait": self._step_and_wait,
            "getSimulationTime": self._get_time, "getStepSize": self._get_step,
            "resetSimulationTime": self._reset_time, "help": self._help,
        }

    def now(self) -> float:
        return self.time.at(self.gate.taken)

    def answer(self, request: Bottle) -> Bottle:
        """The reply to one ``/clock/rpc`` request; never raises on a peer's bytes."""
        verb = str(request[0]) if request and isinstance(request[0], str) else ""
        handler = self._verbs.get(verb)
        if handler is None:
            shown = Bottle(request).to_text()[:60]
            return Bottle([Vocab("fail"), f"unknown ClockServer call {shown!r}; known: "
                           f"{' '.join(v for v in self._verbs if v != 'help')}"])
        try:
            return handler(request)
        except ClockError as exc:
            return Bottle([Vocab("fail"), f"{verb}: {exc}"])

    # -- the verbs ---------------------------------------------------------------------------

    def _no_arguments(self, request: Bottle) -> None:
        if len(request) > 1:
            raise ClockError(f"takes no arguments, got {Bottle(request[1:]).to_text()[:40]!r}")

    def _count(self, request: Bottle) -> int:
        """``numberOfSteps`` (default 1): a whole number from 1 to :attr:`max_steps`."""
        if len(request) == 1:
            return 1
        if len(request) > 2:
            raise ClockError(f"takes one step count, got {Bottle(request[1:]).to_text()[:40]!r}")
        count = request[1]
        if type(count) is not int:
            raise ClockError(f"the step count must be an integer, got {count!r}")
        if not 1 <= count <= self.max_steps:
            raise ClockError(f"the step count must be 1 to {self.max_steps} "
                             f"({MAX_STEP_SPAN_S:g} s of {self.time.step * 1e3:g} ms steps), "
                             f"got {count}")
        return count

    def _pause(self, request: Bottle) -> Bottle:
        self._no_arguments(request)
        self.gate.pause()
        return Bottle(ONEWAY)

    def _continue(self, request: Bottle) -> Bottle:
        self._no_arguments(request)
        self.gate.resume()
        return Bottle(ONEWAY)

    def _step(self, request: Bottle) -> Bottle:
        self.gate.grant(self._count(request))
        return Bottle(ONEWAY)

    def _step_and_wait(self, request: Bottle) -> Bottle:
        target = self.gate.grant(self._count(request))
        if not self.gate.wait_for(target) or \
                (self.published is not None and not self.published(target)):
            raise ClockError("the simulation stopped before the steps were taken")
        return Bottle()

    def _get_time(self, request: Bottle) -> Bottle:
        self._no_arguments(request)
        return Bottle([float(self.now())])

    def _get_step(self, request: Bottle) -> Bottle:
        self._no_arguments(request)
        return Bottle([float(self.time.step)])

    def _reset_time(self, request: Bottle) -> Bottle:
        self._no_arguments(request)
        refusal = self.on_reset() if self.on_reset else None
        if refusal:
            raise ClockError(refusal)
        self.time.base = self.gate.taken
        return Bottle(ONEWAY)

    def _help(self, request: Bottle) -> Bottle:
        return Bottle([Vocab("many"), *(v for v in self._verbs if v != "help")])


def parse_rtf(text: str) -> Optional[float]:
    """``--rtf``: a real-time factor above 0, or ``max`` (None: as fast as the machine goes)."""
    if text.strip().lower() == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--rtf takes a factor above 0 or 'max', not {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"--rtf takes a factor above 0 or 'max', not {text!r}")
    return value
