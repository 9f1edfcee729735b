"""What a switch does to a module: one :class:`Lifecycle` for every driver.

:mod:`walkman.gym.lifecycle` says which switch is legal and where it leads;
this file carries it out, with every side effect the pilot can see: the
module's hooks, the status word of each lifecycle state, the module's own
status told again on resume, the robot held once ``stop`` or ``quit`` released
it, the warning for an illegal switch.  The process runner
(:mod:`walkman.gym.runner`) and the offline runner (:mod:`walkman.gym.offline`)
each drive one :class:`Lifecycle` and decide only *where* and *when*:

* ``call_hook(hook)`` runs a hook where the module's code runs.  The runner
  asks its control thread, between two ``run()`` calls, and answers None when
  the hook did not return in time; offline it is :meth:`Lifecycle.perform`, here.
* ``wait_until(done, timeout)`` lets the module run on until ``done()`` (its
  safe pause).  The runner polls while its control thread calls ``run()``;
  offline steps the simulated world.

What each switch does, in order (the runner's order, which runs on the robot):

==========  ==================================================================
start       ``custom_init``; if it fails the state and its status word stay.
            Then ``running``; the module says its own status from here on.
pause       ``run()`` goes on to a safe pause (told if it does not come within
            :data:`~walkman.gym.lifecycle.PAUSE_GRACE`); ``paused``: ``run()``
            is no longer called; the module's status is kept; ``custom_pause``
            (paused whatever it answers); "paused".
resume      ``custom_resume``; if it fails the module stays paused.  Then
            ``running``, and the status kept at the pause is said again
            (``run()`` may not repeat it).
stop, quit  ``stop`` of a running module first goes on to a safe pause.  Then
            ``stopped`` / ``destructor``; if ``custom_init`` was in force,
            ``custom_release`` and the robot held (the module's
            :meth:`held_posture`); "stopped" / "destructor".
==========  ==================================================================

A hook that raises is told on the warning port, with its traceback in the
log, and counts as failed (:meth:`Lifecycle.perform`).  The state changes
under one lock, applied to the state as it is *now*: the runner's control
thread also stops a module whose ``run()`` raised (:meth:`Lifecycle.fail_stop`),
and a switch that lost that race is refused by the table and told, never
written over the winner's.
"""

from __future__ import annotations

import logging
import threading
import time
from enum import Enum
from typing import TYPE_CHECKING, Callable, Dict, Optional, Tuple

from walkman.gym.interfaces import PilotInterfaces
from walkman.gym.lifecycle import (HOOKS, PAUSE_GRACE, IllegalTransition, State, Switch,
                                   next_state, parse_switch, releases, run_hook, status_word)
from walkman.gym.thread import ControlThread, GenericThread
from walkman.hal.protocol import HalUsageError

if TYPE_CHECKING:
    from walkman.hal.robot import WholeBody

log = logging.getLogger("walkman.gym")

#: Runs ``custom_<hook>`` where the module's code runs: its verdict, or None if it hung.
HookCall = Callable[[str], Optional[bool]]
#: Lets the module run until ``done()`` or ``timeout`` s: whether ``done()`` came true.
Wait = Callable[[Callable[[], bool], float], bool]


class Outcome(str, Enum):
    DONE = "done"
    #: Illegal, a hook failed, or the state changed meanwhile: told, the state is as it was.
    REFUSED = "refused"
    #: ``stop``/``quit`` took effect but ``custom_release`` never returned: the driver must
    #: end the module (the runner restarts its process).
    HUNG = "hung"


class Lifecycle:
    """One module's lifecycle state and what each switch does to it (module docstring).

    ``robot`` gives the whole-body interface to hold on ``stop`` (None: nothing to
    hold); ``prepare_init`` is checked before ``custom_init`` (the runner: the HAL is
    there); a False answer fails the start.  ``clock`` dates each change of state
    (:attr:`since`: the link-loss policy counts from it).
    """

    def __init__(self, name: str, thread: GenericThread, interfaces: PilotInterfaces, *,
                 wait_until: Wait, call_hook: Optional[HookCall] = None,
                 robot: Callable[[], Optional["WholeBody"]] = lambda: None,
                 prepare_init: Callable[[], bool] = lambda: True,
                 initial: State = State.CONSTRUCTOR,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.name, self.thread, self.interfaces = name, thread, interfaces
        self._wait_until = wait_until
        self._call_hook: HookCall = call_hook or self.perform
        self._robot = robot
        self._prepare_init = prepare_init
        self._lock = threading.Lock()
        self._state = initial
        self._clock = clock
        self._since = clock()
        #: What the module was saying when it paused, said again on resume.
        self._status_at_pause: Optional[Tuple[str, list]] = None
        self._apply: Dict[Switch, Callable[[Switch], Outcome]] = {
            Switch.START: self._start, Switch.PAUSE: self._pause, Switch.RESUME: self._resume,
            Switch.STOP: self._stop, Switch.QUIT: self._stop}
        self.say_state()

    @property
    def state(self) -> State:
        return self._state

    @property
    def since(self) -> float:
        """When (``clock``) the module entered :attr:`state`."""
        return self._since

    def _transition(self, switch: Switch) -> Tuple[State, State]:
        """Apply ``switch`` to the state as it is now, atomically: ``(before, after)``;
        :class:`IllegalTransition` if the other thread changed it meanwhile."""
        with self._lock:
            before = self._state
            self._state = next_state(self.name, before, switch.value)
            self._since = self._clock()
            return before, self._state

    def say_state(self) -> None:
        """The status word of the state outside ``running`` (running, the module speaks)."""
        state = self._state
        if state != State.RUNNING:
            self.interfaces.set_status(status_word(state))

    def warn(self, text: str, exc_info: bool = False) -> None:
        log.warning("%s", text, exc_info=exc_info)
        self.interfaces.warn(text)

    # -- switches (the driver's thread) ------------------------------------------------------

    def accept(self, command: str) -> Optional[Switch]:
        """The switch ``command`` names if it is legal now; None, and a warning, if not."""
        try:
            next_state(self.name, self._state, command)
        except IllegalTransition as exc:
            self.warn(str(exc))
            return None
        return parse_switch(command)

    def switch(self, command: str) -> Outcome:
        """:meth:`accept` then :meth:`apply`."""
        switch = self.accept(command)
        return Outcome.REFUSED if switch is None else self.apply(switch)

    def apply(self, switch: Switch) -> Outcome:
        """Carry out an accepted switch with its hooks and status (module docstring)."""
        try:
            outcome = self._apply[switch](switch)
        except IllegalTransition as exc:  # run() failed while the hooks ran: the module stopped
            self.warn(f"{exc}; the state changed meanwhile")
            return Outcome.REFUSED
        if outcome is not Outcome.REFUSED:
            log.info("%s: %s -> %s", self.name, switch.value, self._state.value)
        return outcome

    def _start(self, switch: Switch) -> Outcome:
        if not self._call_hook(HOOKS[switch]):
            self.warn(f"{self.name}: custom_init() failed, the module stays {self._state.value}")
            self.say_state()
            return Outcome.REFUSED
        self._transition(switch)
        return Outcome.DONE

    def _pause(self, switch: Switch) -> Outcome:
        self._reach_safe_pause()
        try:
            self._transition(switch)  # run() is not called again from here on
        except IllegalTransition:
            self.thread.pause_requested = False
            raise
        self._status_at_pause = (self.interfaces.state, list(self.interfaces.data))
        if self._call_hook(HOOKS[switch]) is None:
            self.warn(f"{self.name}: custom_pause() did not return")
        self.say_state()
        return Outcome.DONE

    def _resume(self, switch: Switch) -> Outcome:
        self.thread.pause_requested = False
        if not self._call_hook(HOOKS[switch]):
            self.warn(f"{self.name}: custom_resume() failed, staying paused")
            return Outcome.REFUSED
        self._transition(switch)
        if self.interfaces.state == status_word(State.PAUSED) and self._status_at_pause:
            self.interfaces.set_status(*self._status_at_pause)
        return Outcome.DONE

    def _stop(self, switch: Switch) -> Outcome:
        """``stop`` or ``quit``: ``stop`` of a running module first lets it reach a safe
        pause, as ``pause`` does (walking lands its foot and comes to rest)."""
        if switch == Switch.STOP and self._state == State.RUNNING:
            self._reach_safe_pause()
        self.thread.pause_requested = False
        before, _ = self._transition(switch)
        if releases(before):  # custom_init in force: undo it once, and hold what it drove
            if self._call_hook(HOOKS[switch]) is None:
                return Outcome.HUNG
            self.hold(f"'{switch.value}'")
        self.say_state()
        return Outcome.DONE

    def _reach_safe_pause(self) -> None:
        """Let run() go on until the module says it can pause (paper: finish the step)."""
        thread = self.thread
        thread.pause_requested = True
        if not self._wait_until(lambda: self._state != State.RUNNING or thread.ready_to_pause(),
                                PAUSE_GRACE):
            self.warn(f"{self.name}: no safe pause within {PAUSE_GRACE:g} s; pausing now")

    # -- in the thread that runs the module's code -------------------------------------------

    def perform(self, hook: str) -> bool:
        """Run ``custom_<hook>``; False if it failed (told), or if it no longer applies."""
        if hook in (HOOKS[Switch.PAUSE], HOOKS[Switch.RESUME]) and self._state != State.PAUSED:
            return False  # run() failed and the module stopped since the pilot asked
        try:
            if hook == HOOKS[Switch.START] and not self._prepare_init():
                return False
            return run_hook(self.thread, hook)
        except Exception as exc:  # the module's hook failed: its bug, told with the traceback
            self.warn(f"{self.name}: custom_{hook}() raised {type(exc).__name__}: {exc}",
                      exc_info=True)
            return False

    def fail_stop(self) -> bool:
        """After run() raised: stop and release, unless the pilot stopped it meanwhile."""
        try:
            self._transition(Switch.STOP)
        except IllegalTransition:
            return False  # stopped or quit by the pilot, whose release comes next
        self.perform(HOOKS[Switch.STOP])
        self.say_state()
        return True

    def hold(self, after: str) -> None:
        """Keep the robot where it is after ``after``; if even that fails, the pilot hears it."""
        robot = self._robot()
        if robot is None:
            return
        try:
            posture = self._module_posture()
            held = robot.hold() if posture is None else \
                robot.move(posture, joints=getattr(self.thread, "joints", None))
        except HalUsageError as exc:
            self.warn(f"{self.name}: could not hold the robot after {after}: {exc}")
            return
        except Exception as exc:  # a bug while holding: told with its traceback; stopping goes on
            self.warn(f"{self.name}: holding the robot after {after} failed with "
                      f"{type(exc).__name__}: {exc}", exc_info=True)
            return
        if not held:
            self.warn(f"{self.name}: could not hold the robot after {after}: the HAL does not "
                      f"take commands")

    def _module_posture(self):
        """The module's :meth:`held_posture`, or None if it has none or it fails."""
        if not isinstance(self.thread, ControlThread):
            return None
        try:
            return self.thread.held_posture()
        except Exception:  # the module's bug: hold what the joints read instead
            log.exception("%s: held_posture() failed; holding the sensed posture", self.name)
            return None
