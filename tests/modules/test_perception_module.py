"""The head camera as a GYM module: the pilot starts it, changes its rate, resolution and
region, pauses it, and is warned of what it refuses (processes: HAL, module, roscore)."""

from __future__ import annotations

import re
import sys

import pytest

from harness import free_port, wait_until
from system.processes import ROSCORE_READY
from system.topology import ros_environment
from tests.walkman.test_gym_hal import Pilot, start_hal

PYTHON = sys.executable
STATUSES = ["waiting", "streaming", "idle"]
#: Prints each image's size, and each camera info's size and region, one line each.
WATCH = r"""
import sys, rospy
from sensor_msgs.msg import CameraInfo, Image
rospy.init_node("watch", anonymous=True)
rospy.Subscriber("/multisense/left/image_color", Image,
                 lambda m: print(f"IMAGE {m.width}x{m.height} seq {m.header.seq}", flush=True))
rospy.Subscriber("/multisense/left/camera_info", CameraInfo,
                 lambda m: print(f"INFO {m.width}x{m.height} roi {m.roi.x_offset} "
                                 f"{m.roi.y_offset} {m.roi.width}x{m.roi.height}", flush=True))
print("WATCHING", flush=True)
rospy.spin()
"""


@pytest.fixture
def camera(lite_world, tmp_path):
    ros_port = free_port()
    env = {**lite_world.env, **ros_environment(tmp_path, ros_port), "MUJOCO_GL": "osmesa"}
    lite_world.start(["roscore", "-p", str(ros_port)], "roscore", env=env) \
        .wait_for(ROSCORE_READY, 60)
    start_hal(lite_world, "sim")
    module = lite_world.start([PYTHON, "-m", "walkman.gym.supervisor", "perception"],
                              "module perception", env=env)
    module.wait_for("ready for the pilot", timeout=90)
    watch = lite_world.start([PYTHON, "-c", WATCH], "watch", env=env)
    watch.wait_for("WATCHING", 60)
    pilot = Pilot(lite_world, "perception", STATUSES)
    yield pilot, watch, module
    pilot.close()


def images(watch) -> list:
    return re.findall(r"^IMAGE (\d+)x(\d+) seq (\d+)", watch.output(), re.M)


def test_the_pilot_starts_retargets_and_pauses_the_camera(camera, lite):
    pilot, watch, module = camera
    assert images(watch) == []                     # a GYM module: nothing before start
    pilot.send(lite, "switch", "start")
    pilot.wait_state("streaming", 60)
    wait_until(lambda: len(images(watch)) >= 2, 30, message="frames after start")
    assert images(watch)[-1][:2] == ("320", "240")
    assert pilot.data()[:3] == [2.0, 320, 240]     # 2 Hz unless the pilot says

    pilot.send(lite, "command", "set_region 80 60 160 120")
    wait_until(lambda: "INFO 320x240 roi 80 60 160x120" in watch.output(), 30,
               message="a camera info with the region")
    wait_until(lambda: images(watch)[-1][:2] == ("160", "120"), 30, message="a cropped image")
    pilot.send(lite, "command", "set_resolution 160 120")   # the region goes with the old size
    wait_until(lambda: "INFO 160x120 roi 0 0 0x0" in watch.output(), 30,
               message="the new resolution")

    pilot.send(lite, "command", "set_rate 0")
    pilot.wait_state("idle", 30)
    seen = len(images(watch))
    pilot.send(lite, "command", "set_rate 40")                 # refused: too fast
    pilot.wait_warning("a rate is 0..30 frames per second, got 40")
    pilot.send(lite, "command", "set_region 150 100 100 100")  # refused: not inside
    pilot.wait_warning("is not inside the 160x120 image")
    assert len(images(watch)) <= seen + 1                       # one may have been on its way

    pilot.send(lite, "command", "set_rate 4")
    pilot.wait_state("streaming", 30)
    wait_until(lambda: len(images(watch)) >= seen + 3, 30, message="frames at 4 Hz")
    pilot.send(lite, "switch", "pause")
    pilot.wait_state("paused", 30)
    paused_at = len(images(watch))
    for _ in range(4):                     # two seconds of the module's own statuses
        assert pilot.state() == "paused"
    assert len(images(watch)) <= paused_at + 1   # paused: no frame rendered or sent
    pilot.send(lite, "switch", "resume")
    pilot.wait_state("streaming", 30)
    wait_until(lambda: len(images(watch)) >= paused_at + 3, 30, message="frames after resume")
    # Its log goes on after rospy took the root logger's handlers: each command, the frames.
    log = module.output()
    assert re.search(r"perception: command set_rate 4(\.0)? \(seq", log), log[-2000:]
    assert "perception: first frame published (320x240)" in log, log[-2000:]
