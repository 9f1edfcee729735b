"""What the robot does and the pilot sees when the link breaks.  Emulated hosts; needs root.

Issue 33's tests: through a 20 s blackout of the emulated link (``walkman-netem
blackouts``), a command whose validity ends inside it never runs and the pilot reads
why; one whose validity outlasts it runs once after the link returns; and the pilot
gateway's ``/bridge/link`` says "down" within about two seconds of the cut, and "up"
when the link is back.
"""

from __future__ import annotations

import re
import time
from contextlib import contextmanager
from typing import Sequence, Tuple

import pytest

from bridge_harness import TwoPCs
from harness import wait_until
from pilot_side import bridge_status, executed, exists, switch, wait_nothing_in_flight
from test_emulated_network import link, pcs  # noqa: F401 -- the emulated hosts, as fixtures

pytestmark = pytest.mark.requires("root")

#: The issue's blackout and validities: shorter than it, and longer.
BLACKOUT_S, SHORT_VALIDITY, LONG_VALIDITY = 20.0, 5.0, 60.0


def test_a_blackout_expires_short_lived_commands_and_runs_the_others_once(pcs, lite, link):
    link.apply("drc", loss=0)
    pcs.start_name_servers()
    pcs.start_roscore(pcs.pilot)
    module = pcs.robot.python("-m", "walkman.gym.supervisor", "witness",
                              "--name", "/counter", name="counter module")
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    module.wait_for("ready for the pilot", 60)
    pcs.wait_linked()
    gateway = pcs.pilot.python("-m", "rosnodes.gateway", "--config", str(pcs.config),
                               "--link", "bridge", name="gateway")
    gateway.wait_for("ROS topics and services up", 60)
    links = pcs.pilot.start(["rostopic", "echo", "-p", "/bridge/link/state"], "link echo")
    states = pcs.pilot.start(["rostopic", "echo", "-p", "/pilot/command_states/state"],
                             "command states")
    links.wait_for(r",up$", 30)
    switch(pcs, lite, "start", 2)
    warnings = pcs.pilot.world.tool(lite, "read", "/test/warnings", "/counter/warning:o")
    wait_until(lambda: exists(pcs.pilot, lite, "/counter/warning:o", "/test/warnings"), 30,
               message="the pilot reading the module's warnings")

    link.blackout(True)
    cut = time.monotonic()
    links.wait_for(r",down$", 10)
    noticed = time.monotonic() - cut
    print(f"/bridge/link said down {noticed:.2f} s after the cut")
    assert noticed < 4.0, f"/bridge/link said down {noticed:.1f} s after the cut"
    commands = pcs.pilot.world.run_tool(
        lite, "write", "/test/commands", "/counter/command:i",
        input_text=f"(count 3) 3 (age 0 valid {SHORT_VALIDITY})\n"
                   f"(count 4) 4 (age 0 valid {LONG_VALIDITY})\n")
    assert commands.returncode == 0, commands.stdout + commands.stderr
    # A dangerous command whose 1 s countdown ends inside the blackout: it may start only
    # within 5 s after its countdown, so it must never run.
    dangerous = pcs.pilot.start(["rostopic", "pub", "-1", "/counter/command",
                                 "walkman_msgs/Command",
                                 "{command: count, dangerous: true, countdown: 1}"], "dangerous")
    assert dangerous.wait(60) == 0, dangerous.output()
    gateway.wait_for(r"sent to /counter/command:i: count \d+", 15)
    wait_until(lambda: "(queued_commands 3)" in bridge_status(pcs.pilot, lite), 15,
               message="the pilot's bridge holding the three commands for the link")
    # A command queued behind the blackout and cancelled during it never runs.
    queued = pcs.pilot.start(["rostopic", "pub", "-1", "/counter/command",
                              "walkman_msgs/Command", "{command: count, validity: 120}"], "queued")
    assert queued.wait(60) == 0, queued.output()
    wait_until(lambda: "(queued_commands 4)" in bridge_status(pcs.pilot, lite), 15,
               message="the fourth command held for the link")
    seq = gateway.wait_for(r"sent to /counter/command:i: count (\d+)", 15, count=2).group(1)
    cancel = pcs.pilot.start(["rosservice", "call", "/counter/cancel", f"{{seq: {seq}}}"],
                             "cancel")
    assert cancel.wait(60) == 0, cancel.output()
    assert re.search(rf"ok: True\s+cancelled: \[{seq}\]", cancel.output()), cancel.output()
    # The blackout's length is the thing under test: the short validity ends inside it.
    wait_until(lambda: time.monotonic() - cut >= BLACKOUT_S, BLACKOUT_S + 5,
               message="the blackout's end")
    assert executed(pcs.log) == []
    link.blackout(False)

    wait_until(lambda: executed(pcs.log) == [4], 60,
               message=f"the long-lived command run after the link returned "
                       f"(got {executed(pcs.log)})")
    refusal = warnings.wait_for(r"`count 3` expired after (\d+) s in the queue .*not run", 30)
    assert int(refusal.group(1)) >= BLACKOUT_S - 5
    warnings.wait_for(r"`count` expired after \d+ s in the queue \(valid 6 s\); not run", 30)
    # Its life as every pilot station sees it: held for the link, written to the module's
    # port when the link came back, refused there as too old.
    states.wait_for(r",expired$", 30)
    said = [line.split(",")[-1] for line in states.lines if "," in line][1:]
    assert said == ["queued", "queued", "cancelled", "delivered", "expired"], said
    links.wait_for(r",up$", 30, count=2)
    wait_nothing_in_flight(pcs, lite)
    assert executed(pcs.log) == [4]                      # once, and never the expired one


