"""What a switch does, the same under both drivers of walkman.gym.transitions.Lifecycle.

Every test runs twice: under the process runner (its real control thread, the
test playing the watchdog, no YARP) and under the offline runner (simulated
time).  The expectations are the runner's, which is what runs on the robot; the
offline runner used to run the pause and release hooks before the state
changed, left "paused" standing after a resume, never held the robot on stop,
raised out of a hook or a missed safe pause, and said less when a start failed.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator, List, Tuple

import pytest

from harness import wait_until

from walkman.gym import runner as runner_module
from walkman.gym import transitions
from walkman.gym.interfaces import RecordingInterfaces
from walkman.gym.lifecycle import State
from walkman.gym.offline import OfflineWorld
from walkman.gym.runner import ModuleRunner
from walkman.gym.thread import ControlThread
from walkman.hal.sim import SimBackend

TIMEOUT = 20.0


class Probe(ControlThread):
    """Says "ok" once started and never again: what a status looks like after a resume is
    the lifecycle's doing.  Logs each hook with the lifecycle state and status it meets."""

    statuses = ["ok"]
    needs_robot = False  # the runner needs no HAL; offline it has the simulated robot anyway

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.lifecycle_state: Callable[[], State] = lambda: State.CONSTRUCTOR
        self.hooks: List[Tuple[str, State, str]] = []
        self.init_succeeds = True
        self.resume_raises = False
        self.safe_to_pause = True

    def _log(self, hook: str) -> None:
        self.hooks.append((hook, self.lifecycle_state(), self.status_interface.status))

    def custom_init(self) -> bool:
        self._log("init")
        if self.init_succeeds:
            self.status_interface.set_status("ok")
        return self.init_succeeds

    def ready_to_pause(self) -> bool:
        return self.safe_to_pause

    def custom_pause(self) -> bool:
        self._log("pause")
        return True

    def custom_resume(self) -> bool:
        self._log("resume")
        if self.resume_raises:
            raise RuntimeError("a step still in the air")
        return True

    def custom_release(self) -> None:
        self._log("release")


class Driven:
    """One Probe under one driver: ``switch``, ``state``, what the pilot hears, the holds."""

    def __init__(self, switch: Callable[[str], object], state: Callable[[], State],
                 interfaces: RecordingInterfaces, module: Probe) -> None:
        self.switch, self.state = switch, state
        self.interfaces, self.module = interfaces, module
        self.holds: List[str] = []
        module.lifecycle_state = state


class HeldRobot:
    """The runner's robot: counts the holds (the offline one is the simulated robot)."""

    connected = True
    round_period = 0.0   # rounds unknown: the loop runs on the wall clock
    newest_round = 0.0

    def __init__(self, holds: List[str]) -> None:
        self.holds = holds
        self.reading_idle: List[bool] = []      # what the runner told, in order

    def hold(self) -> bool:
        self.holds.append("held")
        return True

    def wait_until_ready(self, timeout: float) -> bool:
        return True

    def take_hal_warnings(self) -> list:
        return []

    def read_idle(self, idle: bool) -> None:
        self.reading_idle.append(idle)

    def close(self) -> None:
        """Nothing to close."""


@contextmanager
def run_by_a_runner(monkeypatch) -> Iterator[Driven]:
    """A Probe under a module runner, its robot a :class:`HeldRobot` (``robot``)."""
    monkeypatch.setenv("WALKMAN_NO_RT", "1")
    monkeypatch.setattr(runner_module, "HOOK_TIMEOUT", TIMEOUT)  # a busy box is no hang
    runner = ModuleRunner("probe", Probe, {"thread_period": 10},
                          interfaces=RecordingInterfaces("/probe", Probe))
    it = Driven(runner.switch, lambda: runner.state, runner.interfaces, runner.thread)
    runner.robot = it.robot = HeldRobot(it.holds)
    runner.start()
    try:
        yield it
    finally:
        runner.close()
        runner.loop.join(TIMEOUT)


@pytest.fixture(params=["runner", "offline"])
def driven(request, monkeypatch) -> Iterator[Driven]:
    if request.param == "runner":
        with run_by_a_runner(monkeypatch) as it:
            yield it
    else:
        world = OfflineWorld(SimBackend(scene=False))
        module = world.add(Probe, "probe")
        it = Driven(module.switch, lambda: module.lifecycle.state, module.interfaces,
                    module.thread)
        hold = module.robot.hold
        module.robot.hold = lambda: bool(it.holds.append("held")) or hold()
        yield it


