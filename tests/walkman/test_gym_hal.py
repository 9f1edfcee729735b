"""Name server, HAL and GYM modules as real processes, started in any order.

The "done when" of the walkman core issue: a name server, ``walkman-hal``
(sim and ethercat) and ``walkman-module gaze_control`` in any order; the
pilot sends ``start`` and a gaze command with ``yarp write`` (real YARP and
yarp-lite), the head moves in the simulator and the status changes; the same
module works when the HAL groups joints differently; stop/quit win over a
module that hangs or throws; bad input is refused without harm.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from typing import List, Optional, Tuple

import numpy as np
import pytest

from harness import Proc, YarpWorld, missing_reference, wait_until
from walkman.gym.command_life import Receipt, decode_receipt
from walkman.gym.inbox_journal import journal_path
from walkman.gym.interfaces import decode_status
from walkman.model import MODELS_DIR
from yarp_lite import network
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient

PYTHON = sys.executable
GAZE_STATUSES = ["ready", "moving", "tracking", "unreachable"]


class Pilot:
    """Listens to a module's status and warnings, and talks to its switch and command ports."""

    def __init__(self, world: YarpWorld, module: str, statuses: Optional[List[str]] = None):
        self.world = world
        self.module = module
        self.statuses = statuses
        self.status = BufferedPort(f"/test/{module}/status:i")
        self.warnings: List[str] = []
        self.warning_port = BufferedPort(f"/test/{module}/warning:i",
                                         on_read=lambda b: self.warnings.append(str(b[1])))
        self.receipts: List[Receipt] = []
        self.receipt_port = BufferedPort(f"/test/{module}/receipt:i",
                                         on_read=lambda b: self.receipts.append(
                                             decode_receipt(b)))
        client = NameClient()
        client.subscribe(f"/{module}/status:o", self.status.name)
        client.subscribe(f"/{module}/warning:o", self.warning_port.name)
        client.subscribe(f"/{module}/receipt:o", self.receipt_port.name)
        # Persistent connections are made by the name server, shortly after.
        assert self.status.wait_for_inputs(1, 20) and self.warning_port.wait_for_inputs(1, 20) \
            and self.receipt_port.wait_for_inputs(1, 20)

    def state(self, timeout: float = 2.0) -> Optional[str]:
        """The state in the next status (None: none came within ``timeout``)."""
        bottle = self.status.read(timeout=timeout)
        return decode_status(bottle, self.statuses)[1] if bottle is not None else None

    def data(self) -> list:
        bottle = self.status.read(timeout=2)
        return decode_status(bottle, self.statuses)[2] if bottle is not None else []

    def wait_state(self, state: str, timeout: float = 20.0) -> None:
        seen: List[Optional[str]] = []

        def reached() -> bool:
            seen.append(self.state())
            return seen[-1] == state

        try:
            wait_until(reached, timeout, message=f"{self.module} {state}")
        except AssertionError as exc:   # WaitTimeout: say what the module said instead
            said = [s for k, s in enumerate(seen) if k == 0 or seen[k - 1] != s]
            raise type(exc)(f"{exc}; its states meanwhile {said[-8:]}, its warnings "
                            f"{self.warnings[-5:]}") from None

    def send(self, tool, port: str, line: str) -> None:
        result = self.world.run_tool(tool, "write", f"/test/writer{int(time.time() * 1e6)}",
                                     f"/{self.module}/{port}:i", input_text=line + "\n")
        assert result.returncode == 0, result.stdout + result.stderr

    def wait_warning(self, text: str, timeout: float = 15.0) -> None:
        wait_until(lambda: any(text in w for w in self.warnings), timeout,
                   message=f"warning containing {text!r} (got {self.warnings})")

    def receipt(self, seq: int, state: str, timeout: float = 20.0) -> Receipt:
        """The first receipt ``state`` of command ``seq`` (waits for it)."""
        def said() -> Optional[Receipt]:
            return next((r for r in list(self.receipts)
                         if r.seq == seq and r.state.value == state), None)
        wait_until(lambda: said() is not None, timeout,
                   message=f"receipt {state} of seq {seq} (got {self.receipts})")
        return said()

    def close(self) -> None:
        self.status.close()
        self.warning_port.close()
        self.receipt_port.close()


