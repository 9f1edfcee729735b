"""Firmware of the emulated boards: what runs on each joint's and sensor's electronics.

Each control board receives its 12-byte Tx slice every millisecond, closes a
PID position loop on the link encoder (torque = P * error - D * velocity,
saturated at the joint's effort) and answers its 16-byte Rx slice.  It
protects itself like real firmware: over temperature, beyond a joint limit or
without a fresh Tx for 50 ms it raises a fault; a timeout makes it hold its
last position, over-temperature makes it go limp; faults latch until the
master sets ``CLEAR_FAULTS``.

The boards are independent, but 33 Python objects stepping at 1 kHz would eat
a core, so :class:`ControlBoards` runs all of them in lock step on numpy
arrays (row ``i`` is board ``i``'s state) and reads/writes the process image
with the packet layout of :mod:`walkman.hal.ethercat.packets`: the bytes are
exactly those of per-board packing (a test checks it).
"""

from __future__ import annotations

from typing import Callable, Sequence, Tuple

import numpy as np

from walkman.hal.ethercat.packets import CLEAR_FAULTS, CONTROL_RX, CONTROL_TX, SENSOR_RX, Fault

TIMEOUT_CYCLES = 50
MAX_TEMPERATURE = 80.0

TX_DTYPE = np.dtype([("position", "<i4"), ("fault", "<u2"), ("p_gain", "<u2"),
                     ("d_gain", "<u2"), ("stamp", "<u2")])
RX_DTYPE = np.dtype([("position", "<i4"), ("reference", "<i4"), ("temperature", "<i2"),
                     ("torque", "<i2"), ("fault", "<u2"), ("rtt", "<u2")])
assert TX_DTYPE.itemsize == CONTROL_TX.size and RX_DTYPE.itemsize == CONTROL_RX.size

_I32 = (-(1 << 31), (1 << 31) - 1)
_I16 = (-(1 << 15), (1 << 15) - 1)


def _fit(values: np.ndarray, bounds, dtype) -> np.ndarray:
    return np.clip(np.rint(values), bounds[0], bounds[1]).astype(dtype)


def pack_tx(position: np.ndarray, fault: int, p_gain: np.ndarray, d_gain: np.ndarray,
            stamp: int) -> bytes:
    """The master's process image: one 12-byte Tx slice per board."""
    image = np.zeros(len(position), dtype=TX_DTYPE)
    image["position"] = _fit(position * 1e6, _I32, np.int32)
    image["fault"] = fault & 0xFFFF
    image["p_gain"] = _fit(p_gain, (0, 65535), np.uint16)
    image["d_gain"] = _fit(d_gain * 100, (0, 65535), np.uint16)
    image["stamp"] = stamp & 0xFFFF
    return image.tobytes()


