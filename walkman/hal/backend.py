"""The lower tier of the HAL: a robot you can step, read and command.

Both backends -- ``sim`` (MuJoCo, position servos with series-elastic
compliance) and ``ethercat`` (emulated firmware boards on a 1 kHz bus) --
implement :class:`Backend`, in whole-body joint order, SI units.  The YARP
server above them (:mod:`walkman.hal.server`) does not know which one runs.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

import numpy as np

from walkman.model.description import Robot, home_posture

#: Reference speed (rad/s) of position-mode moves (``[set] [pos]``, ``[poss]``) until a
#: client sets its own (``[set] [vels]``).
DEFAULT_REF_SPEED = 0.6


@dataclass(frozen=True)
class Imu:
    rpy: Tuple[float, float, float]
    acceleration: Tuple[float, float, float]
    gyro: Tuple[float, float, float]


class Backend(ABC):
    """One robot, stepped at a fixed period (1 ms)."""

    dt: float = 0.001

    def __init__(self, model: Robot) -> None:
        self.model = model
        self.joint_names: List[str] = model.joint_names
        self.index: Dict[str, int] = {name: i for i, name in enumerate(self.joint_names)}
        self.lower = np.array([model.joint(n).lower for n in self.joint_names])
        self.upper = np.array([model.joint(n).upper for n in self.joint_names])
        posture = home_posture(model)
        self.reference = np.array([posture[n] for n in self.joint_names])
        self.idle = np.zeros(len(self.joint_names), dtype=bool)
        self.time = 0.0

    # -- commanding ------------------------------------------------------------------

    def set_references(self, indices: Sequence[int], values: Sequence[float]) -> np.ndarray:
        """Position references (rad), clamped to the joint limits; returns what was applied."""
        indices = np.asarray(indices, dtype=int)
        clamped = np.clip(np.asarray(values, dtype=float), self.lower[indices],
                          self.upper[indices])
        self.reference[indices] = clamped
        self.idle[indices] = False
        self._apply_modes(indices)
        return clamped

    def set_idle(self, indices: Sequence[int]) -> None:
        """Motors off: no torque, the joints go limp."""
        indices = np.asarray(indices, dtype=int)
        self.idle[indices] = True
        self._apply_modes(indices)

    def _apply_modes(self, indices: np.ndarray) -> None:
        """Hook for backends that must reconfigure actuators when modes change."""

    # -- stepping and sensing -----------------------------------------------------------

    @abstractmethod
    def step(self) -> None:
        """Advance one period (1 ms)."""

    @abstractmethod
    def positions(self) -> np.ndarray: ...

    @abstractmethod
    def velocities(self) -> np.ndarray: ...

    @abstractmethod
    def torques(self) -> np.ndarray: ...

    @abstractmethod
    def temperatures(self) -> np.ndarray: ...

    @abstractmethod
    def ft(self, sensor: str) -> np.ndarray:
        """Force (N) and torque (N*m) at an F/T sensor, in its own frame."""

    @abstractmethod
    def imu(self) -> Imu: ...

    @property
    def ft_sensors(self) -> List[str]:
        return [sensor.name for sensor in self.model.sensors if sensor.kind == "ft"]

    def status(self) -> Dict[str, object]:
        """Backend-specific health figures for the HAL's log and rpc."""
        return {}

    def close(self) -> None:
        """Release resources."""


def quat_to_rpy(w: float, x: float, y: float, z: float) -> Tuple[float, float, float]:
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw
