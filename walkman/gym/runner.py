"""The process that runs one GYM module: pilot ports, watchdog, control loop.

Theory of operation
-------------------
Three threads:

* the **watchdog** (main thread) wakes every 0.5 s, or at once when a switch
  command arrives.  It applies switch commands through the lifecycle table
  (:mod:`walkman.gym.lifecycle`), then the module's link-loss policy
  (:mod:`walkman.gym.link_loss`: a ``pause`` or ``stop`` made as a pilot's, then
  a warning saying why) from what the robot's bridge says of the link
  (:mod:`walkman.gym.bridge_link`), publishes the status every 0.5 s (and at
  once when it changes) and writes a heartbeat for the supervisor;
* the **control thread** calls ``run()`` every ``thread_period`` while
  running, and performs the hooks (``custom_init``, ``custom_pause``...) on
  the watchdog's request, between two ``run()`` calls, so user code is never
  re-entered.  Its ticks follow the robot's state rounds
  (:mod:`walkman.gym.pacing`), or, with ``--lockstep``, the robot waits for each
  of them (:mod:`walkman.gym.lockstep`);
* the **connector** finds the HAL (whole-body interface) in the background, so
  the module starts before the HAL and says "waiting_hal" meanwhile.  Only a
  :class:`~yarp_lite.errors.NetworkError` means "not there yet" and is retried;
  a HAL that answers wrongly, or any other exception (a bug, logged with its
  traceback), makes every ``start`` fail with the reason on the warning port.

What a switch does -- hooks, status words, the status told again on resume,
the hold on stop -- is :class:`~walkman.gym.transitions.Lifecycle`'s, the same
object the offline runner drives; this file decides only when and in which
thread.  Both the watchdog and the control thread change the lifecycle state
(the control thread stops a module whose ``run()`` raised); the lifecycle
applies each change to the state as it is *now*, under one lock, so a change
that lost a race (a ``pause`` whose module failed meanwhile) is refused by the
table, never written over the winner's.

``stop`` and ``quit`` always win: the watchdog asks the control thread and
waits 2 s; if ``run()`` hangs, the process exits with :data:`EXIT_ESCALATED`
and the supervisor starts a fresh one, stopped (``quit``: it simply exits).
An exception in ``run()`` is reported on the warning port, the robot holds
its position and the module stops.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import math
import os
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple, Type

from nodekit import stacks
from nodekit.logs import configure_logging, time_prefix
from walkman import inifile
from walkman.gym.bridge_link import BridgeLink
from walkman.gym.command_life import CommandState, Receipt
from walkman.gym.inbox_journal import InboxJournal, Predecessor, interruptions, journal_path
from walkman.gym.interfaces import PilotCommand, PilotInterfaces, decoder_for, validity_of
from walkman.gym.link_loss import LinkLossDecider, link_loss_of
from walkman.gym.lockstep import LockstepSchedule
from walkman.gym.lockstep import wanted as lockstep_wanted
from walkman.gym.pacing import TickSchedule
from walkman.gym.lifecycle import State, Switch
from walkman.gym.thread import ControlThread, GenericThread
from walkman.gym.transitions import Lifecycle, Outcome
from walkman.hal.protocol import HalProtocolError, HalUsageError
from walkman.realtime import (BACKGROUND_PRIORITY, CONTROL_PRIORITY, SWITCH_INTERVAL,
                              at_priority, make_normal, make_process_realtime,
                              make_realtime)
from yarp_lite.errors import NetworkError
from yarp_lite.nameclient import NameClient

log = logging.getLogger("walkman.gym")

EXIT_QUIT = 0
#: What the runner writes on the heartbeat pipe once the pilot's ``quit`` is done and it is
#: closing its ports (a heartbeat is ``b"."``): from then on the supervisor waits for it to
#: end instead of restarting it (walkman.gym.supervisor.QUIT_GRACE)
QUITTING = b"q"
#: What the runner writes on the heartbeat pipe once its SIGUSR1/2 handlers are in place,
#: before its imports: from then on the supervisor passes those signals on (one sent to a
#: process still without a handler would kill it).  Not a beat: a module still starting
#: keeps the supervisor's longer start-up timeout.
SIGNALS_ARMED = b"s"
EXIT_ESCALATED = 3
HOOK_TIMEOUT = 2.0
STATUS_PERIOD = 0.5
#: Shortest time between two statuses sent because the module's status changed: a pilot
#: sees a change at once, and a status that changes every tick costs at most 20 a second.
STATUS_MIN_GAP = 0.05
CONNECT_RETRY = 2.0  # s between two attempts to reach a HAL that is not there yet
DEFAULTS = {"thread_period": 10, "robot_name": "walkman", "urdf_path": ""}


def module_name(spec: str) -> str:
    """The name a module's ports and config go by: ``my_wave:Module`` -> ``my_wave``."""
    return spec.split(":")[0].split(".")[-1]