class ControlBoards:
    """N control boards running their firmware in lock step."""

    def __init__(self, lower: Sequence[float], upper: Sequence[float],
                 effort: Sequence[float]) -> None:
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.effort = np.asarray(effort, dtype=float)
        count = len(self.lower)
        self.reference = np.zeros(count)
        self.p_gain = np.zeros(count)
        self.d_gain = np.zeros(count)
        self.fault = np.zeros(count, dtype=np.uint16)
        self.silent_cycles = np.zeros(count, dtype=int)
        self.last_stamp = np.full(count, -1)
        self.torque = np.zeros(count)

    def receive(self, image: bytes, position: np.ndarray) -> None:
        """Each board takes its Tx slice (a short image leaves the tail boards unfed)."""
        count = len(self.lower)
        usable = min(count, len(image) // TX_DTYPE.itemsize)
        tx = np.frombuffer(image, dtype=TX_DTYPE, count=usable)
        fed = np.zeros(count, dtype=bool)
        fed[:usable] = True
        clear = np.zeros(count, dtype=bool)
        clear[:usable] = (tx["fault"] & CLEAR_FAULTS) != 0
        self.fault[clear] = 0
        fresh = np.zeros(count, dtype=bool)
        fresh[:usable] = tx["stamp"] != self.last_stamp[:usable]
        self.silent_cycles = np.where(fresh, 0, self.silent_cycles + 1)
        if usable:
            update = fresh[:usable]
            self.last_stamp[:usable][update] = tx["stamp"][update]
            self.reference[:usable][update] = tx["position"][update] / 1e6
            self.p_gain[:usable][update] = tx["p_gain"][update]
            self.d_gain[:usable][update] = tx["d_gain"][update] / 100.0
        if len(image) % TX_DTYPE.itemsize or usable < count:
            self.fault[~fed] |= np.uint16(Fault.BAD_PACKET)
        timed_out = self.silent_cycles >= TIMEOUT_CYCLES
        newly = timed_out & ((self.fault & np.uint16(Fault.COMMUNICATION_TIMEOUT)) == 0)
        self.reference[newly] = position[newly]  # hold where we are
        self.fault[timed_out] |= np.uint16(Fault.COMMUNICATION_TIMEOUT)

    def control(self, position: np.ndarray, velocity: np.ndarray,
                temperature: np.ndarray) -> np.ndarray:
        """One 1 kHz PID step of every board; returns the joint torques."""
        self.fault[temperature > MAX_TEMPERATURE] |= np.uint16(Fault.OVER_TEMPERATURE)
        outside = (position < self.lower - 0.02) | (position > self.upper + 0.02)
        self.fault[outside] |= np.uint16(Fault.POSITION_LIMIT)
        reference = np.clip(self.reference, self.lower, self.upper)
        torque = self.p_gain * (reference - position) - self.d_gain * velocity
        saturated = np.abs(torque) > self.effort
        self.fault = np.where(saturated, self.fault | np.uint16(Fault.TORQUE_SATURATED),
                              self.fault & np.uint16(0xFFFF ^ Fault.TORQUE_SATURATED)
                              ).astype(np.uint16)
        torque = np.clip(torque, -self.effort, self.effort)
        limp = (self.fault & np.uint16(Fault.OVER_TEMPERATURE)) != 0
        torque[limp] = 0.0
        self.torque = torque
        return torque

    def answer(self, position: np.ndarray, temperature: np.ndarray,
               round_trip_us: np.ndarray) -> bytes:
        """Every board's Rx slice, concatenated in bus order."""
        image = np.zeros(len(self.lower), dtype=RX_DTYPE)
        image["position"] = _fit(position * 1e6, _I32, np.int32)
        image["reference"] = _fit(self.reference * 1e6, _I32, np.int32)
        image["temperature"] = _fit(temperature * 10, _I16, np.int16)
        image["torque"] = _fit(self.torque * 100, _I16, np.int16)
        image["fault"] = self.fault
        image["rtt"] = np.clip(round_trip_us, 0, 65535).astype(np.uint16)
        return image.tobytes()


def unpack_rx(image: bytes) -> np.ndarray:
    """The master's view of the Rx image (structured array, SI units follow)."""
    return np.frombuffer(image, dtype=RX_DTYPE)


class SensorBoard:
    """A 6-axis sensor (F/T, or the IMU's orientation and rates) on the bus."""

    def __init__(self, name: str, sample: Callable[[], Tuple[float, ...]]) -> None:
        self.name = name
        self.sample = sample
        self.cycle = 0
        self.fault = Fault.NONE

    def answer(self, round_trip_us: int) -> bytes:
        """The 30-byte packet (same bytes as ``SensorRx(...).pack()``, cheaper)."""
        self.cycle += 1
        try:
            scaled = [min(_I32[1], max(_I32[0], round(value * 1000.0)))
                      for value in self.sample()]
        except (ValueError, OverflowError):  # NaN or infinity from the sensor
            self.fault |= Fault.BAD_PACKET
            scaled = [0] * 6
        return SENSOR_RX.pack(*scaled, int(self.fault) & 0xFFFF,
                              min(max(round_trip_us, 0), 65535), self.cycle & 0xFFFF)
