"""What travels on the HAL's YARP ports: pure functions between values and Bottles.

Port names follow YARP's control-board wrapper (``/<robot>/<chain>/...``):

``state:o``       positions in degrees, a float64 Vector, as YARP streams them
``stateExt:o``    one float64 vector ``SEQ TIME N q[N] qdot[N] tau[N] temperature[N]``
                  in SI units (rad, rad/s, N*m, deg C) -- what the whole-body
                  interface reads; flat, so it costs one struct call each way
``command:i``     ``[pos] (q ...) [SEQ]``: stream positions (rad); ``[move] (q ...)``:
                  go there at the reference speed; ``[idle]``: motors off;
                  ``[pjnt] (i ...) (q ...) [SEQ]``: only the listed joints of the
                  chain (indices within the chain), the others keep their reference
``rpc:i``         ``[get] [jnts]``, ``[get] [names]``, ``[get] [lims]``,
                  ``[set] [vels] (...)``, ``[set] [mode] [pos]|[idle]``
``/<robot>/rpc:i`` ``[get] chains`` -> ``((chain name...) ...)``: the grouping;
                  ``[get] stats``; ``[set] harness on|off``  (vocabs hold 4 letters,
                  so longer words are plain strings)
``/<robot>/warning:o``      ``SEQ TEXT OWNER HOLDER ACTION`` when two modules command one
                             joint (:mod:`walkman.hal.arbitration`)
``/<robot>/<ft>/analog:o``  Fx Fy Fz Tx Ty Tz (N, N*m), like YARP's analogServer
``/<robot>/inertial``       roll pitch yaw (deg), acc (m/s^2), gyro (deg/s), mag (0),
                             YARP's inertial layout
``/<robot>/sim/world:o``    simulation only: ``time qpos...`` of the whole MuJoCo scene, 30 Hz,
                             for simulated sensors (the camera of ``walkman-perception``)

Every decoder validates what it is given and raises :class:`HalProtocolError`
naming the problem, so a malformed command is refused and logged, never
applied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

from yarp_lite.bottle import Bottle, Vocab


class HalError(Exception):
    """Base of the HAL's errors."""


class HalProtocolError(HalError):
    """A message on a HAL port is malformed (peer misbehaviour)."""


class HalUsageError(HalError):
    """The whole-body interface was misused (wrong vector length, NaN, ...)."""


def port_names(robot: str, chain: str) -> dict:
    base = f"/{robot}/{chain}"
    return {"state": f"{base}/state:o", "state_ext": f"{base}/stateExt:o",
            "command": f"{base}/command:i", "rpc": f"{base}/rpc:i"}


def robot_rpc_name(robot: str) -> str:
    return f"/{robot}/rpc:i"


def hal_warning_port_name(robot: str) -> str:
    """``seq text owner holder action``: a module's command refused or overridden."""
    return f"/{robot}/warning:o"


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


def encode_state(q_rad: Sequence[float]) -> Bottle:
    return _floats(math.degrees(value) for value in q_rad)


def encode_state_ext(state: ChainState) -> Bottle:
    return Bottle([float(state.seq), float(state.time), float(len(state.q)), *state.q,
                   *state.qdot, *state.tau, *state.temperature])


def decode_state_ext(bottle: Bottle, joints: int) -> ChainState:
    expected = 3 + 4 * joints
    if len(bottle) != expected:
        raise HalProtocolError(f"stateExt has {len(bottle)} values, expected {expected} "
                               f"for {joints} joints")
    if not all(isinstance(value, float) for value in bottle):
        raise HalProtocolError("stateExt must be a vector of float64")
    if int(bottle[2]) != joints:
        raise HalProtocolError(f"stateExt is for {int(bottle[2])} joints, expected {joints}")
    values = tuple(bottle)
    n = joints
    return ChainState(int(values[0]), values[1], values[3:3 + n], values[3 + n:3 + 2 * n],
                      values[3 + 2 * n:3 + 3 * n], values[3 + 3 * n:3 + 4 * n])


@dataclass(frozen=True)
class Command:
    mode: str                      # "pos", "move", "pjnt" or "idle"
    values: Tuple[float, ...] = ()
    seq: Optional[int] = None      # stamp of the state this command answers (latency)
    joints: Optional[Tuple[int, ...]] = None  # "pjnt": which joints of the chain


def encode_command(command: Command) -> Bottle:
    bottle = Bottle([Vocab(command.mode)])
    if command.mode == "pjnt":
        bottle.append(Bottle(int(i) for i in (command.joints or ())))
    if command.mode != "idle":
        bottle.append(_floats(command.values))
    if command.seq is not None:
        bottle.append(int(command.seq))
    return bottle


def _values(mode: str, item: object, count: int) -> Tuple[float, ...]:
    if not isinstance(item, list):
        raise HalProtocolError(f"[{mode}] needs a list of {count} positions, got {item!r}")
    try:
        values = tuple(float(value) for value in item)
    except (TypeError, ValueError):
        raise HalProtocolError(f"[{mode}] positions must be numbers: {item}") from None
    if len(values) != count:
        raise HalProtocolError(f"[{mode}] has {len(values)} positions, expected {count}")
    if not all(math.isfinite(value) for value in values):
        raise HalProtocolError(f"[{mode}] positions must be finite: {values}")
    return values


def decode_command(bottle: Bottle, joints: int) -> Command:
    """Validate a ``command:i`` message for a chain of ``joints`` joints."""
    if not bottle or str(bottle[0]) not in ("pos", "move", "idle", "pjnt"):
        raise HalProtocolError(f"command must start with [pos], [move], [pjnt] or [idle]: {bottle}")
    mode = str(bottle[0])
    if mode == "idle":
        return Command("idle")
    if mode == "pjnt":
        if len(bottle) < 3 or not isinstance(bottle[1], list):
            raise HalProtocolError(f"[pjnt] needs (joint indices) (positions): {bottle}")
        indices = bottle[1]
        if not indices or not all(isinstance(i, int) and not isinstance(i, Vocab)
                                  and 0 <= i < joints for i in indices):
            raise HalProtocolError(f"[pjnt] joint indices must be 0..{joints - 1}: {indices}")
        if len(set(indices)) != len(indices):
            raise HalProtocolError(f"[pjnt] repeats a joint: {indices}")
        values = _values(mode, bottle[2], len(indices))
        seq = int(bottle[3]) if len(bottle) > 3 and isinstance(bottle[3], int) else None
        return Command(mode, values, seq, tuple(int(i) for i in indices))
    values = _values(mode, bottle[1] if len(bottle) > 1 else None, joints)
    seq = int(bottle[2]) if len(bottle) > 2 and isinstance(bottle[2], int) else None
    return Command(mode, values, seq)


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
