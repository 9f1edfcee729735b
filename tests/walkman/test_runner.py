"""The GYM runner in this process, without YARP: races, failures that must be told.

The runner's watchdog role is played by the test (it calls ``switch`` from a
thread of its own), its control thread is the real one.  The module under test
waits on events the test sets, so each race is played in one chosen order,
every time; the waits are on what the runner says (status, warnings, state).
"""

from __future__ import annotations

import logging
import os
import select
import threading
import time
import types
from contextlib import contextmanager
from typing import Iterator, List, Tuple

import pytest

from harness import wait_until
from harness import ManualClock
from walkman.gym import runner as runner_module
from walkman.gym.interfaces import RecordingInterfaces
from walkman.gym.lifecycle import State
from walkman.gym.link_loss import LinkLoss
from walkman.gym.runner import QUITTING, ModuleRunner
from walkman.gym.thread import ControlThread, GenericThread
from walkman.hal.protocol import HalProtocolError, HalUsageError
from yarp_lite.errors import NetworkError

TIMEOUT = 20.0


class Scripted(GenericThread):
    """A module whose run() fails, blocks and pauses exactly when the test says."""

    statuses = ["ok"]

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.fail = threading.Event()        # run() raises once, when set
        self.block = threading.Event()       # run() waits for ``unblock`` first, when set
        self.blocked = threading.Event()
        self.unblock = threading.Event()
        self.pause_checked = threading.Event()
        self.may_pause = threading.Event()   # ready_to_pause() waits for it
        self.releases = 0

    def custom_init(self) -> bool:
        self.status_interface.set_status("ok")
        return True

    def run(self) -> None:
        if self.block.is_set():
            self.blocked.set()
            self.unblock.wait(TIMEOUT)
            self.block.clear()
        if self.fail.is_set():
            self.fail.clear()
            raise RuntimeError("deliberate failure")

    def ready_to_pause(self) -> bool:
        self.pause_checked.set()
        return self.may_pause.wait(TIMEOUT)

    def custom_release(self) -> None:
        self.releases += 1


class Harnessed(ControlThread):
    """A module that needs the robot (the connector must find the HAL first)."""

    statuses = ["ok"]

    def custom_init(self) -> bool:
        return True


@pytest.fixture
def make_runner(monkeypatch) -> Iterator:
    monkeypatch.setenv("WALKMAN_NO_RT", "1")  # no SCHED_FIFO threads inside the test process
    monkeypatch.setattr(runner_module, "HOOK_TIMEOUT", TIMEOUT)  # a busy machine is not a hang
    runners: List[ModuleRunner] = []

    def make(module_class: type, **options) -> ModuleRunner:
        runner = ModuleRunner("scripted", module_class, {"thread_period": 10},
                              interfaces=RecordingInterfaces("/scripted", module_class),
                              **options)
        runners.append(runner)
        runner.start()
        return runner

    yield make
    for runner in runners:
        runner.close()
        runner.loop.join(TIMEOUT)


def says(runner: ModuleRunner, predicate, what: str) -> None:
    interfaces = runner.interfaces
    assert interfaces.wait_for(predicate, TIMEOUT), \
        f"{what}: status {interfaces.state}, warnings {interfaces.warnings}"


def running(make_runner) -> tuple:
    runner = make_runner(Scripted)
    runner.switch("start")
    assert runner.state == State.RUNNING
    return runner, runner.thread


def in_background(target, *args) -> threading.Thread:
    thread = threading.Thread(target=target, args=args, daemon=True)
    thread.start()
    return thread


def test_a_pause_that_loses_the_race_to_a_failing_run_leaves_the_module_stopped(make_runner):
    runner, module = running(make_runner)
    pausing = in_background(runner.switch, "pause")
    assert module.pause_checked.wait(TIMEOUT)  # the pause is legal and under way
    module.fail.set()                           # ...when run() raises: the module stops
    says(runner, lambda: runner.interfaces.state == "stopped", "stopped after run() raised")
    module.may_pause.set()                      # now the pause goes on
    pausing.join(TIMEOUT)
    assert not pausing.is_alive()
    assert runner.state == State.STOPPED and runner.interfaces.state == "stopped"
    assert any("'pause' is not valid while stopped" in w for w in runner.interfaces.warnings)
    assert module.releases == 1 and not module.pause_requested
    runner.switch("start")                      # and it can be started again
    assert runner.state == State.RUNNING