def load_module_class(name: str) -> Type[GenericThread]:
    """``walkman.modules.<name>.Module``, or ``package.module:Class`` for your own."""
    if ":" in name:
        module_path, class_name = name.split(":", 1)
    else:
        module_path, class_name = f"walkman.modules.{name}", "Module"
    try:
        return getattr(importlib.import_module(module_path), class_name)
    except (ImportError, AttributeError) as exc:
        raise SystemExit(f"walkman-module: no module {name!r} ({exc})") from None


class ControlLoop(threading.Thread):
    """Runs the user's code; only this thread ever calls into it."""

    def __init__(self, runner: "ModuleRunner") -> None:
        super().__init__(daemon=True, name=f"{runner.name} control")
        self.runner = runner
        self.cond = threading.Condition()
        self.request: Optional[str] = None
        self.done: Optional[bool] = None
        self.period_errors: List[float] = []
        self.exit = False
        self._reading: Optional[Tuple[int, bool]] = None   # (robot, controlling) told

    def ask(self, hook: str, timeout: Optional[float] = None,
            beat: Callable[[], None] = lambda: None) -> Optional[bool]:
        """Have the control thread perform a hook; None if it did not within ``timeout``.
        ``beat`` is called every :data:`STATUS_PERIOD` meanwhile: a watchdog waiting for a
        slow ``custom_init`` (30 s allowed) is not hung, and its supervisor, which kills a
        module silent for 5 s, must hear it."""
        timeout = HOOK_TIMEOUT if timeout is None else timeout
        deadline = time.monotonic() + timeout
        with self.cond:
            self.request, self.done = hook, None
            self.cond.notify_all()
            while self.done is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                beat()
                self.cond.wait(min(remaining, STATUS_PERIOD))
            return self.done

    def _serve_request(self) -> None:
        with self.cond:
            hook, self.request = self.request, None
        if hook is None:
            return
        with at_priority(BACKGROUND_PRIORITY, self.realtime):  # not above the robot's threads
            result = self.runner.lifecycle.perform(hook)     # while a model loads
        with self.cond:
            self.done = result
            self.cond.notify_all()

    def _read_robot_for(self, controlling: bool) -> None:
        """The robot's state at the loop's rate while it controls, slowly otherwise
        (:meth:`walkman.hal.robot.Robot.read_idle`); told once per change."""
        robot = self.runner.robot
        if robot is not None and self._reading != (id(robot), controlling):
            robot.read_idle(not controlling)
            self._reading = (id(robot), controlling)

    def run(self) -> None:
        runner = self.runner
        # Only a loop on the sense -> move path is real-time (realtime.py): one that moves no
        # joint (perception's renders) runs below every robot's thread.
        moves_the_robot = getattr(runner.module_class, "needs_robot", False)
        # In lockstep the robot waits for the loop: no real-time priority is needed, and none
        # is taken (a loop in lockstep at --rtf max would never sleep).
        self.realtime = make_realtime(CONTROL_PRIORITY) \
            if moves_the_robot and runner.lockstep is None else make_normal()
        self.schedule = runner.lockstep or \
            TickSchedule(runner.thread.thread_period, lambda: runner.robot)
        interrupted = lambda: self.request is not None or self.exit  # noqa: E731
        paused_too = runner.thread.runs_while_paused()
        while not self.exit:
            self._serve_request()
            state = runner.state
            controlling = state == State.RUNNING or (paused_too and state == State.PAUSED)
            self._read_robot_for(controlling)
            if not controlling:
                with self.cond:
                    self.cond.wait_for(lambda: self.request is not None or self.exit, 0.1)
                self.schedule.restart()
                continue
            if not runner.robot_alive():
                with self.cond:  # no HAL: do not drive blind; wait for it to come back
                    self.cond.wait_for(lambda: self.request is not None or self.exit, 0.1)
                self.schedule.restart()
                continue
            if runner.lockstep is not None and not runner.lockstep.round_ready(interrupted):
                continue    # a request came before the round: served first, then the round
            try:
                if state == State.RUNNING:
                    runner.thread.run()
                else:
                    runner.thread.run_paused()
            except HalUsageError as exc:
                runner.warn(f"{runner.name}: refused by the robot: {exc}")
                runner.lifecycle.hold("a refused command")
            except Exception as exc:  # the module's bug: told with its traceback, hold, stop
                hook = "run()" if state == State.RUNNING else "run_paused()"
                runner.warn(f"{runner.name}: {hook} raised {type(exc).__name__}: {exc}",
                            exc_info=True)
                runner.lifecycle.hold(f"{hook} raised")
                runner.fail_stop()
            finally:    # the tick that took them returned, or raised: theirs is done
                runner.interfaces.commands.settle()
            self.period_errors.append(self.schedule.wait())
            if len(self.period_errors) > 20000:
                del self.period_errors[:10000]


