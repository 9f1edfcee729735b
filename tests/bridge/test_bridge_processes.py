"""Both bridges as real processes on loopback, with two name servers.

A GYM module on the robot's name server and a pilot on the pilot's exchange
switch, command and status through the bridge as they would on one name
server; the robot state crosses in the Table 1 codec; then everything is
killed and restarted while commands keep coming, and none is lost or run twice.
"""

from __future__ import annotations

import signal

import pytest

from bridge_harness import PYTHON, TwoPCs
from harness import Implementation, wait_until
from pilot_side import (GYM_PORTS, bridge_status, executed, exists, send, switch,
                        wait_nothing_in_flight, wait_shown)

CONFIG = """<bridge period="0.2" gather="0.4">
  <modules>
    <module name="counter" id="3"/>
    <module name="gaze_control" id="7"/>
  </modules>
  <robot_state id="20" robot="walkman" channel="tcp" rate="20"/>
</bridge>
"""


@pytest.fixture
def pcs(tmp_path, lite):
    config = tmp_path / "bridge.xml"
    config.write_text(CONFIG)
    two = TwoPCs(tmp_path, lite, config)
    yield two
    two.close()


def start_counter(pcs: TwoPCs):
    """The witness module on the robot (it logs to $COUNTER_LOG, set by ``counter_env``)."""
    return pcs.robot.start([PYTHON, "-m", "walkman.gym.supervisor", "witness",
                            "--name", "/counter"], "counter module")


def start_linked(pcs: TwoPCs, lite: Implementation):
    """Name servers, the witness module ready, both bridges linked and the module shown on
    the pilot's name server: where most tests start.  Returns the module's process."""
    pcs.start_name_servers()
    module = start_counter(pcs)
    module.wait_for("ready for the pilot", 60)
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    pcs.wait_linked()
    wait_shown(pcs, lite)
    return module


@pytest.fixture
def counter_env(pcs, tmp_path, monkeypatch):
    log = tmp_path / "executed.log"
    monkeypatch.setenv("COUNTER_LOG", str(log))
    return log


@pytest.mark.parametrize("order", ["bridges-first", "modules-first"])
def test_switch_command_and_status_cross_the_bridge(pcs, lite, counter_env, order):
    if order == "bridges-first":
        pcs.start_bridge(pcs.robot, wait=False)
        pcs.start_bridge(pcs.pilot, wait=False)
        pcs.start_name_servers()
        module = start_counter(pcs)
        pcs.wait_linked()
        wait_shown(pcs, lite)
    else:
        module = start_linked(pcs, lite)
    reader = pcs.pilot.world.tool(lite, "read", "/test/status", "/counter/status:o")
    switch(pcs, lite, "start", 2)
    sender = send(pcs, 1, 5)
    assert sender.wait(60) == 0, sender.output()
    wait_until(lambda: executed(counter_env) == [1, 2, 3, 4, 5], 20,
               message=f"commands executed (got {executed(counter_env)})")
    # The pilot reads the robot's status on its own name server, under the original name
    # ("counting", dictionary-coded as its second state: b, with the last sequence number).
    reader.wait_for(r"^\d+ b 5$", 20)
    # gaze_control is configured but not running on the robot: the pilot does not see it.
    assert not any(exists(pcs.pilot, lite, f"/gaze_control/{port}") for port in GYM_PORTS)
    status = bridge_status(pcs.pilot, lite)
    assert "(modules_shown (counter))" in status, status


def test_the_robot_state_crosses_in_the_table_1_codec(pcs, lite):
    pcs.start_name_servers()
    pcs.robot.python("-m", "walkman.hal.server", "--backend", "sim",
                     name="hal").wait_for("HAL for walkman", 60)
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    pcs.wait_linked()
    wait_until(lambda: pcs.pilot.world.run_tool(lite, "exists", "/walkman/head/stateSI:o")
               .returncode == 0, 30, message="the HAL's ports republished on the pilot side")
    reader = pcs.pilot.world.tool(lite, "read", "/test/head", "/walkman/head/stateSI:o")
    line = reader.wait_for(r"^\s*\d+(\.\d+)? [\d.]+ 2(\.0)? ", 30)
    values = [float(v) for v in line.string.split()]
    assert len(values) == 3 + 4 * 2       # seq time N q[2] qdot[2] tau[2] temperature[2]
    assert 20 < values[-1] < 90            # a plausible board temperature
    assert "(link up)" in bridge_status(pcs.pilot, lite)


