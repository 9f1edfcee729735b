"""``walkman-hal --clock``: the simulated robot's time on YARP's clock wire, followed by yarp_lite
(the real YARP's side is tests/interop/test_clock_interop.py)."""

from __future__ import annotations

import re
import sys

import pytest

from system.processes import wait_until
from walkman.hal.clock_server import EPOCH
from yarp_lite import time as yarp_time
from yarp_lite.bottle import Vocab
from yarp_lite.rpc import RpcClient

PYTHON = sys.executable


def start_hal(world, *extra: str):
    hal = world.start([PYTHON, "-m", "walkman.hal.server", "--scene", "robot", *extra], "hal")
    hal.wait_for("HAL for walkman", timeout=90)
    return hal


def test_yarp_lite_follows_pauses_and_steps_with_the_hals_clock(lite_world):
    hal = start_hal(lite_world, "--clock", "--rtf", "max")
    hal.wait_for(r"simulated time on /clock \(ClockServer on /clock/rpc\), 1 ms steps, from 1 s")
    clock = yarp_time.NetworkClock("/clock").open(wait=30)
    rpc = RpcClient(target="/clock/rpc")
    try:
        assert clock.now() >= EPOCH
        assert rpc.call(["pauseSimulation"]) == [Vocab("done")]
        [paused_at] = rpc.call(["getSimulationTime"])
        # equal to the nanosecond a tick carries (a step off would be a millisecond)
        at = lambda t: abs(clock.now() - t) < 1e-9  # noqa: E731
        wait_until(lambda: at(paused_at), timeout=10, message="the last tick")
        assert rpc.call(["stepSimulationAndWait", 250]) == []
        [stepped_to] = rpc.call(["getSimulationTime"])
        assert stepped_to - paused_at == pytest.approx(0.25, abs=1e-9)
        wait_until(lambda: at(stepped_to), timeout=10, message="the stepped tick")
        assert rpc.call(["resetSimulationTime"]) == [Vocab("done")]
        wait_until(lambda: at(EPOCH), timeout=10, message="the reset tick")
        assert rpc.call(["continueSimulation"]) == [Vocab("done")]
        clock.delay(0.5)                  # as fast as the machine goes: it does go
        assert clock.now() >= EPOCH + 0.5
    finally:
        rpc.close()
        clock.close()
    assert hal.interrupt() == 0           # Ctrl-C: the HAL stops and says how it ran
    assert re.search(r"HAL stopping: .*'real_time_factor'.*'simulated_time'", hal.output())


def test_hal_refuses_a_bad_clock_name_or_rtf_by_name(lite_world):
    for argv, named in ((["--clock", "clock"], "--clock 'clock': a YARP port name starts"),
                        (["--rtf", "0"], "--rtf takes a factor above 0 or 'max', not '0'"),
                        (["--rtf", "fast"], "--rtf takes a factor above 0 or 'max'")):
        proc = lite_world.start([PYTHON, "-m", "walkman.hal.server", *argv], "hal")
        assert proc.wait(60) == 2
        assert named in proc.output(), proc.output()
