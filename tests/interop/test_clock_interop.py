"""The robot's clock against the real YARP 3.5: ``walkman-hal --clock /clock`` is a clock source
that real YARP programs follow (``YARP_CLOCK``), pause with and step with, as Gazebo's
gazebo_yarp_clock; and yarp_lite follows the real ``yarp clock``.

The C++ peer (``cpp/clock_follower.cpp``) is built against the reference YARP: its
``Time::now()`` and ``Time::delay()`` are YARP's own, and it calls ``/clock/rpc`` through a
real ``yarp::os::RpcClient``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from harness import compile_cpp, missing_reference, real_implementation
from system.processes import Proc, WaitTimeout, wait_until
from yarp_lite import time as yarp_time

FOLLOWER = Path(__file__).parent / "cpp" / "clock_follower.cpp"
PYTHON = sys.executable


@pytest.fixture
def follower_binary() -> Path:
    if real_implementation() is None:
        missing_reference()
    return compile_cpp(FOLLOWER, "clock_follower")


class Follower:
    """The C++ program on ``YARP_CLOCK``: ask it, read its answer."""

    def __init__(self, proc: Proc) -> None:
        self.proc = proc
        self.asked = 0

    def ask(self, line: str, answer: str, timeout: float = 15.0) -> str:
        self.asked += 1
        before = sum(1 for text in self.proc.lines if text.startswith(answer + " ") or
                     text == answer)
        self.proc.send(line + "\n")
        match = self.proc.wait_for(rf"^{re.escape(answer)}( |$)", timeout, count=before + 1)
        return match.string[len(answer):].strip()

    def now(self) -> float:
        return float(self.ask("now", "now"))

    def rpc(self, text: str) -> str:
        return self.ask(f"rpc /clock/rpc {text}", "reply")


def start_hal(world, *extra: str) -> Proc:
    hal = world.start([PYTHON, "-m", "walkman.hal.server", "--scene", "robot", *extra], "hal")
    hal.wait_for("HAL for walkman", timeout=90)
    return hal


def test_a_real_yarp_program_follows_pauses_and_steps_with_the_robots_clock(make_world, lite,
                                                                           follower_binary):
    world = make_world(lite)
    start_hal(world, "--clock", "/clock")
    env = {**world.env, "YARP_CLOCK": "/clock"}
    follower = Follower(world.start([str(follower_binary)], "clock follower", stdin=True,
                                    env=env))
    first = follower.proc.wait_for(r"^clock (\d) (\S+)$", timeout=30)
    assert first.group(1) == "0", "YARP_CLOCK did not select the network clock"
    assert float(first.group(2)) >= 1.0, "simulated time starts above zero"

    assert follower.rpc("pauseSimulation") == "[done]"
    step = float(follower.rpc("getStepSize"))
    assert step == pytest.approx(0.001)
    paused_at = float(follower.rpc("getSimulationTime"))
    wait_until(lambda: follower.now() == pytest.approx(paused_at, abs=1e-9), timeout=10,
               message=f"the follower's Time::now() at the paused {paused_at}")
    assert float(follower.rpc("getSimulationTime")) == paused_at, "paused, time stood still"

    follower.proc.send("delay 0.1\n")
    with pytest.raises(WaitTimeout):
        follower.proc.wait_for(r"^delayed", timeout=2.0)    # 2 s of wall time: still waiting

    assert follower.rpc("stepSimulationAndWait 50") == ""   # thrift's void reply: ()
    stepped_to = float(follower.rpc("getSimulationTime"))
    assert stepped_to - paused_at == pytest.approx(50 * step, abs=1e-9)
    wait_until(lambda: follower.now() == pytest.approx(stepped_to, abs=1e-9), timeout=10,
               message=f"the follower's Time::now() at the stepped {stepped_to}")
    assert not any(line.startswith("delayed") for line in follower.proc.lines), \
        "0.05 s of 0.1 stepped: the delay must still wait"
    assert follower.rpc("stepSimulation 1000000000").startswith(
        "[fail] \"stepSimulation: the step count must be 1 to 60000")
    assert follower.rpc("rewind 3").startswith("[fail] \"unknown ClockServer call")

    assert follower.rpc("continueSimulation") == "[done]"
    delayed = follower.proc.wait_for(r"^delayed 0.1 (\S+)$", timeout=30)
    assert float(delayed.group(1)) >= paused_at + 0.1 - 1e-9


def test_the_real_yarp_read_reads_the_clock_as_two_int32(make_world, lite, reference):
    world = make_world(lite)
    start_hal(world, "--clock", "/robot_clock", "--rtf", "max")
    reader = world.tool(reference, "read", "/reader", "/robot_clock")
    reader.wait_for(r"^\d+ \d+$", timeout=30, count=5)
    ticks = [tuple(map(int, line.split())) for line in reader.lines
             if re.fullmatch(r"\d+ \d+", line)]
    assert all(sec >= 1 and 0 <= nsec < 10**9 for sec, nsec in ticks)
    times = [sec + nsec * 1e-9 for sec, nsec in ticks]
    assert times == sorted(times) and times[-1] > times[0]


def test_yarp_lite_follows_the_real_yarp_clock_command(make_world, lite, reference,
                                                       monkeypatch):
    world = make_world(lite)
    world.apply_to_process(monkeypatch)
    world.tool(reference, "clock", "--name", "/wall_clock", "--period", "10", "--rtf", "20")
    clock = yarp_time.NetworkClock("/wall_clock").open(wait=30)
    try:
        start = clock.now()
        clock.delay(2.0)                      # 2 s at 20 times real time: 0.1 s of wall
        assert clock.now() >= start + 2.0
        assert clock.local_name.endswith("/clock:i")
    finally:
        clock.close()


def test_the_real_yarp_program_follows_yarp_lite_clock(make_world, lite, follower_binary):
    world = make_world(lite)
    world.start([PYTHON, "-m", "yarp_lite", "clock", "--name", "/lite_clock", "--period", "5",
                 "--rtf", "0.5"], "yarp-lite clock")
    follower = Follower(world.start([str(follower_binary)], "clock follower", stdin=True,
                                    env={**world.env, "YARP_CLOCK": "/lite_clock"}))
    follower.proc.wait_for(r"^clock 0 ", timeout=30)
    start = follower.now()
    follower.proc.send("delay 0.2\n")
    delayed = follower.proc.wait_for(r"^delayed 0.2 (\S+)$", timeout=30)
    assert float(delayed.group(1)) >= start + 0.2
