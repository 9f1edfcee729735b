"""The drc topology on simulated time (issue 65): the robot PC's roscore carries the robot's
clock, its nodes stamp with it, its modules run in lockstep; the pilot PC keeps the wall clock."""

from __future__ import annotations

import re

import pytest

from harness import dump_outputs_if_failed
from system.processes import wait_until
from system.topology import PYTHON, Topology

#: A stamp of the robot's time is seconds since the robot started (its clock starts at 1 s);
#: a wall-clock stamp is seconds since 1970.
WALL_CLOCK_SECONDS = 1.0e9


def first_secs(text: str) -> int:
    match = re.search(r"secs: (\d+)", text)
    assert match, text
    return int(match.group(1))


@pytest.mark.requires("ros")
@pytest.mark.lockstep
def test_the_robot_pcs_roscore_carries_the_robots_clock_and_its_modules_run_in_lockstep(
        tmp_path, request):
    topology = Topology("drc", tmp_path / "drc", sim_time=True)
    try:
        topology.start_name_servers()
        for name in ("hal", "ros_clock", "joint_state", "gaze_control"):
            topology.start(name)
        for name in ("hal", "ros_clock", "joint_state", "gaze_control"):
            topology.process(name).wait_for(topology.table[name].ready, 120)
        clock = topology.robot.run(["rostopic", "echo", "-n", "1", "/clock"], timeout=60)
        assert 1 <= first_secs(clock.output()) < WALL_CLOCK_SECONDS, clock.output()
        stamp = topology.robot.run(["rostopic", "echo", "-n", "1", "/joint_states/header/stamp"],
                                   timeout=60)
        assert first_secs(stamp.output()) < WALL_CLOCK_SECONDS, stamp.output()
        # A module that controls the robot joins the HAL's clock: the physics waits for it.
        hal = topology.process("hal")
        switch = topology.robot.start("switch", [PYTHON, "-m", "yarp_lite", "write",
                                                 "/test/switch:o", "/gaze_control/switch:i"],
                                      stdin=True)
        switch.send("start\n")
        switch.close_stdin()
        assert switch.wait(60) == 0, switch.output()
        wait_until(lambda: "lockstep: /gaze_control joined" in hal.output(), 60,
                   message="gaze_control in lockstep")
        # The pilot's PC is on the wall clock: no /clock there, and no /use_sim_time.
        param = topology.pilot.run(["rosparam", "get", "/use_sim_time"], timeout=30)
        assert "true" not in param.output().lower(), param.output()
    finally:
        for pc in topology.unique_pcs():
            dump_outputs_if_failed(request, pc.processes.values())
        topology.close()