def assert_quits(module: Proc, timeout: float = 90.0) -> None:
    """The module exits 0 after ``quit`` (a loaded 2-core box is slow to quit, not stuck);
    if not, it is asked for every thread's stack (``SIGUSR1``), kept in its output."""
    try:
        code = module.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        module.popen.send_signal(signal.SIGUSR1)
        try:
            module.wait_for(r"Thread 0x|Current thread 0x", 10)
        except AssertionError:
            pass
        raise AssertionError(f"{module.name} did not exit within {timeout:g} s of quit; "
                             f"its threads' stacks (SIGUSR1) are at the end of its output")
    assert code == 0, module.output()[-3000:]


def start_hal(world: YarpWorld, backend: str = "sim", *extra: str) -> Proc:
    hal = world.start([PYTHON, "-m", "walkman.hal.server", "--backend", backend, *extra],
                      f"hal-{backend}")
    hal.wait_for("HAL for walkman", timeout=60)
    return hal


def start_module(world: YarpWorld, name: str, *extra: str) -> Proc:
    return world.start([PYTHON, "-m", "walkman.gym.supervisor", name, *extra], f"module {name}")


def neck(world_robot_probe) -> np.ndarray:
    q = world_robot_probe.sense_position()
    return q[[world_robot_probe.index["NeckYawj"], world_robot_probe.index["NeckPitchj"]]]


@pytest.fixture
def probe(lite_world):
    from walkman.hal.robot import Robot

    robots = []

    def make():
        robot = Robot("/test/probe")
        assert robot.wait_until_ready(20)
        robots.append(robot)
        return robot
    yield make
    for robot in robots:
        robot.close()


@pytest.mark.parametrize("backend", ["sim", "ethercat"])
@pytest.mark.parametrize("order", ["module-first", "hal-first"])
@pytest.mark.parametrize("tool_name", ["yarp", "yarp_lite"])
def test_pilot_moves_the_head_through_yarp_write(lite_world, probe, implementations, backend,
                                                 order, tool_name):
    tool = implementations[tool_name]
    if tool is None:
        missing_reference()
    if order == "module-first":
        module = start_module(lite_world, "gaze_control")
        module.wait_for("ready for the pilot", timeout=60)
        start_hal(lite_world, backend)
    else:
        start_hal(lite_world, backend)
        module = start_module(lite_world, "gaze_control")
        module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "gaze_control", GAZE_STATUSES)
    try:
        pilot.wait_state("initializing")
        wait_until(lambda: "HAL not reachable" not in module.output() or
                   "Receiving input from /walkman" in module.output(), 30)
        pilot.send(tool, "switch", "start")
        pilot.wait_state("ready")
        robot = probe()
        before = neck(robot)
        pilot.send(tool, "command", "look_at 1.0 0.4 0.1")
        pilot.wait_state("tracking")
        # The reference has arrived; the joints follow within their servo lag.
        wait_until(lambda: neck(robot)[0] > before[0] + 0.25 and neck(robot)[1] > before[1] + 0.2,
                   5, message=f"head turned left and down from {before} (now {neck(robot)})")
        pilot.send(tool, "switch", "quit")
        assert_quits(module)
    finally:
        pilot.close()


def test_regrouping_the_hal_chains_changes_nothing_for_the_module(lite_world, probe, lite):
    start_hal(lite_world, "sim", "--config", str(MODELS_DIR / "hal_whole_body.ini"))
    assert NameClient().query("/walkman/whole_body/command:i") is not None
    assert NameClient().query("/walkman/head/command:i") is None
    module = start_module(lite_world, "gaze_control")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "gaze_control", GAZE_STATUSES)
    try:
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ready")
        robot = probe()
        assert list(robot.chains) == ["whole_body"]
        pilot.send(lite, "command", "look_at 1.0 -0.4 0.1")
        pilot.wait_state("tracking")
        wait_until(lambda: neck(robot)[0] < -0.25, 5, message="head turned right")
        # Paused, the module says so; resumed, it says again what it was doing.
        pilot.send(lite, "switch", "pause")
        pilot.wait_state("paused")
        pilot.send(lite, "switch", "resume")
        pilot.wait_state("tracking")
    finally:
        pilot.close()


