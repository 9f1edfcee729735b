"""The robot's battery: charge drained by the motors and the computers, voltage that sags.

Theory of operation
-------------------
One of Walk-Man's DRC runs ended on a power problem (paper, section 4), so the
simulated robot has a battery the pilot watches like the temperatures.  A
first-order pack model, sans-IO (the HAL's loop feeds it and publishes it):

* electric power drawn = the computers and electronics (:data:`BASE_LOAD`) +
  each motor's mechanical power (``max(0, tau * qdot)``: no regeneration) over
  the drive's efficiency + its copper losses (``LOSS * tau^2``);
* charge falls by power over the pack's energy (:data:`CAPACITY_WH`);
* the terminal voltage is the open-circuit voltage of the charge (a Li-ion
  curve between :data:`EMPTY_V` and :data:`FULL_V`) minus the current through
  the internal resistance: it sags under load.

:meth:`Battery.warnings` says each level the charge fell below (20 %, 10 %,
5 %) once per discharge, as YARP's ``batteryWrapper`` notifies its levels; the
HAL turns them into warnings on ``/<robot>/warning:o``.  The figures are a
plausible 48-V, 1-kWh pack (about two hours of standing), not Walk-Man's data.

The wire form is YARP 3.5's ``batteryWrapper`` stream, so a real
``batteryClient`` reads the HAL: ``voltage current charge_percent temperature
status`` (four float64, one int32) on ``<name>/data:o`` once a second.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import List, Sequence

import numpy as np

from yarp_lite.bottle import Bottle, Float64, Int32

CAPACITY_WH = 1000.0
FULL_V, EMPTY_V = 54.6, 42.0       # a 13-cell Li-ion pack
INTERNAL_OHM = 0.08
BASE_LOAD = 180.0                  # W: the on-board computers, the sensors, the drives' logic
EFFICIENCY = 0.8                   # of the motor drives
LOSS = 0.004                       # W per (N*m)^2: copper losses of a joint holding a torque
TEMPERATURE = 30.0                 # C: the pack's (not modelled)
#: Levels the pilot is warned of, once each as the charge falls below them (percent).
WARNING_LEVELS = (20.0, 10.0, 5.0)
#: A level warns again only after the charge rose this far above it (a charge, a new pack).
REARM = 2.0


class BatteryStatus(IntEnum):
    """``yarp::dev::IBattery::Battery_status`` of YARP 3.5."""

    OK_STANDBY = 0
    OK_IN_CHARGE = 1
    OK_IN_USE = 2
    GENERAL_ERROR = 3
    TIMEOUT = 4
    LOW_WARNING = 5
    CRITICAL_WARNING = 6


@dataclass(frozen=True)
class BatteryReading:
    """What ``batteryWrapper`` streams."""

    voltage: float
    current: float
    charge: float          # percent
    temperature: float
    status: BatteryStatus


def electric_power(torque: np.ndarray, velocity: np.ndarray) -> float:
    """W the robot draws for these joint torques (N*m) and velocities (rad/s)."""
    mechanical = np.clip(torque * velocity, 0.0, None).sum() / EFFICIENCY
    return float(BASE_LOAD + mechanical + LOSS * np.square(torque).sum())


def open_circuit_voltage(charge: float) -> float:
    """A Li-ion pack's resting voltage at ``charge`` (0..1): steep at both ends."""
    c = min(max(charge, 0.0), 1.0)
    shape = 0.08 * np.log(max(c, 1e-3)) + 0.85 * c + 0.15 * c ** 8 + 0.55
    return float(EMPTY_V + (FULL_V - EMPTY_V) * min(max(shape / 1.55, 0.0), 1.0))


class Battery:
    """The pack's state; :meth:`step` drains it."""

    def __init__(self, charge_percent: float = 100.0, speedup: float = 1.0) -> None:
        if not 0.0 <= charge_percent <= 100.0:
            raise ValueError(f"a battery's charge is 0..100 %, got {charge_percent}")
        if speedup <= 0:
            raise ValueError(f"the battery's speedup must be positive, got {speedup}")
        self.charge = charge_percent / 100.0
        self.speedup = speedup          # > 1 lets a test see a discharge in seconds
        self.current = 0.0
        self._warned = {level: charge_percent < level for level in WARNING_LEVELS}

    @property
    def voltage(self) -> float:
        return max(0.0, open_circuit_voltage(self.charge) - INTERNAL_OHM * self.current)

    def step(self, power_w: float, dt: float) -> None:
        """Draw ``power_w`` for ``dt`` seconds."""
        resting = open_circuit_voltage(self.charge)
        self.current = power_w / max(resting, 1.0)
        self.charge = max(0.0, self.charge - power_w * dt * self.speedup / (CAPACITY_WH * 3600))

    def warnings(self) -> List[str]:
        """The levels crossed downward since the last call, as the pilot reads them."""
        percent = self.charge * 100.0
        said = []
        for level in WARNING_LEVELS:
            if percent < level and not self._warned[level]:
                self._warned[level] = True
                said.append(f"battery below {level:g} % ({percent:.1f} %, {self.voltage:.1f} V)"
                            + ("; the robot will soon stop: plan a reset" if level <= 5 else ""))
            elif percent > level + REARM:
                self._warned[level] = False
        return said

    def reading(self) -> BatteryReading:
        percent = self.charge * 100.0
        status = BatteryStatus.CRITICAL_WARNING if percent < 10 else \
            BatteryStatus.LOW_WARNING if percent < 20 else BatteryStatus.OK_IN_USE
        return BatteryReading(self.voltage, self.current, percent, TEMPERATURE, status)


def encode_reading(reading: BatteryReading) -> Bottle:
    """``batteryWrapper``'s stream: voltage current charge temperature (float64), status."""
    return Bottle([Float64(reading.voltage), Float64(reading.current), Float64(reading.charge),
                   Float64(reading.temperature), Int32(int(reading.status))])


def decode_reading(values: Sequence) -> BatteryReading:
    """A ``batteryWrapper`` stream message; ValueError names what is wrong."""
    if len(values) != 5:
        raise ValueError(f"a battery reading is 5 values (voltage current charge temperature "
                         f"status), got {len(values)}")
    numbers = values[:4]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in numbers) or \
            not all(np.isfinite(float(v)) for v in numbers):
        raise ValueError(f"a battery reading's first four values are finite numbers, got "
                         f"{list(numbers)}")
    status = values[4]
    if not isinstance(status, int) or isinstance(status, bool) or \
            status not in BatteryStatus._value2member_map_:
        raise ValueError(f"a battery status is 0..6, got {status!r}")
    return BatteryReading(*(float(v) for v in numbers), BatteryStatus(status))