def test_a_stop_racing_a_failing_run_releases_the_module_once(make_runner):
    runner, module = running(make_runner)
    module.may_pause.set()  # a safe pause at once: the stop races run() alone (waiting
    # TIMEOUT for it instead raced this test's own wait for the stop, and often won)
    module.block.set()
    module.fail.set()
    assert module.blocked.wait(TIMEOUT)  # run() is under way...
    stopping = in_background(runner.switch, "stop")
    wait_until(lambda: runner.state == State.STOPPED, TIMEOUT, message="the stop taking effect")
    module.unblock.set()  # run() raises after the pilot's stop took effect
    stopping.join(TIMEOUT)
    assert not stopping.is_alive()
    says(runner, lambda: runner.interfaces.state == "stopped", "stopped")
    assert module.releases == 1
    assert runner.exit_code == runner_module.EXIT_QUIT  # no escalation: run() gave control back


class Robot:
    """Stands for the HAL's whole-body interface; holding is what goes wrong."""

    connected = True
    round_period = 0.0   # rounds unknown: the loop runs on the wall clock
    newest_round = 0.0

    def __init__(self, hold) -> None:
        self._hold = hold

    def hold(self) -> bool:
        return self._hold()

    def read_idle(self, idle: bool) -> None:
        """Any rate will do: nothing is read (tests/walkman/test_transitions.py checks it)."""

    def take_hal_warnings(self) -> list:
        return []

    def close(self) -> None:
        """Nothing to close."""


def refuse() -> bool:
    raise HalUsageError("non-finite reference for WaistLat")


def crash() -> bool:
    raise KeyError("a bug in holding")


@pytest.mark.parametrize("hold, told", [
    (refuse, "could not hold the robot after run() raised: non-finite reference"),
    (crash, "holding the robot after run() raised failed with KeyError"),
    (lambda: False, "could not hold the robot after run() raised: the HAL does not take"),
], ids=["refused", "bug", "hal-away"])
def test_a_failed_hold_after_run_raised_is_told(make_runner, caplog, hold, told):
    runner, module = running(make_runner)
    runner.robot = Robot(hold)
    module.fail.set()
    says(runner, lambda: runner.interfaces.state == "stopped", "stopped after run() raised")
    warnings = runner.interfaces.warnings
    assert any("run() raised RuntimeError: deliberate failure" in w for w in warnings), warnings
    assert any(told in w for w in warnings), warnings
    if hold is crash:
        [record] = [r for r in caplog.records if "holding the robot" in r.getMessage()]
        assert record.exc_info is not None and record.exc_info[0] is KeyError


def test_run_raising_is_logged_with_its_traceback(make_runner, caplog):
    runner, module = running(make_runner)
    module.fail.set()
    says(runner, lambda: runner.interfaces.state == "stopped", "stopped after run() raised")
    [record] = [r for r in caplog.records if "run() raised" in r.getMessage()]
    assert record.exc_info is not None and record.exc_info[0] is RuntimeError


def connector_meets(monkeypatch, *outcomes: Exception) -> List[int]:
    """The HAL connection fails with each of ``outcomes`` in turn (then with a quit)."""
    attempts: List[int] = []

    def robot(*_args, **_kwargs):
        attempts.append(1)
        if len(attempts) <= len(outcomes):
            raise outcomes[len(attempts) - 1]
        raise AssertionError("the connector tried again after a final failure")

    monkeypatch.setattr("walkman.hal.robot.Robot", robot)
    monkeypatch.setattr(runner_module, "CONNECT_RETRY", 0.0)
    return attempts


def test_an_absent_hal_is_retried_but_a_bug_fails_the_start(make_runner, monkeypatch, caplog):
    caplog.set_level(logging.INFO, logger="walkman.gym")
    attempts = connector_meets(monkeypatch, NetworkError("no HAL answered"),
                               NetworkError("no HAL answered"), ZeroDivisionError("a bug"))
    runner = make_runner(Harnessed)
    says(runner, lambda: runner.robot_failure is not None, "the connector giving up")
    assert len(attempts) == 3 and not runner.robot_ready.is_set()
    assert sum("HAL not reachable yet" in r.getMessage() for r in caplog.records) == 2
    [bug] = [r for r in caplog.records if "ZeroDivisionError" in r.getMessage()]
    assert bug.exc_info is not None and bug.exc_info[0] is ZeroDivisionError
    assert any("connecting to the robot failed: ZeroDivisionError: a bug; the module cannot "
               "start" in w for w in runner.interfaces.warnings)
    runner.switch("start")  # refused, with the reason, instead of waiting for the HAL forever
    assert runner.state == State.CONSTRUCTOR and runner.interfaces.state == "initializing"
    assert runner.interfaces.warnings[-1].startswith("scripted: cannot start: connecting")


def test_a_hal_that_does_not_fit_fails_the_start_without_retrying(make_runner, monkeypatch):
    attempts = connector_meets(monkeypatch, HalProtocolError("the HAL does not expose joints"))
    runner = make_runner(Harnessed)
    says(runner, lambda: runner.robot_failure is not None, "the connector giving up")
    assert len(attempts) == 1
    assert "the HAL does not fit this module" in runner.interfaces.warnings[-1]


class Stander(Scripted):
    """Keeps something safe while paused (walking keeps the robot balanced on its legs)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.paused_ticks = 0
        self.ran_while_paused = threading.Event()

    def run_paused(self) -> None:
        self.paused_ticks += 1
        self.ran_while_paused.set()


def test_stop_of_a_running_module_waits_for_its_safe_pause_first(make_runner):
    runner, module = running(make_runner)
    stopping = in_background(runner.switch, "stop")
    assert module.pause_checked.wait(TIMEOUT)     # stop asks, as pause does ...
    assert runner.state == State.RUNNING and stopping.is_alive()   # ... and waits
    module.may_pause.set()
    stopping.join(TIMEOUT)
    assert runner.state == State.STOPPED and module.releases == 1
    assert not module.pause_requested             # a new start begins clean


def test_paused_modules_are_silent_unless_they_keep_something_safe(make_runner):
    quiet, quiet_module = running(make_runner)
    quiet_module.may_pause.set()
    quiet.switch("pause")
    assert quiet.state == State.PAUSED and not Scripted.runs_while_paused()
    stander = make_runner(Stander)
    stander.switch("start")
    stander.thread.may_pause.set()
    stander.switch("pause")
    assert stander.thread.ran_while_paused.wait(TIMEOUT)
    stander.switch("resume")
    ticks = stander.thread.paused_ticks
    time.sleep(0.1)
    assert stander.thread.paused_ticks <= ticks + 1   # running again: run(), not run_paused()


def test_a_lost_robot_is_told_and_its_return_too():
    """The pilot hears when the HAL goes silent and comes back (the module's clock stands
    still meanwhile: tests/walkman/test_clock.py)."""
    runner = ModuleRunner("harnessed", Harnessed, {"thread_period": 10},
                          interfaces=RecordingInterfaces("/harnessed", Harnessed))
    robot = types.SimpleNamespace(connected=True, state_age=0.0)
    runner.robot = robot
    assert runner.robot_alive()
    robot.connected, robot.state_age = False, 0.6
    assert not runner.robot_alive()
    assert runner.interfaces.state == "waiting_hal"
    robot.connected = True
    assert runner.robot_alive()
    assert "lost the robot (HAL silent for 0.6 s)" in runner.interfaces.warnings[0]
    assert "the robot (HAL) is back" in runner.interfaces.warnings[1]


def test_a_status_set_in_run_leaves_at_once_and_a_flood_of_them_is_thinned(make_runner,
                                                                          monkeypatch):
    monkeypatch.setattr(runner_module, "STATUS_PERIOD", 60.0)  # the period alone: a minute
    runner, thread = running(make_runner)
    sent: list = []
    runner.interfaces.send_status = lambda: sent.append(list(runner.interfaces.data))
    watchdog = in_background(runner.watchdog)
    try:
        wait_until(lambda: sent, TIMEOUT, message="the first status")
        thread.status_interface.set_status("ok", 1.0)            # as run() would
        wait_until(lambda: sent[-1] == [1.0], TIMEOUT, message="the changed status, now")
        before = len(sent)
        for value in range(2, 52):                                # a status every microsecond
            thread.status_interface.set_status("ok", float(value))
        wait_until(lambda: sent[-1] == [51.0], TIMEOUT, message="the newest of the flood")
        assert len(sent) - before <= 4, sent[before:]            # 50 ms apart, not 50 sends
    finally:
        runner.quit_requested = True
        runner.wake.set()
        watchdog.join(TIMEOUT)


# -- the link-loss policy (walkman.gym.link_loss): the test plays the watchdog and the bridge --

LINK_UP = {"link": "up", "silent_s": 0.2}
LINK_SILENT = {"link": "up", "silent_s": 1.6}   # the pilot's bridge unheard: down


class Pausing(Scripted):
    link_loss = LinkLoss.pause(after=5.0)


class Stopping(Scripted):
    link_loss = LinkLoss.stop(after=5.0)


@pytest.fixture
def linked(make_runner):
    """A started module whose robot bridge said the link is up; the test's clock."""
    clock = ManualClock(1000.0)

    def make(module_class: type) -> Tuple[ModuleRunner, ManualClock]:
        runner = make_runner(module_class, clock=clock)
        runner.link.feed(LINK_UP, clock())
        runner.switch("start")
        return runner, clock
    return make


def cut(runner: ModuleRunner, clock: ManualClock, then_wait: float) -> None:
    """The pilot's bridge goes silent: the robot bridge says so (every half second, as
    it does) while ``then_wait`` seconds pass."""
    for _ in range(int(then_wait / 0.5) + 1):
        runner.link.feed(LINK_SILENT, clock())
        clock.now += 0.5
    clock.now -= 0.5


def test_the_policy_pauses_as_a_pilot_would_and_leaves_the_resume_to_the_pilot(linked):
    runner, clock = linked(Pausing)
    module = runner.thread
    clock.now += 10.0                                      # running a while, link up
    cut(runner, clock, 4.5)
    runner.follow_link()                                   # 4.5 s of 5: nothing yet
    assert runner.state == State.RUNNING and not module.pause_requested
    cut(runner, clock, 0.5)
    following = in_background(runner.follow_link)
    assert module.pause_checked.wait(TIMEOUT)              # the pilot's safe pause first...
    assert runner.state == State.RUNNING and following.is_alive()
    module.may_pause.set()
    following.join(TIMEOUT)
    assert runner.state == State.PAUSED and runner.interfaces.state == "paused"
    assert runner.interfaces.warnings == \
        ["scripted: paused: no link to the pilot for 5 s (link-loss policy)"]
    cut(runner, clock, 30.0)
    runner.follow_link()
    assert len(runner.interfaces.warnings) == 1            # said once

    runner.link.feed(LINK_UP, clock())                     # the link is back...
    runner.follow_link()
    assert runner.state == State.PAUSED                    # ...the pilot decides
    assert runner.interfaces.warnings[-1] == \
        "scripted: the link to the pilot is back; the link-loss policy paused the module " \
        "30 s ago and it stays paused until the pilot resumes it"
    runner.switch("resume")
    assert runner.state == State.RUNNING and runner.interfaces.state == "ok"


def test_the_policy_stops_as_a_pilot_would(linked):
    runner, clock = linked(Stopping)
    runner.thread.may_pause.set()
    cut(runner, clock, 6.0)
    runner.follow_link()
    assert runner.state == State.STOPPED and runner.thread.releases == 1
    assert runner.interfaces.state == "stopped"
    assert runner.interfaces.warnings == \
        ["scripted: stopped: no link to the pilot for 6 s (link-loss policy)"]


def test_a_module_that_continues_is_never_switched(linked):
    runner, clock = linked(Scripted)                       # LinkLoss.CONTINUE
    cut(runner, clock, 600.0)
    runner.follow_link()
    assert runner.state == State.RUNNING and runner.interfaces.warnings == []


def test_in_the_lab_no_bridge_ever_speaks_and_nothing_is_down(make_runner):
    clock = ManualClock(1000.0)
    runner = make_runner(Pausing, clock=clock)
    runner.switch("start")
    clock.now += 3600.0
    runner.follow_link()
    assert runner.state == State.RUNNING and runner.interfaces.warnings == []
    assert runner.link.state(clock()).state == "unknown"


def test_a_robot_bridge_gone_quiet_is_a_link_down(linked):
    runner, clock = linked(Pausing)
    runner.thread.may_pause.set()
    clock.now += 2.5                                       # no status since the first
    runner.follow_link()
    assert runner.link.state(clock()).state == "down" and runner.state == State.RUNNING
    clock.now += 5.0
    runner.follow_link()
    assert runner.state == State.PAUSED
    assert runner.interfaces.warnings == \
        ["scripted: paused: no link to the pilot for 5 s (link-loss policy)"]


def test_the_watchdog_follows_the_link(linked):
    runner, clock = linked(Pausing)
    runner.thread.may_pause.set()
    cut(runner, clock, 6.0)
    watchdog = in_background(runner.watchdog)
    try:
        says(runner, lambda: "(link-loss policy)" in "".join(runner.interfaces.warnings),
             "the policy's warning")
        assert runner.state == State.PAUSED
    finally:
        runner.quit_requested = True
        runner.wake.set()
        watchdog.join(TIMEOUT)


class SlowToPause(Scripted):
    """Not at a safe pause until the test says so; says so at once when asked (as walking)."""

    def ready_to_pause(self) -> bool:
        self.pause_checked.set()
        return self.may_pause.is_set()


@contextmanager
def supervised(runner: ModuleRunner) -> Iterator:
    """The runner's heartbeat on a pipe, as the supervisor reads it; yields ``hear(n)``,
    which asserts that n beats arrive."""
    read_fd, runner.heartbeat_fd = os.pipe()

    def hear(count: int) -> None:
        for _ in range(count):
            ready, _, _ = select.select([read_fd], [], [], TIMEOUT)
            assert ready and os.read(read_fd, 1) == b"."
    try:
        yield hear
    finally:
        os.close(read_fd)
        os.close(runner.heartbeat_fd)
        runner.heartbeat_fd = None


def test_the_watchdog_beats_while_it_waits_for_a_safe_pause(make_runner):
    """A walk landing its foot is not a hung watchdog: the supervisor must not kill it."""
    runner = make_runner(SlowToPause)
    runner.switch("start")
    module = runner.thread
    with supervised(runner) as hear_beats:
        pausing = in_background(runner.switch, "pause")
        assert module.pause_checked.wait(TIMEOUT)      # the safe pause is under way...
        hear_beats(2)                                  # ...and the supervisor hears beats
        assert pausing.is_alive() and runner.state == State.RUNNING
        module.may_pause.set()
        pausing.join(TIMEOUT)
        assert runner.state == State.PAUSED


class SlowToInit(Scripted):
    """A module whose custom_init (a model to load) takes until the test lets it finish."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.initialising = threading.Event()
        self.may_finish = threading.Event()

    def custom_init(self) -> bool:
        self.initialising.set()
        self.may_finish.wait(TIMEOUT)
        return super().custom_init()


def test_the_watchdog_beats_while_a_slow_custom_init_runs(make_runner):
    """custom_init may take 30 s; the supervisor kills a module silent for 5 s.  A watchdog
    waiting for it beat nothing before, and a slow init got the module killed."""
    runner = make_runner(SlowToInit)
    module = runner.thread
    with supervised(runner) as hear_beats:
        starting = in_background(runner.switch, "start")
        assert module.initialising.wait(TIMEOUT)       # init is under way...
        hear_beats(3)                                  # ...and the supervisor hears beats
        assert starting.is_alive()
        module.may_finish.set()
        starting.join(TIMEOUT)
        assert runner.state == State.RUNNING


def test_a_quitting_runner_tells_its_supervisor_before_it_closes_its_ports(make_runner):
    runner = make_runner(Scripted)
    read_fd, runner.heartbeat_fd = os.pipe()
    try:
        runner._heartbeat()
        runner.say_quitting()
        assert os.read(read_fd, 16) == b"." + QUITTING
    finally:
        os.close(read_fd)


class HangsInRun(GenericThread):
    """run() that does not give control back until the test lets it."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.hanging, self.release = threading.Event(), threading.Event()

    def custom_init(self) -> bool:
        return True

    def run(self) -> None:
        self.hanging.set()
        self.release.wait(TIMEOUT)