def test_stop_and_quit_win_over_a_hanging_or_throwing_module(lite_world, lite):
    start_hal(lite_world, "sim")
    module = start_module(lite_world, "tests.walkman.misbehaving:Module")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "misbehaving", ["ok"])  # named after its file
    try:
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        pilot.send(lite, "command", "throw")
        pilot.wait_warning("run() raised RuntimeError: deliberate failure")
        pilot.wait_state("stopped")
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        pilot.send(lite, "command", "hang")
        module.wait_for("misbehaving: command hang", count=1)  # run() took it: hanging now
        pilot.send(lite, "switch", "stop")
        module.wait_for("starting a fresh one, stopped", timeout=30)
        pilot.wait_state("stopped", timeout=60)
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        pilot.send(lite, "command", "hang")
        module.wait_for("misbehaving: command hang", count=2)  # in the restarted process
        pilot.send(lite, "switch", "quit")
        assert_quits(module)
    finally:
        pilot.close()


def module_process(supervisor: Proc) -> int:
    """The pid of the module process a supervisor runs now."""
    found = subprocess.run(["pgrep", "-P", str(supervisor.popen.pid), "-f",
                            "walkman.gym.runner"], capture_output=True, text=True)
    pids = found.stdout.split()
    assert len(pids) == 1, f"{supervisor.name}: module processes {pids}"
    return int(pids[0])


def test_commands_a_killed_module_held_are_said_interrupted_by_its_next_process(
        lite_world, lite):
    """fc17 of 2026-11-28: a command accepted, then its module killed -9 before it ran,
    was gone without a word.  The next process now says ``interrupted`` of what the dead
    one held -- taken (it may have begun) or only queued -- and runs neither again."""
    start_hal(lite_world, "sim")
    module = start_module(lite_world, "tests.walkman.misbehaving:Module")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "misbehaving", ["ok"])
    address = NameClient().server_address()
    journal = journal_path("/misbehaving", f"{address.host}:{address.port}",
                           lite_world.env["XDG_STATE_HOME"])
    try:
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        pilot.send(lite, "command", "hang 41")
        pilot.receipt(41, "accepted")                 # run() took it: hanging now
        pilot.send(lite, "command", "(idle 1) 42")    # queued behind the hanging tick
        wait_until(lambda: "a 42 idle 1" in journal.read_text(), 20,
                   message="the second command in the module's journal")
        first = module_process(module)
        os.kill(first, signal.SIGKILL)
        module.wait_for("starting a fresh one, stopped", timeout=30)
        taken, queued = pilot.receipt(41, "interrupted"), pilot.receipt(42, "interrupted")
        assert "during the tick that took `hang`" in taken.reason, taken
        assert "before taking `idle 1`; not run" in queued.reason, queued
        pilot.wait_warning("the previous process ended holding 2 command(s), interrupted")
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        pilot.send(lite, "command", "hang 41")        # a resend of each: both dropped
        pilot.send(lite, "command", "(idle 1) 42")
        pilot.send(lite, "command", "idle 43")
        # In the port's order 41 and 42 came first: had `hang 41` run, 43 would never be taken.
        pilot.receipt(43, "accepted")
        assert [r.state.value for r in pilot.receipts if r.seq in (41, 42)] == \
            ["accepted", "interrupted", "interrupted"], pilot.receipts
        assert module_process(module) != first
    finally:
        pilot.close()


