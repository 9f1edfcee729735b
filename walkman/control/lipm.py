"""Centre-of-mass trajectories from a ZMP plan: Kajita's preview control of the cart-table.

Theory of operation
-------------------
Walking is planned as where the zero-moment point (ZMP) must be: on the
stance foot in single support, moving from one foot to the other in double
support.  The linear inverted pendulum (LIPM) -- the robot's mass at a
constant height ``z`` above the floor -- ties the ZMP ``p`` to the centre of
mass ``c``: ``p = c - z/g * c''``.  Kajita's *cart-table* model makes ``c``'s
jerk the input of a linear system whose output is ``p``, and preview control
(Katayama's optimal servo with preview; Kajita et al., "Biped walking pattern
generation by using preview control of zero-moment point", ICRA 2003) finds
the jerk that makes ``p`` follow the plan, looking ``horizon`` seconds ahead::

    x = (c, c', c'')        x[k+1] = A x[k] + b u[k]        p[k] = C x[k]
    u[k] = -Gi * sum(p - p_ref)  -  Gx x[k]  -  sum_j Gd[j] p_ref[k + j]

The gains come from the discrete Riccati equation of the system augmented
with the integral of the tracking error (:func:`preview_gains`, solved here
with the structure-preserving doubling algorithm: numpy only).  The
controller runs on its own fixed step (:data:`STEP`, 10 ms) whatever the
module's period: :meth:`PreviewAxis.sample` integrates the constant jerk
between steps exactly, so a 2 ms control loop gets a smooth CoM.  ``x`` and
``y`` are two independent axes with the same gains.

Everything here is pure: arrays in, arrays out, time passed in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Tuple

import numpy as np

GRAVITY = 9.81
#: The preview controller's own step (s): fine enough for walking, coarse enough that
#: the Riccati equation is well conditioned.
STEP = 0.01
#: How far ahead the controller looks (s): a step and its next weight shift (1.2 s a step).
HORIZON = 1.6


@dataclass(frozen=True)
class PreviewGains:
    dt: float
    height: float
    integral: float          # Gi
    state: np.ndarray        # Gx, 3
    preview: np.ndarray      # Gd[1..N], N
    A: np.ndarray
    b: np.ndarray
    C: np.ndarray


def cart_table(dt: float, height: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, b, C) of the cart-table model sampled at ``dt`` for a CoM ``height`` (m)."""
    A = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    b = np.array([dt ** 3 / 6, dt * dt / 2, dt])
    C = np.array([1.0, 0.0, -height / GRAVITY])
    return A, b, C


def solve_dare(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
               iterations: int = 60, tolerance: float = 1e-10) -> np.ndarray:
    """The stabilising solution P of ``P = A'PA - A'PB (R + B'PB)^-1 B'PA + Q``.

    Structure-preserving doubling (Chu et al., 2004): quadratic convergence, no
    eigen-decomposition; raises ``ValueError`` if it does not converge."""
    n = A.shape[0]
    a, g, h = A.copy(), B @ np.linalg.solve(R, B.T), Q.copy()
    identity = np.eye(n)
    for _ in range(iterations):
        w = np.linalg.inv(identity + g @ h)
        a_next = a @ w @ a
        g_next = g + a @ w @ g @ a.T
        h_next = h + a.T @ h @ w @ a
        converged = np.linalg.norm(h_next - h) <= tolerance * max(1.0, np.linalg.norm(h_next))
        a, g, h = a_next, (g_next + g_next.T) / 2, (h_next + h_next.T) / 2
        if converged:
            return h
    raise ValueError("the Riccati equation did not converge")


def preview_gains(height: float, dt: float = STEP, horizon: float = HORIZON,
                  error_weight: float = 1.0, jerk_weight: float = 1e-6) -> PreviewGains:
    """Preview gains for a CoM at ``height`` m (Kajita 2003, eq. 12-15)."""
    if not 0.2 <= height <= 3.0:
        raise ValueError(f"a CoM height of {height} m is not a walking robot's")
    A, b, C = cart_table(dt, height)
    # The system augmented with the tracking error's integral: (e, dx).
    At = np.zeros((4, 4))
    At[0, 0] = 1.0
    At[0, 1:] = C @ A
    At[1:, 1:] = A
    Bt = np.concatenate([[C @ b], b]).reshape(4, 1)
    It = np.array([[1.0], [0.0], [0.0], [0.0]])
    Ft = np.vstack([(C @ A).reshape(1, 3), A])
    Q = error_weight * (It @ It.T)
    R = np.array([[jerk_weight]])
    P = solve_dare(At, Bt, Q, R)
    inverse = 1.0 / (R[0, 0] + (Bt.T @ P @ Bt).item())
    integral = inverse * (Bt.T @ P @ It).item()
    state = inverse * (Bt.T @ P @ Ft).ravel()
    closed = At - Bt @ (inverse * (Bt.T @ P @ At))
    steps = int(round(horizon / dt))
    preview = np.zeros(steps)
    X = -closed.T @ P @ It
    preview[0] = -integral
    for j in range(1, steps):
        preview[j] = inverse * (Bt.T @ X).item()
        X = closed.T @ X
    return PreviewGains(dt, height, integral, state, preview, A, b, C)


class PreviewAxis:
    """One horizontal axis of the CoM under preview control, from a ZMP plan ``p_ref(t)``."""

    def __init__(self, gains: PreviewGains, position: float, t0: float) -> None:
        self.gains = gains
        self.x = np.array([position, 0.0, 0.0])
        self.error_sum = 0.0
        self.jerk: Optional[float] = None   # the input over [t, t + dt], once computed
        self.t = t0                          # when x was last computed (a controller step)

    def _control(self, zmp_at: Callable[[np.ndarray], np.ndarray]) -> None:
        """u[k] from x[k] and the plan ahead: the jerk over the coming step."""
        g = self.gains
        future = zmp_at(self.t + g.dt * np.arange(1, len(g.preview) + 1))
        self.error_sum += float(g.C @ self.x) - float(zmp_at(np.array([self.t]))[0])
        self.jerk = -g.integral * self.error_sum - float(g.state @ self.x) - \
            float(g.preview @ future)

    def advance(self, now: float, zmp_at: Callable[[np.ndarray], np.ndarray]) -> None:
        """Run the controller's steps up to ``now``; ``zmp_at(times)`` gives the plan."""
        g = self.gains
        if self.jerk is None:
            self._control(zmp_at)
        while self.t + g.dt <= now + 1e-12:
            self.x = g.A @ self.x + g.b * self.jerk
            self.t += g.dt
            self._control(zmp_at)

    def sample(self, now: float) -> Tuple[float, float, float]:
        """(c, c', c'') at ``now`` (between steps: the step's constant jerk, integrated)."""
        tau = min(max(now - self.t, 0.0), self.gains.dt)
        c, v, a = self.x
        j = self.jerk or 0.0
        return (c + v * tau + a * tau * tau / 2 + j * tau ** 3 / 6,
                v + a * tau + j * tau * tau / 2, a + j * tau)

    def zmp(self, now: float) -> float:
        """The ZMP the CoM's motion makes at ``now`` (p = c - z/g c'')."""
        c, _, a = self.sample(now)
        return c - self.gains.height / GRAVITY * a
