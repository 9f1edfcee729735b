"""Cartesian trajectories: quintic ends, straight lines, circles that keep their radius, SO(3)."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from walkman.control.trajectory import CartesianTrajectory

vectors = st.lists(st.floats(-2, 2), min_size=3, max_size=3).map(np.array)
rotations = vectors.map(lambda v: pin.exp3(v))


def derivative(trajectory, t, h=1e-4):
    """Numerical velocity and acceleration of the position at t."""
    p = [trajectory.at(t + k * h)[0] for k in (-1, 0, 1)]
    return (p[2] - p[0]) / (2 * h), (p[2] - 2 * p[1] + p[0]) / h ** 2


@given(vectors, rotations, vectors, rotations)
def test_linear_starts_and_ends_at_rest_on_its_poses(p0, r0, p1, r1):
    trajectory = CartesianTrajectory()
    trajectory.set_linear((p0, r0), (p1, r1), duration=2.0, t0=5.0)
    assert np.allclose(trajectory.at(5.0)[0], p0) and np.allclose(trajectory.at(5.0)[1], r0)
    assert np.allclose(trajectory.at(7.0)[0], p1) and np.allclose(trajectory.at(7.0)[1], r1,
                                                                  atol=1e-9)
    for t in (5.0 + 1e-4, 7.0 - 1e-4):
        velocity, acceleration = derivative(trajectory, t)
        assert np.allclose(velocity, 0, atol=1e-3) and np.allclose(acceleration, 0, atol=0.1)
    # on the segment, and on the SO(3) geodesic: the angle from r0 grows as s * total
    total = np.linalg.norm(pin.log3(r0.T @ r1))
    p, r = trajectory.at(6.0)
    assert np.allclose(p, (p0 + p1) / 2)
    assert np.linalg.norm(pin.log3(r0.T @ r)) == pytest.approx(total / 2, abs=1e-7)


@given(vectors, rotations, vectors, vectors.filter(lambda a: np.linalg.norm(a) > 0.1),
       st.floats(-6.3, 6.3))
def test_circular_keeps_its_radius_and_turns_by_the_angle(p0, r0, center, axis, angle):
    trajectory = CartesianTrajectory()
    trajectory.set_circular((p0, r0), center, axis, angle, duration=1.0)
    unit = axis / np.linalg.norm(axis)

    def radius(p):
        offset = p - center
        return np.linalg.norm(offset - unit * (offset @ unit))

    for t in np.linspace(0, 1, 11):
        p, r = trajectory.at(t)
        assert radius(p) == pytest.approx(radius(p0), abs=1e-9)
        assert (p - center) @ unit == pytest.approx((p0 - center) @ unit, abs=1e-9)
    p, r = trajectory.at(1.0)
    assert np.allclose(r, pin.exp3(unit * angle) @ r0)  # the grasp turns with the arc
    assert np.allclose(derivative(trajectory, 1.0 - 1e-4)[0], 0, atol=1e-3)


@given(vectors, rotations, vectors, vectors.filter(lambda a: np.linalg.norm(a) > 0.1),
       st.floats(-6.3, 6.3))
def test_a_tool_going_round_a_circle_keeps_its_orientation(p0, r0, center, axis, angle):
    """A drill cutting a circle: the point goes round as on any arc, the frame never turns."""
    turning, tool = CartesianTrajectory(), CartesianTrajectory()
    turning.set_circular((p0, r0), center, axis, angle, duration=1.0)
    tool.set_circular((p0, r0), center, axis, angle, duration=1.0, turn_orientation=False)
    for t in np.linspace(0, 1, 11):
        assert np.allclose(tool.at(t)[0], turning.at(t)[0])
        assert np.allclose(tool.at(t)[1], r0)


def test_bad_parameters_are_refused_by_name():
    trajectory = CartesianTrajectory()
    pose = (np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="duration must be positive"):
        trajectory.set_linear(pose, pose, duration=0)
    with pytest.raises(ValueError, match="goal rotation: not a rotation matrix"):
        trajectory.set_linear(pose, (np.zeros(3), 2 * np.eye(3)), duration=1)
    with pytest.raises(ValueError, match="circle axis: must not be zero"):
        trajectory.set_circular(pose, np.zeros(3), np.zeros(3), 1.0, duration=1)
    with pytest.raises(ValueError, match="start position: need 3 finite numbers"):
        trajectory.set_linear(([0, np.nan, 0], np.eye(3)), pose, duration=1)
    with pytest.raises(RuntimeError, match="no trajectory set"):
        trajectory.at(0.0)
    trajectory.set_linear(pose, pose, duration=1)
    trajectory.reset()
    assert not trajectory.active and trajectory.goal() is None
