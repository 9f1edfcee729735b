"""``walkman-hal --clock``: the simulated robot's time on YARP's clock wire, followed by yarp_lite
(the real YARP's side is tests/interop/test_clock_interop.py)."""

from __future__ import annotations

import re
import signal
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


def test_hal_refuses_paused_without_a_clock_and_a_bad_lockstep_timeout(lite_world):
    for argv, named in ((["--paused"], "--paused needs --clock"),
                        (["--clock", "--lockstep-timeout", "0"],
                         "--lockstep-timeout: '0': between 0.01 and 3600 s"),
                        (["--clock", "--lockstep-timeout", "soon"],
                         "'soon' is not a number of seconds")):
        proc = lite_world.start([PYTHON, "-m", "walkman.hal.server", *argv], "hal")
        assert proc.wait(60) == 2
        assert named in proc.output(), proc.output()


# -- lockstep (walkman/hal/lockstep.py): this test process is the member ---------------------

class Member:
    """A module in lockstep, by hand: joins on /clock/lockstep:i, reads the whole state,
    commands a chain with the state's count, as walkman.gym.lockstep does."""

    def __init__(self) -> None:
        from yarp_lite.buffered_port import BufferedPort
        from yarp_lite.nameclient import NameClient
        from yarp_lite.port import Port

        self.port = Port().open("/member/lockstep:o")
        assert self.port.add_output("/clock/lockstep:i")
        self.state = BufferedPort("/member/state:i")
        NameClient().subscribe("/walkman/stateSI:o", self.state.name)
        assert self.state.wait_for_inputs(1, 20)
        self.command = Port().open("/member/robot/head/command:o")
        assert self.command.add_output("/walkman/head/command:i")

    def send(self, message) -> None:
        from walkman.hal import lockstep
        self.port.write(lockstep.encode(message))

    def round(self, at_least: float, timeout: float = 20.0):
        """The first state (seq, robot time) at ``at_least`` or later."""
        seen = []

        def arrived() -> bool:
            bottle = self.state.read(timeout=1.0)
            if bottle is not None:
                seen.append((int(bottle[0]), float(bottle[1])))
            return bool(seen) and seen[-1][1] >= at_least - 1e-6
        wait_until(arrived, timeout, message=f"a round at {at_least} s")
        return seen[-1]

    def close(self) -> None:
        for port in (self.port, self.state, self.command):
            port.close()


def test_the_hal_holds_its_physics_for_a_member_until_it_ticked_and_its_command_is_in(
        lite_world):
    from walkman.hal import controlboard
    from walkman.hal.lockstep import Join, Tick

    hal = start_hal(lite_world, "--clock", "--rtf", "max", "--paused")
    rpc = RpcClient(target="/clock/rpc")
    member = Member()
    try:
        seq, start = member.round(0.0)
        member.send(Join("/member", start + 0.001))   # the next round
        hal.wait_for("lockstep: /member joined")
        assert rpc.call(["continueSimulation"]) == [Vocab("done")]
        seq, held_at = member.round(start + 0.001)
        assert held_at == pytest.approx(start + 0.002, abs=1e-9)   # states every 2 ms
        # Held there: at --rtf max a free robot would be seconds further by now.
        [clock_at] = rpc.call(["getSimulationTime"])
        wait_until(lambda: member.state.read(timeout=1.0) is not None, 5,
                   message="the state repeated while held")       # the heartbeat
        assert rpc.call(["getSimulationTime"]) == [clock_at]
        refused = rpc.call(["resetSimulationTime"])
        assert refused[0] == Vocab("fail") and "modules are in lockstep" in refused[1]
        # The tick names the head: its command (seq N) must be in before the physics goes on.
        member.send(Tick("/member", seq, held_at + 0.010, ("head",)))
        assert rpc.call(["getSimulationTime"]) == [clock_at]
        member.command.write(controlboard.encode_stream("direct", [0.0, 5.0], None, seq))
        seq, next_round = member.round(held_at + 0.010)
        assert next_round == pytest.approx(held_at + 0.010, abs=1e-9)
        [later] = rpc.call(["getSimulationTime"])
        assert later == pytest.approx(clock_at + 0.010, abs=1e-9)
    finally:
        member.close()
        rpc.close()
    assert hal.interrupt() == 0
    assert "'lockstep_timeouts': 0" in hal.output()


def test_a_member_that_stalls_leaves_the_barrier_after_the_timeout_and_the_robot_goes_on(
        lite_world):
    from walkman.hal.lockstep import Join

    hal = start_hal(lite_world, "--clock", "--rtf", "max", "--lockstep-timeout", "0.5")
    member = Member()
    rpc = RpcClient(target="/clock/rpc")
    try:
        _, now = member.round(0.0)
        member.port.write(Vocab("garbage"))             # refused, logged, nothing else
        member.send(Join("/member", now + 0.1))
        hal.wait_for("HAL: lockstep: /member did not handle the round at robot time "
                     r"[0-9.]+ s within 0.5 s; it leaves the barrier, and the robot goes on "
                     r"without it \(a stalled loop\)", timeout=30)
        member.round(now + 1.0)                         # it does go on
        assert rpc.call(["resetSimulationTime"]) == [Vocab("done")]   # nobody joined now
    finally:
        member.close()
        rpc.close()
    assert "refused on the lockstep port (#1 of this burst): lockstep: unknown message" \
        in hal.output()
    assert hal.interrupt() == 0
    assert "'lockstep_timeouts': 1" in hal.output()


def test_a_module_in_lockstep_stopped_and_started_again_never_holds_the_robot_to_the_timeout(
        lite_world):
    """A stop holds the joints by a move made out of any tick; the next start's first tick
    must not name those commands (the robot would wait for them until the timeout)."""
    from tests.walkman.test_gym_hal import start_module
    from yarp_lite.bottle_text import parse
    from yarp_lite.port import Port

    hal = start_hal(lite_world, "--clock", "--rtf", "max")
    module = start_module(lite_world, "gaze_control", "--lockstep")
    module.wait_for("ready for the pilot", timeout=60)
    switch = Port().open("/test/switch:o")
    try:
        assert switch.add_output("/gaze_control/switch:i")
        for round_number, word in enumerate(("start", "stop", "start", "stop"), 1):
            assert switch.write_with_reply(parse(word), timeout=30) is not None
            if word == "start":
                hal.wait_for("lockstep: /gaze_control joined", timeout=30,
                             count=(round_number + 1) // 2)
            else:
                hal.wait_for("lockstep: /gaze_control left", timeout=30,
                             count=round_number // 2)
    finally:
        switch.close()
    module.kill(signal.SIGTERM)
    module.wait(30)
    assert hal.interrupt() == 0
    assert "'lockstep_timeouts': 0" in hal.output(), hal.output()[-2000:]
    assert "did not handle the round" not in hal.output()
