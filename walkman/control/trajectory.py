"""Trajectories with the quintic time law of the Walk-Man modules.

``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5`` with ``tau = t / T`` goes from 0
to 1 with zero velocity and acceleration at both ends.  Linear trajectories
interpolate positions (and, for Cartesian poses, orientations on SO(3));
circular ones rotate about an axis by ``s * angle``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def quintic(tau: float) -> float:
    tau = min(max(tau, 0.0), 1.0)
    return tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)


def quintic_velocity(tau: float) -> float:
    """ds/dtau."""
    tau = min(max(tau, 0.0), 1.0)
    return 30.0 * tau * tau * (1.0 - tau) ** 2


def quintic_acceleration(tau: float) -> float:
    """d2s/dtau2."""
    tau = min(max(tau, 0.0), 1.0)
    return 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)


@dataclass
class JointTrajectory:
    """From ``start`` to ``goal`` in ``duration`` seconds, quintic in time."""

    start: np.ndarray
    goal: np.ndarray
    duration: float
    t0: float = 0.0

    def __post_init__(self) -> None:
        self.start = np.asarray(self.start, dtype=float)
        self.goal = np.asarray(self.goal, dtype=float)
        if self.duration <= 0:
            raise ValueError(f"trajectory duration must be positive, got {self.duration}")

    def at(self, t: float) -> np.ndarray:
        return self.start + (self.goal - self.start) * quintic((t - self.t0) / self.duration)

    def done(self, t: float) -> bool:
        return t - self.t0 >= self.duration


def duration_for(distance: float, max_speed: float, minimum: float = 0.2) -> float:
    """Shortest quintic duration whose peak speed (1.875 d / T) stays under max_speed."""
    return max(minimum, 1.875 * abs(distance) / max_speed)