def test_bad_input_is_refused_and_the_robot_holds(lite_world, probe, lite):
    start_hal(lite_world, "sim")
    module = start_module(lite_world, "tests.walkman.misbehaving:Module")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "misbehaving", ["ok"])  # named after its file
    try:
        pilot.send(lite, "switch", "dance")
        pilot.wait_warning("'dance' is not valid while constructor")
        pilot.send(lite, "switch", "pause")
        pilot.wait_warning("'pause' is not valid while constructor")
        pilot.send(lite, "switch", "start")
        pilot.wait_state("ok")
        robot = probe()
        before = robot.sense_position()
        pilot.send(lite, "command", "not_a_number")
        pilot.wait_warning("non-finite reference for WaistLat")
        pilot.send(lite, "command", "short")
        pilot.wait_warning("move needs 33 joint positions, got 2")
        pilot.wait_state("ok")  # still running
        pilot.send(lite, "command", "far")
        wait_until(lambda: pilot.data() == [1.0], message="clamp reported")
        assert np.allclose(robot.sense_position()[:3], before[:3], atol=0.02)
        neck_yaw = robot.index["NeckYawj"]
        # The neck travels to its limit (0.6109 rad) and stops there, not at 5 rad.
        wait_until(lambda: abs(robot.sense_position()[neck_yaw] - 0.6109) < 0.02, 20,
                   message="neck yaw settles at its limit")
        time.sleep(0.5)  # under test: it stays there (no sleep-free way to see "nothing moves")
        assert robot.sense_position()[neck_yaw] == pytest.approx(0.6109, abs=0.02)
        # A malformed message straight at the HAL is refused there too.
        hal_port = NameClient().query("/walkman/head/command:i")
        network.request(hal_port, [Vocab("pos"), Bottle([1.0])], timeout=5)
        wait_until(lambda: "refused command" in lite_world.processes[1].output(), 10)
    finally:
        pilot.close()


def gaze_tracking(world: YarpWorld, tool, target: str) -> Tuple[Proc, Proc, Pilot]:
    """The sim HAL and gaze_control as processes, started and tracking ``target``; the
    caller closes the pilot."""
    hal = start_hal(world, "sim")
    module = start_module(world, "gaze_control")
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(world, "gaze_control", GAZE_STATUSES)
    try:
        pilot.send(tool, "switch", "start")
        pilot.wait_state("ready")
        pilot.send(tool, "command", f"look_at {target}")
        pilot.wait_state("tracking", timeout=30)
    except BaseException:
        pilot.close()
        raise
    return hal, module, pilot


def test_a_hal_that_disappears_and_comes_back(lite_world, lite, probe):
    hal, module, pilot = gaze_tracking(lite_world, lite, "1.0 -0.4 0.1")  # position direct
    try:
        hal.kill()
        pilot.wait_warning("lost the robot (HAL silent")
        pilot.wait_state("waiting_hal")
        start_hal(lite_world, "sim")                          # boots in position mode
        pilot.wait_warning("the robot (HAL) is back", timeout=40)
        robot = probe()
        before = neck(robot)
        pilot.send(lite, "command", "look_at 1.0 0.4 0.1")
        pilot.wait_state("tracking", timeout=30)
        # The module switched its joints to position direct again: the head moves.
        wait_until(lambda: neck(robot)[0] > before[0] + 0.25, 10,
                   message=f"head turned left after the HAL restart (from {before})")
    finally:
        pilot.close()


def test_temperature_module_reports_round_robin_and_warns(lite_world, lite, tmp_path):
    config = tmp_path / "temperature.ini"
    config.write_text("thread_period 1000\nwarning_threshold 30.05\n")
    start_hal(lite_world, "ethercat", "--thermal-speedup", "2000")
    module = start_module(lite_world, "temperature", "--from", str(config))
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "temperature", ["monitoring", "hot"])
    try:
        pilot.send(lite, "switch", "start")
        wait_until(lambda: len(pilot.data()) == 14, 20, message="seven (index, temp) pairs")
        indices = set()
        deadline = time.time() + 15
        while len(indices) < 33 and time.time() < deadline:
            indices.update(pilot.data()[0::2])
        assert indices == set(range(33))  # every joint within a few seconds
        pilot.wait_warning("limit 30.05 C", timeout=60)
    finally:
        pilot.close()


@pytest.mark.parametrize("config, period", [("hal_chains.ini", 0.002),
                                            ("hal_whole_body.ini", 0.001)])
def test_the_robot_says_when_each_state_round_arrives(lite_world, config, period, monkeypatch):
    """A round is every chain's state of one HAL step: a module's loop ticks on them.  The
    HAL streams them in one message; a robot that does not is read chain by chain."""
    from walkman.hal import protocol
    from walkman.hal.robot import Robot

    start_hal(lite_world, "sim", "--config", str(MODELS_DIR / config))
    robots = []
    try:
        whole = Robot("/test/whole")                          # as a 500 Hz module reads
        slow = Robot("/test/slow", state_interval=protocol.state_interval(0.1))  # a 10 Hz one
        robots += [whole, slow]
        with monkeypatch.context() as patch:
            patch.setattr(protocol, "whole_state_port_name", lambda robot: "/no/such/port")
            chains = Robot("/test/chains")
        robots.append(chains)
        readers = {robot.owner: [p.name for p in robot._ports if p.name.endswith("state:i")]
                   for robot in robots}
        assert readers["/test/whole"] == ["/test/whole/robot/state:i"]
        assert readers["/test/chains"] == [f"/test/chains/robot/{chain}/state:i"
                                           for chain in chains.chains]
        for robot in (whole, chains):
            # (chain by chain, a reader starved by its machine sees rounds of two steps or
            # more, and says "not known" until it keeps up again: wait for that)
            wait_until(lambda: robot.round_period > 0, 60, message=f"{robot.owner} rounds")
            # Eight chains each counted as a round would say a quarter of a millisecond.
            # Timed by the HAL's own clock, loaded or not (by arrival, a reader held up and
            # handed a burst said 0.71 ms for 1 ms: walkman.hal.rounds).
            assert robot.round_period == pytest.approx(period, rel=0.02), robot.round_period
            newest = robot.newest_round
            arrived = robot.wait_round(newest, 1.0)
            assert arrived is not None and arrived > newest
            assert robot.wait_round(time.monotonic() + 10, 0.05) is None  # none from the future
        # Read whole or chain by chain, the same joints in the same places.
        assert np.allclose(whole.sense_position(), chains.sense_position(), atol=2e-3)
        # A reader throttled to fewer states than the robot's sees its own rhythm: no rounds
        # for a loop to lock on.
        assert slow.wait_until_ready(5)
        time.sleep(1.0)
        assert slow.round_period == 0.0 and slow.newest_round > 0
    finally:
        for robot in robots:
            robot.close()


def test_a_robot_opened_without_sensors_reads_only_its_joints(lite_world):
    """``walkman-joint-state`` shows joints only: three 100-Hz sensor streams it never used
    cost it and the HAL a share of a core in every topology."""
    from walkman.hal.protocol import HalUsageError
    from walkman.hal.robot import Robot

    start_hal(lite_world, "sim")
    robots = []
    try:
        full, joints_only = Robot("/test/full"), Robot("/test/joints", sensors=False)
        robots += [full, joints_only]
        assert full.wait_until_ready(20) and joints_only.wait_until_ready(20)
        wait_until(lambda: full.sense_imu() is not None, 10, message="the IMU")
        assert {p.name for p in full._ports} > {"/test/full/robot/inertial:i"}
        assert not [p.name for p in joints_only._ports
                    if p.name.endswith(("inertial:i", "_ft:i"))]
        assert np.allclose(full.sense_position(), joints_only.sense_position(), atol=2e-3)
        with pytest.raises(HalUsageError, match="without its sensors"):
            joints_only.sense_imu()
        with pytest.raises(HalUsageError, match="without its sensors"):
            joints_only.sense_ft("l_arm_ft")
    finally:
        for robot in robots:
            robot.close()


