"""rosnodes/ros_clock.py: the robot's simulated time on a real roscore's ``/clock``, read with the
real ``rostopic``, and a ROS node under ``/use_sim_time`` following it (processes: roscore,
name server, ``walkman-hal --clock``, the node)."""

from __future__ import annotations

import re
import sys

import pytest

from harness import free_port, wait_until
from system.processes import ROSCORE_READY
from system.topology import ros_environment
from yarp_lite.rpc import RpcClient

PYTHON = sys.executable
#: A rospy node started after /use_sim_time: what it reads as now, paused and stepped.
SIM_NODE = """
import rospy, sys
rospy.init_node("sim_time_reader", disable_signals=True)
print("USE_SIM_TIME", rospy.get_param("/use_sim_time"), flush=True)
for line in sys.stdin:
    print("NOW", rospy.Time.now().to_sec(), flush=True)
"""


@pytest.fixture
def robot_on_sim_time(lite_world, tmp_path):
    ros_port = free_port()
    env = {**lite_world.env, **ros_environment(tmp_path, ros_port)}
    lite_world.start(["roscore", "-p", str(ros_port)], "roscore", env=env) \
        .wait_for(ROSCORE_READY, 60)
    lite_world.start([PYTHON, "-m", "walkman.hal.server", "--scene", "robot", "--clock"],
                     "hal").wait_for("simulated time on /clock", timeout=90)
    node = lite_world.start([PYTHON, "-m", "rosnodes.ros_clock", "--use-sim-time",
                             "--period", "2"], "ros clock", env=env)
    node.wait_for("publishing /clock on ROS's /clock", timeout=60)
    return lite_world, env


def test_rostopic_echoes_the_robots_clock_and_a_sim_time_node_pauses_with_it(robot_on_sim_time):
    world, env = robot_on_sim_time
    echo = world.start(["rostopic", "echo", "-n", "1", "/clock"], "rostopic echo", env=env)
    assert echo.wait(60) == 0, echo.output()
    secs = re.search(r"secs: (\d+)\s+nsecs: +(\d+)", echo.output())
    assert secs and int(secs.group(1)) >= 1, echo.output()   # simulated time starts at 1 s

    rpc = RpcClient(target="/clock/rpc")
    # Paused before the node subscribes: the time it reads must come from the latched /clock,
    # since a paused robot publishes no new time (fc127: a node that connected after the last
    # change read 0 for ever).
    rpc.call(["pauseSimulation"])
    reader = world.start([PYTHON, "-c", SIM_NODE], "sim time node", stdin=True, env=env)
    reader.wait_for(r"^USE_SIM_TIME True", timeout=60)
    try:
        [paused_at] = rpc.call(["getSimulationTime"])
        seen = []

        def now_is(expected: float) -> bool:
            reader.send("now\n")
            match = reader.wait_for(r"^NOW (\S+)$", timeout=30, count=len(seen) + 1)
            seen.append(float(match.group(1)))
            return abs(seen[-1] - expected) < 1e-6

        wait_until(lambda: now_is(paused_at), timeout=30, message=f"ROS time at {paused_at}")
        assert rpc.call(["stepSimulationAndWait", 3]) == []
        [stepped_to] = rpc.call(["getSimulationTime"])
        wait_until(lambda: now_is(stepped_to), timeout=30, message=f"ROS time at {stepped_to}")
        assert max(seen) <= stepped_to + 1e-6, "ROS time ran past the paused robot's"
    finally:
        rpc.call(["continueSimulation"])
        rpc.close()


def test_the_node_refuses_bad_arguments_by_name(lite_world):
    for argv, named in ((["--source", "clock"], "--source 'clock': a YARP port name"),
                        (["--period", "0"], "--period 0: from 0.1 to 10000 ms")):
        proc = lite_world.start([PYTHON, "-m", "rosnodes.ros_clock", *argv], "ros clock")
        assert proc.wait(60) == 2
        assert named in proc.output(), proc.output()
