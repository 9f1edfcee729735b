"""Inverse kinematics on the project's URDF: < 1 mm and < 0.01 rad, or a clear failure."""

import numpy as np
import pytest

from walkman.control.ik import IkError, InverseKinematics
from walkman.control.kinematics import Kinematics

LEFT_ARM = ["LShSag", "LShLat", "LShYaw", "LElbj", "LForearmPlate", "LWrj1", "LWrj2"]
RIGHT_LEG = ["RHipLat", "RHipYaw", "RHipSag", "RKneeSag", "RAnkSag", "RAnkLat"]


@pytest.fixture(scope="module")
def ik():
    return InverseKinematics(Kinematics())


def reachable_targets(ik, frame, joints, count, seed):
    """Poses of ``frame`` at random postures of ``joints`` (middle of their ranges)."""
    rng = np.random.default_rng(seed)
    index = ik.joints_of(joints)
    home = np.clip(np.zeros(33), ik.lower, ik.upper)
    for _ in range(count):
        q = home.copy()
        span = ik.upper[index] - ik.lower[index]
        q[index] = ik.lower[index] + span * rng.uniform(0.2, 0.8, len(index))
        yield home, ik.kinematics.pose(q, frame)


@pytest.mark.parametrize("frame,joints", [("l_hand", LEFT_ARM), ("r_foot", RIGHT_LEG)])
def test_reachable_poses_are_reached_within_a_millimetre(ik, frame, joints):
    for home, (position, rotation) in reachable_targets(ik, frame, joints, 12, seed=3):
        result = ik.solve(frame, position, rotation, home, joints)
        assert result.reached, (position, result)
        p, r = ik.kinematics.pose(result.q, frame)
        assert np.linalg.norm(p - position) < 1e-3
        assert np.all(result.q >= ik.lower - 1e-12) and np.all(result.q <= ik.upper + 1e-12)
        others = np.setdiff1d(np.arange(33), ik.joints_of(joints))
        assert np.array_equal(result.q[others], home[others])  # only the chain moved


def test_tracking_a_moving_target_takes_few_iterations(ik):
    q = np.clip(np.zeros(33), ik.lower, ik.upper)
    q[ik.joints_of(LEFT_ARM)] = [0.3, 0.6, 0.0, -1.0, 0.0, 0.2, 0.0]
    position, rotation = ik.kinematics.pose(q, "l_hand")
    for step in range(20):  # 1 cm per control tick
        position = position + np.array([0.0, 0.0, 0.01])
        result = ik.solve("l_hand", position, rotation, q, LEFT_ARM)
        assert result.reached and result.iterations <= 10, result
        q = result.q


def test_unreachable_targets_fail_clearly(ik):
    home = np.clip(np.zeros(33), ik.lower, ik.upper)
    result = ik.solve("l_hand", [3.0, 0.0, 0.0], None, home, LEFT_ARM, restarts=1)
    assert not result.reached and result.position_error > 1.5
    with pytest.raises(IkError, match=r"l_hand cannot reach \[3.0, 0.0, 0.0\]: best pose is"):
        ik.solve_or_raise("l_hand", [3.0, 0.0, 0.0], None, home, LEFT_ARM)


def test_bad_requests_are_refused_by_name(ik):
    home = np.zeros(33)
    with pytest.raises(IkError, match="no frame 'l_tentacle'"):
        ik.solve("l_tentacle", [0, 0, 0], None, home)
    with pytest.raises(IkError, match="3 finite numbers"):
        ik.solve("l_hand", [0, np.nan, 0], None, home)
    with pytest.raises(IkError, match="rotation matrix"):
        ik.solve("l_hand", [0, 0, 0], np.ones((3, 3)), home)
    with pytest.raises(IkError, match="unknown joints"):
        ik.solve("l_hand", [0, 0, 0], None, home, ["LElbow"])
