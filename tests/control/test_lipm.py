"""Preview control of the cart-table: the Riccati solution, and a CoM whose ZMP follows the plan."""

import numpy as np
import pytest

from walkman.control.lipm import GRAVITY, PreviewAxis, cart_table, preview_gains, solve_dare


def test_the_riccati_solution_satisfies_its_equation():
    A, b, _ = cart_table(0.01, 0.9)
    B = b.reshape(3, 1)
    Q, R = np.diag([1.0, 0.1, 0.01]), np.array([[1e-3]])
    P = solve_dare(A, B, Q, R)
    right = A.T @ P @ A - A.T @ P @ B @ np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A) + Q
    assert np.allclose(P, right, atol=1e-8)
    assert np.all(np.linalg.eigvalsh((P + P.T) / 2) > 0)


def test_a_height_no_walking_robot_has_is_refused():
    with pytest.raises(ValueError, match="not a walking robot's"):
        preview_gains(0.05)


def step_plan(times: np.ndarray) -> np.ndarray:
    """The ZMP on the right foot (-0.1) from 1 s, on the left (+0.1) from 2 s, between at 3 s."""
    return np.select([times < 1.0, times < 2.0, times < 3.0], [0.0, -0.1, 0.1], 0.0)


def test_the_zmp_of_the_planned_com_follows_the_plan_and_the_com_comes_to_rest():
    gains = preview_gains(0.9)
    axis = PreviewAxis(gains, 0.0, 0.0)
    errors = []
    for t in np.arange(0.0, 6.0, 0.002):   # a 2 ms loop over the 10 ms controller
        axis.advance(t, step_plan)
        if 0.2 < t % 1.0 < 0.8 and 1.0 < t < 3.0:   # well inside each phase
            errors.append(abs(axis.zmp(t) - step_plan(np.array([t]))[0]))
    assert max(errors) < 0.01          # 1 cm: the pendulum's ZMP is where it was planned
    c, v, a = axis.sample(6.0)
    assert abs(c) < 0.005 and abs(v) < 0.01 and abs(a) < 0.05


def test_the_com_starts_moving_before_the_zmp_does():
    """Preview: the CoM leaves early towards where the ZMP will go (at 1 s, to -0.1)."""
    axis = PreviewAxis(preview_gains(0.9), 0.0, 0.0)
    axis.advance(0.9, step_plan)
    position, velocity, _ = axis.sample(0.9)
    assert position < -0.01 and velocity < -0.05


def test_samples_between_controller_steps_are_smooth():
    axis = PreviewAxis(preview_gains(0.9), 0.0, 0.0)
    samples = []
    for t in np.arange(0.5, 1.5, 0.001):
        axis.advance(t, step_plan)
        samples.append(axis.sample(t))
    position, velocity, _ = np.array(samples).T
    # each sample continues the last: the velocity is the position's slope, without jumps
    assert np.abs(np.diff(position) / 0.001 - velocity[:-1]).max() < 0.005
    assert np.abs(np.diff(velocity)).max() < 0.001 * GRAVITY