def warned(driven: Driven, text: str) -> bool:
    return any(text in warning for warning in driven.interfaces.warnings)


def test_each_switch_runs_its_hook_in_the_runners_order_with_its_status_words(driven):
    assert driven.interfaces.state == "initializing"
    for command in ("start", "pause", "resume", "stop", "start", "quit"):
        driven.switch(command)
    assert driven.state() == State.DESTRUCTOR
    assert driven.module.hooks == [
        ("init", State.CONSTRUCTOR, "initializing"),
        ("pause", State.PAUSED, "ok"),            # run() no longer called: already paused
        ("resume", State.PAUSED, "paused"),
        ("release", State.STOPPED, "ok"),         # the resume said "ok" again
        ("init", State.STOPPED, "stopped"),
        ("release", State.DESTRUCTOR, "ok"),
    ]
    assert driven.interfaces.history == ["ok", "paused", "ok", "stopped", "ok", "destructor"]
    assert driven.holds == ["held", "held"]      # custom_init undone on stop and quit: held
    assert not driven.interfaces.warnings


def test_the_robot_is_read_slowly_whenever_the_module_does_not_control_it(monkeypatch):
    """Idle modules decoding the robot's 500-Hz state took a third of a core in a lab
    topology: the runner tells its robot each change between controlling and not (the
    offline world's robot is read straight from the simulator: nothing to slow)."""
    with run_by_a_runner(monkeypatch) as driven:
        robot = driven.robot
        wait_until(lambda: robot.reading_idle == [True], TIMEOUT,
                   message=f"constructor: read slowly ({robot.reading_idle})")
        for command, idle in (("start", False), ("pause", True), ("resume", False),
                              ("stop", True), ("start", False)):
            told = len(robot.reading_idle)
            driven.switch(command)
            wait_until(lambda: len(robot.reading_idle) > told, TIMEOUT,
                       message=f"{command}: told ({robot.reading_idle})")
            assert robot.reading_idle[told:] == [idle], (command, robot.reading_idle)


def test_a_stop_of_a_module_never_started_releases_and_holds_nothing(driven):
    driven.switch("quit")
    assert driven.state() == State.DESTRUCTOR and driven.interfaces.state == "destructor"
    assert driven.module.hooks == [] and driven.holds == []


def test_an_illegal_switch_is_told_and_runs_no_hook(driven):
    driven.switch("resume")
    assert warned(driven, "probe: 'resume' is not valid while constructor (allowed: start, quit)")
    assert driven.state() == State.CONSTRUCTOR and driven.module.hooks == []


def test_a_failed_start_is_told_and_the_status_word_stays(driven):
    driven.module.init_succeeds = False
    driven.switch("start")
    assert driven.state() == State.CONSTRUCTOR and driven.interfaces.state == "initializing"
    assert warned(driven, "probe: custom_init() failed, the module stays constructor")


def test_a_hook_that_raises_is_told_and_the_module_stays_paused(driven):
    driven.switch("start")
    driven.switch("pause")
    driven.module.resume_raises = True
    driven.switch("resume")
    assert driven.state() == State.PAUSED and driven.interfaces.state == "paused"
    assert warned(driven, "probe: custom_resume() raised RuntimeError: a step still in the air")
    assert warned(driven, "probe: custom_resume() failed, staying paused")
    driven.module.resume_raises = False
    driven.switch("resume")                       # the next try goes through
    assert driven.state() == State.RUNNING and driven.interfaces.state == "ok"


def test_no_safe_pause_in_time_is_told_and_the_module_pauses_anyway(driven, monkeypatch):
    monkeypatch.setattr(transitions, "PAUSE_GRACE", 0.3)
    driven.switch("start")
    driven.module.safe_to_pause = False
    driven.switch("pause")
    assert warned(driven, "probe: no safe pause within 0.3 s; pausing now")
    assert driven.state() == State.PAUSED and driven.interfaces.state == "paused"
    assert driven.module.pause_requested          # still asked until it resumes or stops
    driven.switch("stop")
    assert driven.state() == State.STOPPED and not driven.module.pause_requested
