"""What travels on the HAL's YARP ports besides YARP's own protocols.

Each chain is a YARP control board (``/<robot>/<chain>/rpc:i``, ``command:i``,
``state:o``, ``stateExt:o``), spoken as YARP 3.5 speaks it: see
:mod:`walkman.hal.controlboard`.  This module holds the port names and what
we add beside YARP's protocols:

``/<robot>/<chain>/stateSI:o``  one float64 vector ``SEQ TIME N q[N] qdot[N] tau[N]
                  temperature[N]`` in SI units (rad, rad/s, N*m, deg C): the
                  compact, stamped state the bridge's Table 1 codec carries
                  (standard clients read ``stateExt:o`` and never see it)
``/<robot>/stateSI:o``  the same vector for the whole robot, its joints in the
                  order of ``[get] chains``, then the CRC-32 of those joint names
                  in that order: one message per robot step, so a whole-body
                  client wakes once per state instead of once per chain
``/<robot>/rpc:i`` ``[get] chains`` -> ``((chain name...) ...)``: the grouping, so
                  a whole-body client finds every chain without a config;
                  ``[get] stats``; ``[set] harness on|off``; simulation only:
                  ``[set] push IX IY IZ [SECONDS]``, an impulse (N*s, world
                  frame) on the torso, and ``[set] station NAME``, the robot
                  moved to a task's station (vocabs hold 4 letters, so longer
                  words are plain strings)
``/<robot>/warning:o``      ``SEQ TEXT OWNER HOLDER ACTION`` when two modules command one
                             joint (:mod:`walkman.hal.arbitration`)
``/<robot>/<ft>/analog:o``  Fx Fy Fz Tx Ty Tz (N, N*m), like YARP's analogServer
``/<robot>/inertial``       roll pitch yaw (deg), acc (m/s^2), gyro (deg/s), mag (0),
                             YARP's ServerInertial layout
``/<robot>/sim/world:o``    simulation only: ``time qpos...`` of the whole MuJoCo scene, 30 Hz,
                             for simulated sensors (the camera of ``walkman-perception``)

Every decoder validates what it is given and raises :class:`HalProtocolError`
naming the problem, so a malformed message is refused and logged, never
applied.
"""

from __future__ import annotations

import functools
import itertools
import math
import zlib
from dataclasses import dataclass
from typing import List, Sequence, Tuple

from yarp_lite.bottle import Bottle


#: The F/T sensors and the IMU stream every this much robot time (s), on the robot steps
#: that are whole multiples of it.
SENSOR_PERIOD_S = 0.01


class HalError(Exception):
    """Base of the HAL's errors."""


class HalProtocolError(HalError):
    """A message on a HAL port is malformed (peer misbehaviour)."""


class HalUsageError(HalError):
    """The whole-body interface was misused (wrong vector length, NaN, ...)."""


def port_names(robot: str, chain: str) -> dict:
    base = f"/{robot}/{chain}"
    return {"state": f"{base}/state:o", "state_ext": f"{base}/stateExt:o",
            "state_si": f"{base}/stateSI:o", "command": f"{base}/command:i",
            "rpc": f"{base}/rpc:i"}


def whole_state_port_name(robot: str) -> str:
    """The whole robot's SI state, every chain in one message."""
    return f"/{robot}/stateSI:o"


def robot_rpc_name(robot: str) -> str:
    return f"/{robot}/rpc:i"


def hal_warning_port_name(robot: str) -> str:
    """``seq text owner holder action``: a module's command refused or overridden."""
    return f"/{robot}/warning:o"


def battery_port_name(robot: str) -> str:
    """YARP's ``batteryWrapper`` stream (:mod:`walkman.hal.battery`); ``.../rpc:i`` beside it."""
    return f"/{robot}/battery/data:o"


def battery_rpc_name(robot: str) -> str:
    return f"/{robot}/battery/rpc:i"


def ft_port_name(robot: str, sensor: str) -> str:
    return f"/{robot}/{sensor}/analog:o"


def imu_port_name(robot: str) -> str:
    return f"/{robot}/inertial"


def world_port_name(robot: str) -> str:
    """Simulation only: the whole scene's generalized positions (for simulated sensors)."""
    return f"/{robot}/sim/world:o"


def encode_world(time_s: float, qpos: Sequence[float]) -> Bottle:
    return Bottle([float(time_s), *map(float, qpos)])