def test_no_command_lost_or_run_twice_through_kills_and_restarts(pcs, lite, counter_env):
    pcs.start_name_servers()
    module = start_counter(pcs)
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    pcs.wait_linked()
    switch(pcs, lite, "start", 2)

    def progress(count: int, timeout: float = 30) -> None:
        wait_until(lambda: len(executed(counter_env)) >= count, timeout,
                   message=f"{count} commands executed (got {executed(counter_env)[-5:]})")

    assert send(pcs, 1, 10).wait(60) == 0
    progress(10)

    # The robot's bridge dies; the pilot keeps commanding; the commands wait, then run.
    pcs.kill_bridge(pcs.robot)
    assert send(pcs, 11, 20).wait(60) == 0
    wait_until(lambda: "(queued_commands 10)" in bridge_status(pcs.pilot, lite), 30,
               message="the pilot's bridge holding the 10 commands")
    assert len(executed(counter_env)) == 10
    pcs.start_bridge(pcs.robot)
    progress(20)

    # The pilot's bridge dies in the middle of a burst; the pilot insists until accepted.
    sender = send(pcs, 21, 40, interval=0.05)
    sender.wait_for("sent 25", 30)
    refusals = sum(line.startswith("not accepted") for line in sender.lines)
    pcs.kill_bridge(pcs.pilot)
    # Down until the pilot has seen a command refused; it insists while the bridge restarts.
    sender.wait_for(r"^not accepted \d+", 30, count=refusals + 1)
    pcs.start_bridge(pcs.pilot)
    assert sender.wait(90) == 0, sender.output()
    progress(40)

    # The robot's name server dies and comes back on its port: ports register again.
    pcs.robot.world.stop_server()
    assert send(pcs, 41, 45).wait(60) == 0
    pcs.robot.world.start_server()
    progress(45, timeout=60)

    # The module dies: its ports leave the pilot's name server too, as they would on one
    # name server; the pilot's commands are refused until it is back, then run.
    module.kill(signal.SIGKILL)
    wait_until(lambda: not exists(pcs.robot, lite, "/counter/command:i"), 30,
               message="the module's command port gone with it")
    wait_until(lambda: not any(exists(pcs.pilot, lite, f"/counter/{port}") for port in
                               GYM_PORTS), 30,
               message="the module's stand-ins gone from the pilot's name server")
    sender = send(pcs, 46, 50)
    sender.wait_for(r"^not accepted 46$", 30)
    start_counter(pcs).wait_for("ready for the pilot", 60)
    switch(pcs, lite, "start", 3)
    assert sender.wait(60) == 0, sender.output()
    progress(50, timeout=60)

    wait_nothing_in_flight(pcs, lite)
    assert executed(counter_env) == list(range(1, 51))


def test_a_receipt_written_while_the_robot_bridge_restarts_reaches_the_pilot(pcs, lite,
                                                                           counter_env):
    """Issue 33: four expirations of a 100-round chaos run never reached the pilot, written
    by the module while the killed robot bridge was not yet connected again to its
    ``receipt:o``.  The module's port now holds them for the bridge's return."""
    module = start_linked(pcs, lite)
    receipts = pcs.pilot.world.tool(lite, "read", "/test/receipts", "/counter/receipt:o")
    warnings = pcs.pilot.world.tool(lite, "read", "/test/warnings", "/counter/warning:o")
    switch(pcs, lite, "start", 2)
    receipts.wait_for(r"^accepted$", 30)     # ``yarp read`` prints ``2 accepted`` so

    pcs.kill_bridge(pcs.robot)
    wait_until(lambda: not exists(pcs.robot, lite, "/counter/receipt:o",
                                  "/bridge/robot/counter/receipt"), 30,
               message="the module's receipt port without its bridge reader")
    # On the robot, while no bridge reads: a switch that waited too long, refused as expired.
    written = pcs.robot.world.run_tool(lite, "write", "/test/late", "/counter/switch:i",
                                       input_text="pause 9 (age 100 valid 5)\n")
    assert written.returncode == 0, written.stdout + written.stderr
    module.wait_for(r"`pause` expired after 100 s in the queue \(valid 5 s\); not run", 20)
    pcs.start_bridge(pcs.robot)
    pcs.wait_linked()
    receipts.wait_for(r"^9 expired ", 30)
    warnings.wait_for(r"`pause` expired after 100 s in the queue", 30)
    assert receipts.lines.count("accepted") == 1     # what the old bridge took: not again


def test_a_real_yarp_pilot_and_name_server_see_no_difference(tmp_path, reference, lite,
                                                             monkeypatch):
    """Pilot side on the reference yarpserver, typed with the reference ``yarp`` tools."""
    config = tmp_path / "bridge.xml"
    config.write_text(CONFIG)
    pcs = TwoPCs(tmp_path, lite, config)
    pcs.pilot.world.server_impl = reference
    log = tmp_path / "executed.log"
    monkeypatch.setenv("COUNTER_LOG", str(log))
    try:
        start_linked(pcs, lite)
        reader = pcs.pilot.world.tool(reference, "read", "/test/status", "/counter/status:o")
        writer = pcs.pilot.world.tool(reference, "write", "/test/w", "/counter/switch:i",
                                      stdin=True)
        wait_until(lambda: exists(pcs.pilot, lite, "/test/w", "/counter/switch:i"), 30,
                   message="yarp write connected to the switch port")
        writer.send("start 2\n")
        commands = pcs.pilot.world.tool(reference, "write", "/test/c", "/counter/command:i",
                                        stdin=True)
        wait_until(lambda: exists(pcs.pilot, lite, "/test/c", "/counter/command:i"), 30,
                   message="yarp write connected to the command port")
        commands.send("(count 1) 1\n")
        commands.send("(count 2) 2\n")
        wait_until(lambda: executed(log) == [1, 2], 20, message="commands via real yarp write")
        reader.wait_for(r"^\d+ b 2$", 20)
    finally:
        pcs.close()
