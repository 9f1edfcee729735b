"""The PI's footsteps from the camera (pilot/camera_footsteps.py), on clouds its click tests
took over the DRC link (tests/control/data/, with the joint state each was taken at)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pilot.camera_footsteps import footsteps_from_camera
from pilot.link import CloudEvent
from walkman.control.kinematics import Kinematics
from walkman.head_camera import FRAME

DATA = Path(__file__).resolve().parents[1] / "control" / "data"
TAKEN = 1_800_000_000.0          # s: the clouds' stamp here


@pytest.fixture(scope="module")
def kinematics() -> Kinematics:
    return Kinematics()


def look(name: str, frame: str = FRAME):
    """A saved look: the cloud as the PI holds it (taken at :data:`TAKEN`), the posture."""
    saved = np.load(DATA / name)
    xyz = saved["xyz"]
    return (CloudEvent(len(xyz), int(TAKEN * 1e9), xyz, frame),
            np.asarray(saved["posture"], float))


def test_the_look_from_the_kerbs_top_places_footsteps(kinematics):
    cloud, posture = look("pi-look-from-the-kerb-top.npz")
    steps, problem = footsteps_from_camera(cloud, posture, kinematics, 1.0, TAKEN + 0.7)
    assert problem == "" and len(steps) >= 4, problem


def test_a_refusal_names_the_cloud_it_was_judged_on(kinematics):
    """What lies in the way, and the cloud's size and age: a pilot who sees a coarse or late
    cloud knows to click again on the next."""
    cloud, posture = look("pi-look-at-debris.npz")
    steps, problem = footsteps_from_camera(cloud, posture, kinematics, 0.6, TAKEN + 1.34)
    assert steps == []
    assert problem.startswith("no footsteps from the camera: something "), problem
    assert problem.endswith(f"(judged on a cloud of {len(cloud.xyz)} points, 1.3 s old)"), \
        problem


def test_a_cloud_from_a_clock_ahead_is_told_0_s_old(kinematics):
    cloud, posture = look("pi-look-at-debris.npz")
    _, problem = footsteps_from_camera(cloud, posture, kinematics, 0.6, TAKEN - 5.0)
    assert problem.endswith("points, 0.0 s old)"), problem


def test_without_a_posture_a_cloud_or_in_another_frame_nothing_is_placed(kinematics):
    cloud, posture = look("pi-look-at-debris.npz")
    assert footsteps_from_camera(cloud, None, kinematics, 0.6, TAKEN) == \
        ([], "the feet's posture is not known yet (no joint state from the robot)")
    assert footsteps_from_camera(None, posture, kinematics, 0.6, TAKEN)[1].startswith(
        "no point cloud from the head camera yet")
    assert footsteps_from_camera(CloudEvent(10, 0, None, FRAME), posture, kinematics, 0.6,
                                 TAKEN)[1].startswith("no point cloud from the head camera yet")
    other, _ = look("pi-look-at-debris.npz", frame="map")
    assert footsteps_from_camera(other, posture, kinematics, 0.6, TAKEN) == \
        ([], f"the cloud is in map, not {FRAME}")