def decode_world(bottle: Bottle, size: int) -> Tuple[float, List[float]]:
    if len(bottle) != size + 1 or not all(isinstance(v, float) for v in bottle):
        raise HalProtocolError(f"world state has {len(bottle)} values, expected {size + 1} floats")
    return bottle[0], list(bottle[1:])


def _floats(values: Sequence[float]) -> Bottle:
    return Bottle(float(value) for value in values)


@dataclass(frozen=True)
class ChainState:
    seq: int
    time: float
    q: Tuple[float, ...]
    qdot: Tuple[float, ...]
    tau: Tuple[float, ...]
    temperature: Tuple[float, ...]


def encode_state_si(state: ChainState) -> Bottle:
    return Bottle([float(state.seq), float(state.time), float(len(state.q)), *state.q,
                   *state.qdot, *state.tau, *state.temperature])


def _all_floats(values: Sequence[object]) -> bool:
    return all(map(isinstance, values, itertools.repeat(float)))   # C speed: 500 Hz x ~130


def decode_state_si(bottle: Bottle, joints: int) -> ChainState:
    return _state_from_values(tuple(bottle), joints)


def _state_from_values(values: Tuple[object, ...], joints: int) -> ChainState:
    expected = 3 + 4 * joints
    if len(values) != expected:
        raise HalProtocolError(f"stateSI has {len(values)} values, expected {expected} "
                               f"for {joints} joints")
    if not _all_floats(values):
        raise HalProtocolError("stateSI must be a vector of float64")
    if int(values[2]) != joints:
        raise HalProtocolError(f"stateSI is for {int(values[2])} joints, expected {joints}")
    n = joints
    return ChainState(int(values[0]), values[1], values[3:3 + n], values[3 + n:3 + 2 * n],
                      values[3 + 2 * n:3 + 3 * n], values[3 + 3 * n:3 + 4 * n])


def grouping_fingerprint(joint_names: Sequence[str]) -> float:
    """The joints of a whole-robot state, in order, as one float64 (a CRC-32: exact)."""
    return _fingerprint(tuple(joint_names))


@functools.lru_cache(maxsize=16)
def _fingerprint(joint_names: Tuple[str, ...]) -> float:
    return float(zlib.crc32(" ".join(joint_names).encode()))


def encode_whole_state(state: ChainState, joint_names: Sequence[str]) -> Bottle:
    """``stateSI`` for the whole robot, then the fingerprint of its joints' order."""
    bottle = encode_state_si(state)
    bottle.append(grouping_fingerprint(joint_names))
    return bottle


def decode_whole_state(bottle: Bottle, joint_names: Sequence[str]) -> ChainState:
    """The whole robot's state, refused when its joints are not in ``joint_names``' order:
    a HAL restarted with another grouping would put positions on the wrong joints."""
    values = tuple(bottle)
    if not values:
        raise HalProtocolError("whole-robot stateSI is empty")
    state = _state_from_values(values[:-1], len(joint_names))
    if values[-1] != grouping_fingerprint(joint_names):
        raise HalProtocolError("whole-robot stateSI groups the joints differently from when "
                               "this client connected (the HAL restarted with another "
                               "configuration?)")
    return state


def encode_ft(wrench: Sequence[float]) -> Bottle:
    return _floats(wrench)


def encode_inertial(rpy_rad: Sequence[float], acc: Sequence[float], gyro_rad: Sequence[float]) -> Bottle:
    return _floats([*(math.degrees(a) for a in rpy_rad), *acc,
                    *(math.degrees(g) for g in gyro_rad), 0.0, 0.0, 0.0])


def decode_inertial(bottle: Bottle) -> Tuple[List[float], List[float], List[float]]:
    if len(bottle) < 9:
        raise HalProtocolError(f"inertial message has {len(bottle)} values, expected 12")
    values = [float(v) for v in bottle]
    return ([math.radians(v) for v in values[0:3]], values[3:6],
            [math.radians(v) for v in values[6:9]])


def state_interval(period: float) -> float:
    """How often a reader running every ``period`` seconds needs the joints' state: a bit
    more than twice per period, and at least every 20 ms.  The HAL streams each chain at
    500 Hz: a 100 Hz module decoding all of it spent most of its time on states it never
    used, and on 2 cores the readers together starved the HAL itself.  Not exactly twice:
    a 500 Hz module over a 1 kHz robot must read every state as it comes, for its loop
    ticks on them (:mod:`walkman.gym.pacing`); a reader pausing a full millisecond after
    each read left every other one waiting or skipped."""
    return min(0.02, max(0.0, period) * 0.4)
