"""The GYM runner in this process, without YARP: races, failures that must be told.

The runner's watchdog role is played by the test (it calls ``switch`` from a
thread of its own), its control thread is the real one.  The module under test
waits on events the test sets, so each race is played in one chosen order,
every time; the waits are on what the runner says (status, warnings, state).
"""

from __future__ import annotations

import logging
import threading
import time
import types
from typing import Iterator, List

import pytest

from harness import wait_until
from walkman.gym import runner as runner_module
from walkman.gym.interfaces import RecordingInterfaces
from walkman.gym.lifecycle import State
from walkman.gym.runner import ModuleRunner
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

    def make(module_class: type) -> ModuleRunner:
        runner = ModuleRunner("scripted", module_class, {"thread_period": 10},
                              interfaces=RecordingInterfaces("/scripted", module_class))
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