STOP_CONFIG = """<bridge period="0.5" gather="0.4">
  <modules>
    <module name="counter" id="3"/>
    <module name="gaze_control" id="7"/>
  </modules>
  <robot_state id="20" robot="walkman" channel="tcp" rate="10"/>
  <emergency_stop id="250" robot="walkman" copies="3"/>
</bridge>
"""


def head_position(pcs, lite) -> float:
    """NeckYawj (degrees) as the HAL's control board says on the robot."""
    reply = pcs.robot.world.run_tool(lite, "rpc", "/walkman/head/rpc:i",
                                     input_text="[get] [encs]\n").stdout
    found = re.search(r"\(([-\d.e]+) [-\d.e]+\)", reply)
    assert found, reply
    return float(found.group(1))


def hal_halt(pcs, lite) -> str:
    """``on`` or ``off``: the HAL's halt, asked on the robot (``[get] halt``)."""
    reply = pcs.robot.world.run_tool(lite, "rpc", "/walkman/rpc:i",
                                     input_text="[get] halt\n").stdout
    found = re.search(r"\[ok\] \"?(on|off)\"?", reply)
    assert found, reply
    return found.group(1)


def latest_state(pcs, module: str) -> str:
    """The module's last status word, as the pilot's gateway says (latched)."""
    echo = pcs.pilot.start(["rostopic", "echo", "-n", "1", f"/{module}/status/state"],
                           f"{module} state")
    echo.wait(30)
    return echo.output()


@contextmanager
def linked_for_a_stop(tmp_path, lite, link, modules: Sequence[Tuple[str, ...]] = ()):
    """Both PCs for a stop-all: the robot's HAL and ``modules`` (each ``(name, module
    arguments...)``), the bridges linked over ``link`` at no loss, the pilot's gateway up."""
    config = tmp_path / "bridge.xml"
    config.write_text(STOP_CONFIG)
    pcs = TwoPCs(tmp_path, lite, config, link=link)
    try:
        link.apply("drc", loss=0)
        pcs.start_name_servers()
        pcs.start_roscore(pcs.pilot)
        pcs.robot.python("-m", "walkman.hal.server", "--backend", "sim",
                         name="hal").wait_for("HAL for walkman", 60)
        started = [pcs.robot.python("-m", "walkman.gym.supervisor", *arguments, name=name)
                   for name, *arguments in modules]
        for module in started:
            module.wait_for("ready for the pilot", 90)
        pcs.start_bridge(pcs.robot)
        pcs.start_bridge(pcs.pilot)
        pcs.wait_linked()
        gateway = pcs.pilot.python("-m", "rosnodes.gateway", "--config", str(config),
                                   "--link", "bridge", name="gateway")
        gateway.wait_for("ROS topics and services up", 60)
        yield pcs
    finally:
        pcs.close()


