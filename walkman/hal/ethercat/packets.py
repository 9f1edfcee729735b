"""The EtherCAT process data of Walk-Man's boards (paper, Figure 4), byte for byte.

=================  ======  ==================================================
control board Tx   bytes   master -> board, every millisecond
=================  ======  ==================================================
position desired     4     int32, micro-radians
fault                2     uint16, master's fault word (``CLEAR_FAULTS`` bit)
P gain               2     uint16, N*m/rad
D gain               2     uint16, 0.01 N*m*s/rad
timestamp            2     uint16, master cycle counter (ms, wraps)
=================  ======  ==================================================

=================  ======  ==================================================
control board Rx   bytes   board -> master
=================  ======  ==================================================
position link        4     int32, micro-radians (link-side encoder)
reference pos        4     int32, micro-radians (what the PID tracks)
max temperature      2     int16, 0.1 deg C
torque link          2     int16, 0.01 N*m (series-elastic spring)
fault                2     uint16, :class:`Fault` bits
round trip time      2     uint16, microseconds, measured by the master
=================  ======  ==================================================

=================  ======  ==================================================
sensor board       bytes   board -> master (4 F/T boards and the IMU board)
=================  ======  ==================================================
Fx Fy Fz Tx Ty Tz  4 each  int32, mN and mN*m (the IMU board: roll, pitch,
                           yaw in milli-rad and angular rates in milli-rad/s)
fault                2     uint16
round trip time      2     uint16, microseconds
timestamp            2     uint16, board cycle counter
=================  ======  ==================================================

Encoders saturate instead of wrapping, so an out-of-range value is visible
as a limit, not a jump; decoders reject packets of the wrong size.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntFlag
from typing import Tuple

CONTROL_TX = struct.Struct("<iHHHH")      # 12 bytes
CONTROL_RX = struct.Struct("<iihhHH")     # 16 bytes
SENSOR_RX = struct.Struct("<6iHHH")       # 30 bytes
CLEAR_FAULTS = 0x8000

_INT32 = (-(1 << 31), (1 << 31) - 1)
_INT16 = (-(1 << 15), (1 << 15) - 1)
_UINT16 = (0, (1 << 16) - 1)


class Fault(IntFlag):
    NONE = 0
    OVER_TEMPERATURE = 0x01
    POSITION_LIMIT = 0x02
    TORQUE_SATURATED = 0x04
    COMMUNICATION_TIMEOUT = 0x08
    BAD_PACKET = 0x10


class PacketError(ValueError):
    """A process-data slice has the wrong size."""


def _fit(value: float, bounds: Tuple[int, int]) -> int:
    return int(max(bounds[0], min(bounds[1], round(value))))


def micro(value: float) -> int:
    return _fit(value * 1e6, _INT32)


@dataclass(frozen=True)
class ControlTx:
    position_desired: float   # rad
    fault: int
    p_gain: float             # N*m/rad
    d_gain: float             # N*m*s/rad
    timestamp: int

    def pack(self) -> bytes:
        return CONTROL_TX.pack(micro(self.position_desired), _fit(self.fault, _UINT16),
                               _fit(self.p_gain, _UINT16), _fit(self.d_gain * 100, _UINT16),
                               self.timestamp & 0xFFFF)

    @classmethod
    def unpack(cls, data: bytes) -> "ControlTx":
        if len(data) != CONTROL_TX.size:
            raise PacketError(f"control Tx is {CONTROL_TX.size} bytes, got {len(data)}")
        position, fault, p_gain, d_gain, stamp = CONTROL_TX.unpack(data)
        return cls(position / 1e6, fault, float(p_gain), d_gain / 100.0, stamp)


@dataclass(frozen=True)
class ControlRx:
    position_link: float      # rad
    reference: float          # rad
    max_temperature: float    # deg C
    torque_link: float        # N*m
    fault: int
    round_trip_us: int

    def pack(self) -> bytes:
        return CONTROL_RX.pack(micro(self.position_link), micro(self.reference),
                               _fit(self.max_temperature * 10, _INT16),
                               _fit(self.torque_link * 100, _INT16), _fit(self.fault, _UINT16),
                               _fit(self.round_trip_us, _UINT16))

    @classmethod
    def unpack(cls, data: bytes) -> "ControlRx":
        if len(data) != CONTROL_RX.size:
            raise PacketError(f"control Rx is {CONTROL_RX.size} bytes, got {len(data)}")
        position, reference, temperature, torque, fault, rtt = CONTROL_RX.unpack(data)
        return cls(position / 1e6, reference / 1e6, temperature / 10.0, torque / 100.0,
                   fault, rtt)


@dataclass(frozen=True)
class SensorRx:
    values: Tuple[float, float, float, float, float, float]  # N, N*m (or rad, rad/s)
    fault: int
    round_trip_us: int
    timestamp: int

    def pack(self) -> bytes:
        return SENSOR_RX.pack(*(micro(v / 1000.0) for v in self.values),
                              _fit(self.fault, _UINT16), _fit(self.round_trip_us, _UINT16),
                              self.timestamp & 0xFFFF)

    @classmethod
    def unpack(cls, data: bytes) -> "SensorRx":
        if len(data) != SENSOR_RX.size:
            raise PacketError(f"sensor packet is {SENSOR_RX.size} bytes, got {len(data)}")
        *values, fault, rtt, stamp = SENSOR_RX.unpack(data)
        return cls(tuple(v / 1000.0 for v in values), fault, rtt, stamp)  # type: ignore[arg-type]
