"""The Pilot Interface under Xvfb, clicked by QTest, on the drc topology (loopback).

The robot PC runs the HAL (MuJoCo, valve station), gaze_control, drc_valve,
perception and joint state; the pilot PC its bridge, gateway and joint state.  A
PI process (tests/system/pi_driver.py) starts gaze_control and steps the valve
task by clicks; it is SIGKILLed mid-task and a new PI finishes the task, cancels a
timed turn with a second click, and checks that the 3-D view draws the robot and
the cloud.  The valve is read in the MuJoCo scene.  Screenshots are kept in the
test's folder (and copied to ``out/pilot-gui`` for a look).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import subprocess
import sys

import pytest

from system.processes import Proc
from system.topology import REPO, Component, Topology
from tests.system.conftest import dump_outputs_if_failed

PYTHON = sys.executable
DRIVER = REPO / "tests" / "system" / "pi_driver.py"
pytestmark = pytest.mark.requires("xvfb")


@pytest.fixture
def display():
    """A private Xvfb display (its number chosen by Xvfb itself)."""
    read, write = os.pipe()
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1400x900x24",
                               "-nolisten", "tcp"], pass_fds=(write,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()
    try:
        assert number.isdigit(), "Xvfb did not say its display number"
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(10)


@pytest.fixture
def drc(tmp_path, request):
    valve = Component("drc_valve", "robot", (PYTHON, "-m", "walkman.gym.supervisor",
                                             "drc_valve"), r"ready for the pilot")
    topology = Topology("drc", tmp_path / "drc", extra=[valve])
    topology.start_name_servers()
    topology.start_all([n for n in topology.table if n != "rosbag"])
    del topology.table["rosbag"]
    try:
        topology.wait_ready(180)
        yield topology
    finally:
        for pc in topology.unique_pcs():
            dump_outputs_if_failed(request, pc.processes.values())
        topology.close()


def valve_angle(topology) -> float:
    out = topology.robot.run([PYTHON, "-m", "tests.modules.scene", "valve"], timeout=60).output()
    words = out.split()
    return float(words[words.index("valve") + 1])


def start_pi(topology, display: str, phase: str, out) -> Proc:
    topology.pilot.extra_env["DISPLAY"] = display
    return topology.pilot.start(f"pi_{phase}", [PYTHON, str(DRIVER), phase, str(out)])


def test_the_valve_task_by_clicks_with_a_pi_crash_and_a_cancelled_timed_turn(
        drc, display, tmp_path):
    out = tmp_path / "screens"
    out.mkdir()
    try:
        first = start_pi(drc, display, "first", out)
        first.wait_for(r"UP after", 90)
        first.wait_for(r"STEP gaze_control started", 60)
        first.wait_for(r"STEP illegal buttons disabled", 60)
        first.wait_for(r"READY to be killed|FAIL", 180)
        assert "FAIL" not in first.output(), first.output()
        before = valve_angle(drc)
        first.kill(signal.SIGKILL)                  # the paper's one GUI crash at the DRC

        second = start_pi(drc, display, "second", out)
        second.wait_for(r"DONE|FAIL", 400)
        assert "FAIL" not in second.output(), second.output()
    finally:
        shutil.copytree(out, REPO / "out" / "pilot-gui", dirs_exist_ok=True)
    turned = valve_angle(drc) - before
    assert math.isclose(turned, math.pi / 2, rel_tol=0.15), turned
    # The cancelled turn never left the gateway: one turn reached the module.
    gateway = drc.process("gateway").output()
    sent_turns = re.findall(r"sent to /drc_valve/command:i: \(turn ", gateway)
    assert len(sent_turns) == 1, gateway[-3000:]
    assert "cancelled" in gateway
    # Every command is attributed to the PI that sent it.
    assert "(from pi_test_first)" in gateway and "(from pi_test_second)" in gateway
    pixels = re.search(r"PIXELS all (\d+) without_robot (\d+) without_cloud (\d+)",
                       second.output())
    assert pixels, second.output()