@pytest.mark.requires("root")
def test_the_threads_between_sense_and_move_run_with_real_time_priority(lite_world, lite):
    """The loops, and the threads that hand a state to the module and its command back to
    the HAL: a port thread at normal priority made the sense -> move p99 2.6-3.2 ms.  The
    other threads (ports, rpc handlers) run real-time below them: preempted while holding
    the interpreter lock, they kept the physics waiting 35-94 ms on a busy machine."""
    from system.processes import descendants, fifo_priorities
    from walkman.realtime import (BACKGROUND_PRIORITY, CONTROL_PRIORITY,
                                  HAL_BACKGROUND_PRIORITY, HAL_PRIORITY, PATH_PRIORITY)

    hal, module, pilot = gaze_tracking(lite_world, lite, "1.0 0.4 0.1")  # streaming commands
    try:
        runner = [pid for pid in descendants(module.popen.pid)
                  if CONTROL_PRIORITY in fifo_priorities(pid)]
        assert len(runner) == 1, "no module process with a real-time control loop"
        # the HAL: physics, publisher and the command reader of the chain the module moves
        wait_until(lambda: fifo_priorities(hal.popen.pid).count(PATH_PRIORITY) >= 2, 10,
                   message=f"the HAL's threads: {fifo_priorities(hal.popen.pid)}")
        assert HAL_PRIORITY in fifo_priorities(hal.popen.pid)
        # the module: its control loop and its reader of the robot's state
        assert fifo_priorities(runner[0]).count(PATH_PRIORITY) >= 1, fifo_priorities(runner[0])
        # each port has its server thread at least; the HAL's above every module's loop
        for pid, background in ((hal.popen.pid, HAL_BACKGROUND_PRIORITY),
                                (runner[0], BACKGROUND_PRIORITY)):
            assert fifo_priorities(pid).count(background) >= 5, fifo_priorities(pid)
        assert HAL_BACKGROUND_PRIORITY > CONTROL_PRIORITY > BACKGROUND_PRIORITY
        pilot.send(lite, "switch", "quit")
        assert_quits(module)
    finally:
        pilot.close()


@pytest.mark.requires("root")
def test_a_module_that_moves_no_joint_runs_its_loop_below_every_real_time_thread(lite_world):
    """perception renders in its loop, 20-100 ms of CPU a frame.  At the control loops'
    priority a render runs on its CPU to the end, and a balancing robot's loop waiting for
    that CPU cannot preempt it (likely the 14-ms ticks before a trip on the kerb): a loop
    that moves no joint is not on the sense -> move path, and runs at normal priority; its
    port threads stay real-time."""
    from system.processes import descendants, fifo_priorities
    from walkman.realtime import BACKGROUND_PRIORITY, CONTROL_PRIORITY

    module = start_module(lite_world, "perception")
    module.wait_for("ready for the pilot", timeout=60)
    runner = [pid for pid in descendants(module.popen.pid)
              if BACKGROUND_PRIORITY in fifo_priorities(pid)]
    assert len(runner) == 1, "no real-time module process"
    assert CONTROL_PRIORITY not in fifo_priorities(runner[0]), fifo_priorities(runner[0])


def test_a_module_asked_with_sigusr1_prints_every_thread_s_stack(lite_world):
    """``kill -USR1`` to the supervisor: where each thread of the module process is (the
    watchdog waiting for the pilot, the control loop), the module running on."""
    module = start_module(lite_world, "gaze_control")
    module.wait_for("ready for the pilot", timeout=60)
    module.popen.send_signal(signal.SIGUSR1)
    module.wait_for(r"in watchdog", 20)
    assert re.search(r"File .*walkman/gym/runner\.py.* in run\b", module.output()), \
        module.output()[-3000:]
    pilot = Pilot(lite_world, "gaze_control", GAZE_STATUSES)
    try:
        assert pilot.state() is not None      # still serving the pilot
    finally:
        pilot.close()
    module.popen.send_signal(signal.SIGTERM)
    assert module.wait(30) == 0