def test_a_quit_that_run_ignores_is_still_told_to_the_supervisor(make_runner, monkeypatch):
    """Not told, the ports' slow closing (over 5 s on a loaded PC) read as a lost heartbeat and
    the supervisor started a fresh module that nobody would quit (CI of 2026-12-02)."""
    runner = make_runner(HangsInRun)
    module = runner.thread
    read_fd, runner.heartbeat_fd = os.pipe()
    try:
        runner.switch("start")
        assert module.hanging.wait(TIMEOUT)
        monkeypatch.setattr(runner_module, "HOOK_TIMEOUT", 0.2)  # run() holds on: a hang
        runner.switch("quit")
        assert runner.quit_requested and runner.exit_code == runner_module.EXIT_QUIT
        assert runner.finish(runner.exit_code) is True  # stuck: the process must _exit
        assert QUITTING in os.read(read_fd, 1024)
    finally:
        module.release.set()
        os.close(read_fd)


def test_a_stop_that_run_ignores_is_not_a_quit(make_runner, monkeypatch):
    """The supervisor restarts that one, stopped: no QUITTING."""
    runner = make_runner(HangsInRun)
    module = runner.thread
    read_fd, runner.heartbeat_fd = os.pipe()
    try:
        runner.switch("start")
        assert module.hanging.wait(TIMEOUT)
        monkeypatch.setattr(runner_module, "HOOK_TIMEOUT", 0.2)
        runner.switch("stop")
        assert runner.exit_code == runner_module.EXIT_ESCALATED
        runner._heartbeat()
        assert runner.finish(runner.exit_code) is True
        assert QUITTING not in os.read(read_fd, 1024)
    finally:
        module.release.set()
        os.close(read_fd)


def test_each_numbered_switch_is_receipted_accepted_or_refused_with_why(make_runner):
    from walkman.gym.command_life import CommandState, Receipt
    from yarp_lite.bottle_text import parse

    runner = make_runner(Scripted)
    watchdog = in_background(runner.watchdog)
    try:
        runner.interfaces.switch.feed(parse("start 11"))
        says(runner, lambda: runner.interfaces.receipts, "the start's receipt")
        runner.interfaces.switch.feed(parse("resume 12"))   # illegal while running
        runner.interfaces.switch.feed(parse("pause"))       # no number: no receipt
        says(runner, lambda: len(runner.interfaces.receipts) == 2, "the resume's receipt")
        assert runner.interfaces.receipts == [
            Receipt(11, CommandState.ACCEPTED),
            Receipt(12, CommandState.REFUSED, "'resume' is not carried out while running")]
    finally:
        runner.quit_requested = True
        runner.wake.set()
        watchdog.join(TIMEOUT)


def test_a_start_requested_on_launch_is_carried_out_by_the_watchdog(make_runner):
    """``walkman-module NAME --start``: the module starts as if the pilot said so."""
    runner = make_runner(Scripted)
    assert runner.state == State.CONSTRUCTOR
    watchdog = in_background(runner.watchdog)
    runner.request_start()
    wait_until(lambda: runner.state == State.RUNNING, TIMEOUT, message="started on launch")
    says(runner, lambda: runner.interfaces.state == "ok", "the module's own status")
    runner.quit_requested = True
    runner.wake.set()
    watchdog.join(TIMEOUT)


def test_the_command_line_sets_keys_over_the_ini_and_bad_values_are_named():
    options = runner_module.parse_args(["perception", "--start", "--set", "rate", "1",
                                        "--set", "robot_name", "other"])
    config = runner_module.load_config(options)
    assert options.start
    assert config["rate"] == 1 and config["robot_name"] == "other"
    assert config["cloud_step"] == 8            # the rest from perception.ini
    bad = runner_module.parse_args(["perception", "--set", "rate", '"unclosed'])
    with pytest.raises(runner_module.inifile.IniError, match=r"--set rate '\"unclosed': no value"):
        runner_module.load_config(bad)
    empty = runner_module.parse_args(["perception", "--set", " ", "1"])
    with pytest.raises(runner_module.inifile.IniError, match=r"the key is empty"):
        runner_module.load_config(empty)
