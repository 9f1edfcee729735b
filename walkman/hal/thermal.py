"""Motor temperatures: copper losses heat each joint, the air cools it.

First-order model per joint: ``dT/dt = k * tau^2 - (T - ambient) / time_constant``.
With Walk-Man's efforts, holding a pose keeps the hips and knees warm
(40-55 C) while the wrists stay near ambient, so the temperature module and
its warnings have something real to watch, on both HAL backends.
"""

from __future__ import annotations

import numpy as np

AMBIENT = 30.0
TIME_CONSTANT = 120.0   # s
HEATING = 2.1e-5          # C per s per (N*m)^2: +50 C at a sustained 140 N*m


class ThermalModel:
    def __init__(self, joints: int, ambient: float = AMBIENT, speedup: float = 1.0) -> None:
        self.temperature = np.full(joints, ambient)
        self.ambient = ambient
        self.speedup = speedup  # > 1 lets tests see heating in seconds

    def step(self, torque: np.ndarray, dt: float) -> np.ndarray:
        dt = dt * self.speedup
        self.temperature += dt * (HEATING * torque * torque
                                  - (self.temperature - self.ambient) / TIME_CONSTANT)
        return self.temperature