@pytest.mark.two_pcs
def test_a_stop_all_at_30_percent_loss_holds_every_module_and_the_hal(tmp_path, lite, link,
                                                                       monkeypatch):
    monkeypatch.setenv("COUNTER_LOG", str(tmp_path / "executed.log"))
    modules = [("counter", "witness", "--name", "/counter"), ("gaze_control", "gaze_control")]
    with linked_for_a_stop(tmp_path, lite, link, modules) as pcs:
        for module in ("counter", "gaze_control"):
            started = pcs.pilot.start(["rosservice", "call", f"/{module}/switch_and_wait",
                                       "{command: start, timeout: 30}"], f"start {module}")
            assert started.wait(60) == 0 and "ok: True" in started.output(), started.output()
        look = pcs.pilot.start(["rosservice", "call", "/gaze_control/send_command",
                                "{command: look_at, numbers: [1.0, 0.4, 0.1]}"], "look")
        assert look.wait(60) == 0, look.output()
        wait_until(lambda: head_position(pcs, lite) > 10, 30,
                   message=f"the head turning ({look.output()})")

        link.set_loss(30)
        stop = pcs.pilot.start(["rosservice", "call", "/pilot/stop_all"], "stop all")
        assert stop.wait(60) == 0, stop.output()
        answer = stop.output()
        assert "ok: True" in answer and "counter" in answer and "gaze_control" in answer, \
            answer
        held = head_position(pcs, lite)
        # Every module held: paused, as its status says on the pilot's side.
        link.set_loss(0)
        for module in ("counter", "gaze_control"):
            wait_until(lambda m=module: "paused" in latest_state(pcs, m), 30,
                       message=f"{module} paused")
        # The HAL holds its posture: a new look is refused, the head stays where it was.
        again = pcs.pilot.start(["rosservice", "call", "/gaze_control/send_command",
                                 "{command: look_at, numbers: [1.0, -0.4, 0.1]}"], "look again")
        assert again.wait(60) == 0
        assert hal_halt(pcs, lite) == "on"   # ("on" in the reply: its "Response" says on)
        assert head_position(pcs, lite) == pytest.approx(held, abs=0.5)
        release = pcs.pilot.start(["rosservice", "call", "/pilot/release"], "release")
        assert release.wait(60) == 0 and "ok: True" in release.output(), release.output()
        assert hal_halt(pcs, lite) == "off"


@pytest.mark.two_pcs
def test_a_stop_all_gets_through_by_udp_alone_at_30_percent_loss(tmp_path, lite, link):
    """The stop goes out on TCP and as datagram copies: with every TCP segment across the
    radio dropped, the copies alone must halt the robot, at 30 % loss."""
    with linked_for_a_stop(tmp_path, lite, link) as pcs:
        halted = lambda: hal_halt(pcs, lite) == "on"  # noqa: E731
        assert not halted()
        try:
            link.block_tcp(True)
            link.set_loss(30)
            stop = pcs.pilot.start(["rosservice", "call", "/pilot/stop_all"], "stop all")
            wait_until(halted, 30, message="the HAL halted by the stop's datagrams alone")
            assert link.tcp_dropped() > 0, \
                "nothing tried the blocked TCP path: not a test of it"
            stop.wait(90)
        finally:
            link.block_tcp(False)
            link.set_loss(0)