class ModuleRunner:
    """One module's lifecycle, hooks and pilot interfaces (see the module docstring).

    ``interfaces`` replaces the port-backed pilot interfaces (tests pass
    :class:`~walkman.gym.interfaces.RecordingInterfaces` to run without YARP);
    then the bridge's statuses are not read from a port either: a test feeds
    :attr:`link` itself.  ``clock`` dates the lifecycle's changes and the link's (the
    link-loss policy compares them); a test may pass one it moves.
    """

    def __init__(self, name: str, module_class: Type[GenericThread], config: Dict[str, Any],
                 prefix: Optional[str] = None, initial: State = State.CONSTRUCTOR,
                 heartbeat_fd: Optional[int] = None,
                 nameclient: Optional[NameClient] = None,
                 interfaces: Optional[PilotInterfaces] = None,
                 clock: Callable[[], float] = time.monotonic,
                 lockstep: bool = False) -> None:
        self.name = name
        self.clock = clock
        self.prefix = prefix or f"/{name}"
        self.config = config
        self.module_class = module_class
        self.nameclient = nameclient or NameClient()
        self.interfaces = interfaces or PilotInterfaces(
            self.prefix, self.nameclient, statuses=module_class.statuses or None,
            command_decoder=decoder_for(module_class), validity=validity_of(module_class))
        self.heartbeat_fd = heartbeat_fd
        self.wake = threading.Event()
        self.interfaces.switch.on_arrival = self.wake.set
        self.interfaces.commands.on_arrival = None
        self.robot = None
        self.kinematics = None
        self.robot_ready = threading.Event()
        #: Why the module cannot start (the connector gave up), or None.
        self.robot_failure: Optional[str] = None
        self.thread = self._make_thread()
        #: In lockstep with the robot's clock (:mod:`walkman.gym.lockstep`), or None.
        self.lockstep: Optional[LockstepSchedule] = None
        if lockstep and getattr(module_class, "needs_robot", False):
            self.lockstep = LockstepSchedule(self.thread.thread_period, self.prefix,
                                             lambda: self.robot, nameclient=self.nameclient)
        self.lifecycle = Lifecycle(name, self.thread, self.interfaces, initial=initial,
                                   call_hook=self._ask_control_thread,
                                   wait_until=self._wait_until, robot=lambda: self.robot,
                                   prepare_init=self._robot_ready_for_init, clock=clock)
        #: What the robot's bridge says of the link, and the module's policy when it dies.
        self.link = BridgeLink(name, clock)
        self._link_from_port = interfaces is None
        self.link_loss = LinkLossDecider(name, link_loss_of(module_class))
        self.loop = ControlLoop(self)
        self.quit_requested = False
        self.exit_code = EXIT_QUIT
        self._robot_alive = True
        self._status_before_loss = ""
        self.start_pending = False
        self.status_changed = False

    def _make_thread(self) -> GenericThread:
        return self.module_class(self.name, self.config, self.interfaces,
                                 on_status_change=self._on_status_change)

    def _on_status_change(self) -> None:
        """The module set a new status (control thread): the watchdog sends it now."""
        self.status_changed = True
        self.wake.set()

    # -- the lifecycle state ------------------------------------------------------------

    @property
    def state(self) -> State:
        """The lifecycle state; only :attr:`lifecycle` changes it."""
        return self.lifecycle.state

    def _ask_control_thread(self, hook: str) -> Optional[bool]:
        """How the lifecycle runs a hook: on the control thread (None: it did not return)."""
        return self.loop.ask(hook, timeout=30 if hook == "init" else None,
                             beat=self._heartbeat)

    def _wait_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """How the lifecycle waits for a safe pause: here, while the control thread runs.
        The watchdog is waiting, not hung: it goes on beating (the supervisor's timeout is
        as long as the pause's grace, and killing a walk mid-step is what the pause avoids)."""
        deadline = time.monotonic() + timeout
        next_beat = 0.0
        while True:
            now = time.monotonic()
            if now >= next_beat:
                self._heartbeat()
                next_beat = now + STATUS_PERIOD
            if done():
                return True
            if now > deadline:
                return False
            time.sleep(0.01)

    # -- set-up --------------------------------------------------------------------------

    def start(self) -> None:
        before = self._take_over_journal() if self._link_from_port else Predecessor()
        self.interfaces.open(wait=math.inf)
        if self.lockstep is not None:
            self.lockstep.open(wait=math.inf)
        self._report_predecessor(before)
        if self._link_from_port:
            self.link.open(self.nameclient, f"{self.prefix}/bridge:i")
        if getattr(self.module_class, "needs_robot", False):
            threading.Thread(target=self._connect_robot, daemon=True,
                             name=f"{self.name} connector").start()
        else:
            self.robot_ready.set()
        self.loop.start()
        log.info("%s: ready for the pilot on %s/switch:i (state %s; link-loss policy %s)",
                 self.name, self.prefix, self.state.value, self.link_loss.policy)

    def _take_over_journal(self) -> Predecessor:
        """Read what this module's previous process left in its command journal, and keep
        one for the next (:mod:`walkman.gym.inbox_journal`); before the ports open, so a
        resend of a command the previous process saw is dropped from the first."""
        try:
            address = self.nameclient.server_address()
            server = f"{address.host}:{address.port}"
        except NetworkError:
            server = "unconfigured"
        journal = InboxJournal(journal_path(self.prefix, server))
        try:
            before = journal.take_over()
        except OSError as exc:
            log.warning("%s: no command journal (%s): a command this process dies holding "
                        "will not be reported", self.name, exc)
            return Predecessor()
        self.interfaces.commands.remember(before.seen)
        self.interfaces.commands.journal = journal
        return before

    def _report_predecessor(self, before: Predecessor) -> None:
        """Say ``interrupted`` of every command the previous process died holding."""
        receipts = interruptions(before.unfinished, self.name)
        for receipt in receipts:
            self.interfaces.receipt(receipt)
        if receipts:
            listed = ", ".join(f"`{held.text}` (seq {held.seq}, "
                               f"{'taken: it may have begun' if held.taken else 'not taken'})"
                               for held in before.unfinished)
            self.warn(f"{self.name}: the previous process ended holding {len(receipts)} "
                      f"command(s), interrupted, none run again: {listed}")

    def _connect_robot(self) -> None:
        """The connector thread: retry while the HAL is not there; any other failure is final."""
        try:
            from walkman.control.kinematics import Kinematics
            from walkman.hal.protocol import state_interval
            from walkman.hal.robot import Robot

            while self.robot is None:
                if self.quit_requested:
                    return
                try:
                    # In lockstep every round is read: the one the robot waits at must come.
                    self.robot = Robot(self.prefix,
                                       robot=str(self.config.get("robot_name", "walkman")),
                                       nameclient=self.nameclient, connect_timeout=3600,
                                       state_interval=0.0 if self.lockstep else
                                       state_interval(self.thread.thread_period),
                                       realtime_readers=self.lockstep is None,
                                       lockstep=self.lockstep is not None)
                except NetworkError as exc:
                    log.info("%s: HAL not reachable yet (%s)", self.name, exc)
                    time.sleep(CONNECT_RETRY)
            self.kinematics = Kinematics(self.config.get("urdf_path") or None)
        except HalProtocolError as exc:  # the HAL answered, but not as this module needs
            self._cannot_start(f"the HAL does not fit this module: {exc}")
            return
        except Exception as exc:  # a bug: seen with its traceback; starting would drive blind
            self._cannot_start(f"connecting to the robot failed: {type(exc).__name__}: {exc}",
                               exc_info=True)
            return
        thread = self.thread
        if isinstance(thread, ControlThread):
            thread.robot, thread.kinematics = self.robot, self.kinematics
            thread.clock = self.lockstep.now if self.lockstep else self.robot.clock.now
        self.robot_ready.set()
        self.wake.set()

    def _cannot_start(self, reason: str, exc_info: bool = False) -> None:
        # Said before it is set: whoever sees robot_failure finds the warning already out.
        self.warn(f"{self.name}: {reason}; the module cannot start", exc_info=exc_info)
        self.robot_failure = reason
        self.wake.set()  # a start waiting for the robot is refused now

    # -- hooks, run by the control thread ---------------------------------------------------

    def _robot_ready_for_init(self) -> bool:
        """Before ``custom_init``: the HAL is there, and a ControlThread's first state too."""
        if not self.robot_ready.wait(timeout=0):
            return False
        if isinstance(self.thread, ControlThread) and self.robot is not None:
            self.robot.wait_until_ready(5.0)
        return True

    def robot_alive(self) -> bool:
        """False (and said once) while a ControlThread's HAL is silent."""
        robot = self.robot
        if robot is None or not getattr(self.module_class, "needs_robot", False):
            return True
        alive = robot.connected
        if alive != self._robot_alive:
            self._robot_alive = alive
            if alive:
                self.warn(f"{self.name}: the robot (HAL) is back; running again")
                self.interfaces.set_status(self._status_before_loss or "running")
            else:
                self._status_before_loss = self.interfaces.state
                self.warn(f"{self.name}: lost the robot (HAL silent for "
                          f"{robot.state_age:.1f} s); control paused until it is back")
                self.interfaces.set_status("waiting_hal")
            self._on_status_change()
        return alive

    def fail_stop(self) -> None:
        """After run() raised (control thread): stop, unless the pilot stopped it meanwhile."""
        if self.lifecycle.fail_stop():
            self.wake.set()

    def warn(self, text: str, exc_info: bool = False) -> None:
        self.lifecycle.warn(text, exc_info=exc_info)

    # -- switch commands (watchdog) ----------------------------------------------------------------

    def switch(self, command: str) -> Optional[Outcome]:
        """Apply a pilot's switch command (watchdog thread); None if refused before any
        hook ran (told)."""
        switch = self.lifecycle.accept(command)  # refused now: told, no hook runs
        if switch is None:
            return None
        if switch == Switch.START and not self._robot_allows_start():
            self.interfaces.send_status()
            return None
        outcome = self.lifecycle.apply(switch)
        if outcome is Outcome.HUNG:
            self.warn(f"{self.name}: run() does not give control back; restarting the "
                      f"module process ({switch.value})")
            self.exit_code = EXIT_QUIT if switch == Switch.QUIT else EXIT_ESCALATED
            self.quit_requested = True
        elif self.state == State.DESTRUCTOR:
            self.quit_requested = True
        self.interfaces.send_status()
        return outcome

    def _switch_told(self, command: PilotCommand) -> None:
        """A pilot's switch, and its receipt: accepted (carried out, or a start waiting for
        the HAL) or refused with why (:mod:`walkman.gym.command_life`)."""
        before = self.state
        outcome = self.switch(command.name)
        if command.seq is None:
            return
        pending = command.name.strip().lower() == "start" and self.start_pending
        if outcome in (None, Outcome.REFUSED) and not pending:
            self.interfaces.receipt(Receipt(command.seq, CommandState.REFUSED,
                                            f"'{command.name}' is not carried out while "
                                            f"{before.value}"))
        else:
            self.interfaces.receipt(Receipt(command.seq, CommandState.ACCEPTED))

    def follow_link(self) -> None:
        """The module's link-loss policy, now (watchdog thread): the switch it makes is a
        pilot's, with its safe pause and hold; the warning says why once it took effect."""
        now = self.clock()
        verdict = self.link_loss.step(self.link.state(now), self.state, self.lifecycle.since,
                                      now)
        if verdict is None:
            return
        if verdict.switch is not None:
            log.info("%s: link-loss policy (%s): %s", self.name, self.link_loss.policy,
                     verdict.switch.value)
            if verdict.switch == Switch.STOP:
                self.start_pending = False
            outcome = self.switch(verdict.switch.value)
            if outcome is None or outcome is Outcome.REFUSED:
                return  # the lifecycle said why
        self.warn(verdict.warning)

    def request_start(self) -> None:
        """Start as soon as the robot allows, as the pilot's ``start`` would (the watchdog
        carries it out; ``stop`` or ``quit`` before then cancel it)."""
        self.start_pending = True
        self.wake.set()

    def _robot_allows_start(self) -> bool:
        """Whether ``start`` may go on now: not before the HAL, never if it cannot come."""
        if self.robot_failure is not None:
            self.start_pending = False
            self.warn(f"{self.name}: cannot start: {self.robot_failure}")
            self.lifecycle.say_state()
            return False
        if not self.robot_ready.is_set():
            # Started before the HAL: say so, and start as soon as it is there.
            self.start_pending = True
            self.interfaces.set_status("waiting_hal")
            log.info("%s: start requested; waiting for the robot (HAL) first", self.name)
            return False
        self.start_pending = False
        return True

    def watchdog(self) -> int:
        """Serve the pilot until ``quit``; returns the process exit code."""
        next_status = last_status = 0.0
        while not self.quit_requested:
            wait = STATUS_PERIOD
            if self.status_changed:  # woken too soon after the last status: until the gap
                wait = max(0.0, last_status + STATUS_MIN_GAP - time.monotonic())
            self.wake.wait(wait)
            self.wake.clear()
            for problem in self.interfaces.switch.take_rejections() + \
                    self.interfaces.commands.take_rejections():
                self.warn(f"{self.name}: {problem}")
            if self.robot is not None:  # the HAL refused some of our joints: tell the pilot
                for text in self.robot.take_hal_warnings():
                    self.warn(f"{self.name}: {text}")
            while True:
                command = self.interfaces.switch.get()
                if command is None or self.quit_requested:
                    break
                if command.name.strip().lower() in ("stop", "quit"):
                    self.start_pending = False
                self._switch_told(command)
            if self.start_pending and not self.quit_requested and \
                    (self.robot_ready.is_set() or self.robot_failure is not None):
                self.switch("start")
            if not self.quit_requested:
                self.follow_link()
            now = time.monotonic()
            if now >= next_status or \
                    (self.status_changed and now >= last_status + STATUS_MIN_GAP):
                self.status_changed = False
                self.interfaces.send_status()
                next_status, last_status = now + STATUS_PERIOD, now
            self._heartbeat()
        self.interfaces.send_status()
        return self.exit_code

    def _heartbeat(self, word: bytes = b".") -> None:
        if self.heartbeat_fd is not None:
            try:
                os.write(self.heartbeat_fd, word)
            except OSError:
                self.heartbeat_fd = None

    def say_quitting(self) -> None:
        """Tell the supervisor the quit is done and the ports are closing: closing a dozen
        ports (each unregistered from the name server) took more than the heartbeat's 5 s on
        a loaded PC, and the supervisor killed the quitting module and started a fresh one,
        stopped, that nobody had asked for (fc14 of 2026-11-28)."""
        self._heartbeat(QUITTING)

    def finish(self, code: int) -> bool:
        """End the module: a quit is told to the supervisor before the ports close, also one
        whose ``run()`` never gave control back -- that one was not told, its ports took over
        5 s to close beside a loaded suite, and the supervisor, hearing no beat, started a
        fresh module nobody would ever quit (CI of 2026-12-02).  Returns whether a thread is
        stuck in ``run()`` (the process must ``os._exit``, not wait for it)."""
        stuck = self.loop.request is not None  # the control thread never took its last hook
        if code == EXIT_QUIT:
            self.say_quitting()
        self.close()  # unregister the ports either way
        return stuck

    def close(self) -> None:
        self.loop.exit = True
        if self.lockstep is not None:
            self.lockstep.close()
        if self.robot is not None:
            self.robot.close()
        self.link.close()
        self.interfaces.close()
        if self.interfaces.commands.journal is not None:
            self.interfaces.commands.journal.close()

    def period_stats(self) -> Dict[str, float]:
        errors = sorted(abs(e) for e in self.loop.period_errors)
        if not errors:
            return {}
        schedule = getattr(self.loop, "schedule", None)
        intervals = sorted(schedule.interval_errors) if schedule else []
        return {"median_ms": errors[len(errors) // 2] * 1e3,
                "p99_ms": errors[int(len(errors) * 0.99)] * 1e3, "samples": len(errors),
                "locked": schedule.locked_ticks if schedule else 0,
                "interval_p99_ms": intervals[int(len(intervals) * 0.99)] * 1e3
                if intervals else math.nan}


def parse_args(argv: Optional[List[str]] = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="walkman-module",
                                     description="Run a GYM module (see walkman/modules/).")
    parser.add_argument("module", help="module name (gaze_control, temperature...) or pkg.mod:Class")
    parser.add_argument("--from", dest="config_file", help="configuration file (.ini)")
    parser.add_argument("--context", default="", help="configuration context (folder)")
    parser.add_argument("--name", help="port prefix (default /<module>)")
    parser.add_argument("--period", type=float, help="thread_period in ms (overrides the .ini)")
    parser.add_argument("--set", nargs=2, action="append", default=[], metavar=("KEY", "VALUE"),
                        help="set a configuration key over the .ini's (repeatable)")
    parser.add_argument("--start", action="store_true",
                        help="start on launch, as if the pilot said start (not after a restart: "
                             "a module that crashed waits for the pilot)")
    parser.add_argument("--initial", choices=["constructor", "stopped"], default="constructor",
                        help=argparse.SUPPRESS)
    parser.add_argument("--heartbeat-fd", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--no-supervisor", action="store_true",
                        help="run in this process (no restart on hang or crash)")
    parser.add_argument("--lockstep", action="store_true",
                        help="hold the robot's physics at each tick until it is handled "
                             "(walkman-hal --clock; the clock YARP_CLOCK names, default "
                             "/clock); also WALKMAN_LOCKSTEP=1")
    parser.add_argument("--verbose", action="store_true")
    return parser.parse_args(argv)


def load_config(options: argparse.Namespace) -> Dict[str, Any]:
    name = options.config_file or f"{module_name(options.module)}.ini"
    context = options.context or module_name(options.module)
    try:
        config = inifile.load(name, context, DEFAULTS)
    except inifile.IniError:
        if options.config_file:
            raise
        config = dict(DEFAULTS)
    config = inifile.override(config, options.set)
    if options.period:
        config["thread_period"] = options.period
    period = float(config["thread_period"])
    if not 1 <= period <= 1000:
        raise inifile.IniError(f"thread_period must be 1..1000 ms, got {period}")
    return config


def run_module(argv: Optional[List[str]] = None) -> int:
    options = parse_args(argv)
    # kill -USR1 (to this process or its supervisor): every thread's stack on stderr;
    # -USR2: faulthandler's, for an interpreter wedged in C (nodekit.stacks).  The
    # supervisor passes those signals on only once it has read SIGNALS_ARMED.
    stacks.on_signals()
    if options.heartbeat_fd is not None:
        try:
            os.write(options.heartbeat_fd, SIGNALS_ARMED)
        except OSError:
            pass  # no supervisor to read it: none to pass signals on
    lockstep = lockstep_wanted(options.lockstep)
    if not lockstep:  # in lockstep the robot waits for this process: no real time needed
        sys.setswitchinterval(SWITCH_INTERVAL)
        make_process_realtime()  # no thread holding the interpreter lock preempted (realtime.py)
    line = f"{time_prefix()}[%(levelname)s] %(message)s"
    logging.basicConfig(level=logging.DEBUG if options.verbose else logging.INFO, format=line,
                        stream=sys.stderr)         # a user's module's own loggers
    # Ours on handlers of their own: a module that starts a ROS node (perception) lost every
    # later line when rospy.init_node replaced the root's handlers.
    configure_logging("", options.verbose, line=line)
    try:
        config = load_config(options)
    except inifile.IniError as exc:
        log.error("%s", exc)
        return 2
    module_class = load_module_class(options.module)
    name = module_name(options.module)
    runner = ModuleRunner(name, module_class, config, prefix=options.name,
                          initial=State(options.initial), heartbeat_fd=options.heartbeat_fd,
                          lockstep=lockstep)
    import signal

    def request_quit(*_):
        runner.quit_requested = True
        runner.wake.set()
    signal.signal(signal.SIGTERM, request_quit)
    try:
        runner.start()
        if options.start and runner.state == State.CONSTRUCTOR:
            log.info("%s: starting on launch (--start)", name)
            runner.request_start()
        code = runner.watchdog()
    except KeyboardInterrupt:
        code = EXIT_QUIT
    stats = runner.period_stats()
    if stats:
        log.info("%s: loop period error median %.3f ms, p99 %.3f ms over %d ticks "
                 "(%d on the robot's states); interval error p99 %.3f ms", name,
                 stats["median_ms"], stats["p99_ms"], stats["samples"], stats["locked"],
                 stats["interval_p99_ms"])
    stuck = runner.finish(code)
    if stuck or code == EXIT_ESCALATED:
        os._exit(code)  # a thread stuck in run(): do not wait for it
    return code


if __name__ == "__main__":
    sys.exit(run_module())
