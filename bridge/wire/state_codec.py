"""The robot state, compressed the way Table 1 of the paper counts it -- and smaller.

Theory of operation
-------------------
Table 1 budgets, per second at T = 1 s: 33 joint ids (8 bit), 33 encoders
(16 bit), 33 torques (8 bit), 7 board temperatures (16 bit), plus 1152 bit of
serialization overhead.  We keep the same information and resolution:

* encoders: 16 bit over [-4, 4) rad (1.2e-4 rad steps), every joint;
* torques: 8 bit mu-law over +-300 N*m (finer near zero, where the robot lives);
* temperatures: 16 bit centi-degrees, seven joints per second in rotation, all
  of them in the first frame of a connection;
* no joint ids: the joint order is the HAL's chain layout, sent once per
  connection in the key frame (chain and joint names, so the pilot side can
  describe the robot as the HAL does).

Each field is then sent in the cheapest of three forms -- raw, deltas against
the previous frame (a bitmap of changed joints and zigzag varints), or
"unchanged" -- chosen per frame and announced in the header byte.  A still
robot costs a few bytes a second; a robot moving every joint costs about the
raw size.  Deltas need both ends to agree on the previous frame, which the TCP
channel guarantees per connection (:meth:`StateEncoder.reset` on reconnect).

Frame: ``header`` ``svarint time delta (ms)`` [``layout``] ``encoders``
``torques`` ``temperatures``.

Hostile input: :meth:`StateDecoder.decode` raises :class:`BridgeProtocolError`
naming the field (unknown header bits, a delta without a key frame, a code
leaving its range, temperatures outside the layout, trailing bytes) and
leaves its context untouched, so the next good frame decodes as if the bad
one never came.  Limits: a layout has at most 64 chains of 1024 joints, names
of 255 bytes; every other count is bounded by the layout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np

from bridge.errors import BridgeProtocolError, NeedMoreData
from bridge.wire.varint import Buffer, get_svarint, get_varint, put_svarint, put_varint, take

ENCODER_RANGE = 4.0            # rad: 16-bit codes cover [-4, 4)
TORQUE_RANGE = 300.0           # N*m
MU = 255.0
TEMPERATURE_OFFSET = -100.0    # deg C at code 0; 0.01 deg C per step
TEMPERATURES_PER_SECOND = 7

KEY = 0x01
_RAW, _DELTA, _SAME = 0, 1, 2


@dataclass(frozen=True)
class Layout:
    """The HAL's chains in order: ``(chain name, (joint names...))``."""

    chains: Tuple[Tuple[str, Tuple[str, ...]], ...]

    @property
    def joints(self) -> int:
        return sum(len(joints) for _, joints in self.chains)

    @property
    def counts(self) -> List[Tuple[str, int]]:
        return [(name, len(joints)) for name, joints in self.chains]


@dataclass
class RobotState:
    """One reading of the whole robot (SI units), as the HAL publishes it."""

    layout: Layout
    time: float
    q: np.ndarray
    tau: np.ndarray
    temperature: np.ndarray
    fresh_temperatures: Tuple[int, ...] = field(default=())


# -- quantization (pure, vectorized) ---------------------------------------------------


def quantize_encoders(q: np.ndarray) -> np.ndarray:
    codes = np.round((np.asarray(q, float) + ENCODER_RANGE) / (2 * ENCODER_RANGE) * 65536)
    return np.clip(np.nan_to_num(codes, nan=32768), 0, 65535).astype(np.int64)


def encoders_from_codes(codes: np.ndarray) -> np.ndarray:
    return codes.astype(float) / 65536 * (2 * ENCODER_RANGE) - ENCODER_RANGE


def quantize_torques(tau: np.ndarray) -> np.ndarray:
    """mu-law: sign in bit 7, log magnitude in bits 0..6."""
    tau = np.nan_to_num(np.asarray(tau, float))
    magnitude = np.minimum(np.abs(tau) / TORQUE_RANGE, 1.0)
    level = np.round(np.log1p(MU * magnitude) / math.log1p(MU) * 127).astype(np.int64)
    return np.where(tau < 0, level | 0x80, level)


def torques_from_codes(codes: np.ndarray) -> np.ndarray:
    level = (codes & 0x7F).astype(float) / 127
    magnitude = np.expm1(level * math.log1p(MU)) / MU * TORQUE_RANGE
    return np.where(codes & 0x80, -magnitude, magnitude)


def quantize_temperatures(temperature: np.ndarray) -> np.ndarray:
    codes = np.round((np.nan_to_num(np.asarray(temperature, float)) - TEMPERATURE_OFFSET) * 100)
    return np.clip(codes, 0, 65535).astype(np.int64)


def temperatures_from_codes(codes: np.ndarray) -> np.ndarray:
    return codes.astype(float) / 100 + TEMPERATURE_OFFSET


# -- field forms ---------------------------------------------------------------------


def _bitmap_deltas(new: np.ndarray, old: np.ndarray) -> bytes:
    changed = np.flatnonzero(new != old)
    bitmap = bytearray((len(new) + 7) // 8)
    out = bytearray()
    for index in changed.tolist():
        bitmap[index // 8] |= 1 << (index % 8)
        put_svarint(out, int(new[index]) - int(old[index]))
    return bytes(bitmap + out)


def _encode_field(new: np.ndarray, old: Optional[np.ndarray], width: int) -> Tuple[int, bytes]:
    raw = new.astype("<u2" if width == 2 else "u1").tobytes()
    if old is None:
        return _RAW, raw
    if np.array_equal(new, old):
        return _SAME, b""
    delta = _bitmap_deltas(new, old)
    return (_DELTA, delta) if len(delta) < len(raw) else (_RAW, raw)


def _decode_field(buf: Buffer, pos: int, mode: int, old: Optional[np.ndarray], count: int,
                  width: int, what: str) -> Tuple[np.ndarray, int]:
    if mode == _RAW:
        raw, pos = take(buf, pos, count * width, what)
        return np.frombuffer(raw, "<u2" if width == 2 else "u1").astype(np.int64), pos
    if old is None:
        raise BridgeProtocolError(f"{what}: a delta without a previous frame")
    if mode == _SAME:
        return old.copy(), pos
    if mode != _DELTA:
        raise BridgeProtocolError(f"{what}: unknown form {mode}")
    bitmap, pos = take(buf, pos, (count + 7) // 8, f"{what} bitmap")
    new = old.copy()
    limit = (1 << (8 * width)) - 1
    for index in range(count):
        if bitmap[index // 8] & (1 << (index % 8)):
            change, pos = get_svarint(buf, pos, f"{what} delta")
            value = int(old[index]) + change
            if not 0 <= value <= limit:
                raise BridgeProtocolError(f"{what}: joint {index} delta leaves the code range")
            new[index] = value
    if count % 8 and bitmap[-1] >> (count % 8):
        raise BridgeProtocolError(f"{what}: bitmap marks joints that do not exist")
    return new, pos


def _put_text(out: bytearray, text: str) -> None:
    data = text.encode()
    put_varint(out, len(data))
    out += data


def _get_text(buf: Buffer, pos: int, what: str) -> Tuple[str, int]:
    length, pos = get_varint(buf, pos, f"{what} length")
    if length > 255:
        raise BridgeProtocolError(f"{what} of {length} bytes")
    raw, pos = take(buf, pos, length, what)
    return raw.decode("utf-8", "replace"), pos


def _put_layout(out: bytearray, layout: Layout) -> None:
    put_varint(out, len(layout.chains))
    for name, joints in layout.chains:
        _put_text(out, name)
        put_varint(out, len(joints))
        for joint in joints:
            _put_text(out, joint)


def _get_layout(buf: Buffer, pos: int) -> Tuple[Layout, int]:
    chains, pos = get_varint(buf, pos, "chain count")
    if chains > 64:
        raise BridgeProtocolError(f"layout with {chains} chains")
    out = []
    for _ in range(chains):
        name, pos = _get_text(buf, pos, "chain name")
        count, pos = get_varint(buf, pos, "joint count")
        if count > 1024:
            raise BridgeProtocolError(f"chain with {count} joints")
        joints = []
        for _ in range(count):
            joint, pos = _get_text(buf, pos, "joint name")
            joints.append(joint)
        out.append((name, tuple(joints)))
    return Layout(tuple(out)), pos


# -- the two ends ----------------------------------------------------------------------


class _Context:
    """What both ends remember of the previous frame on one connection."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._layout: Optional[Layout] = None
        self._encoders: Optional[np.ndarray] = None
        self._torques: Optional[np.ndarray] = None
        self._temperatures: Optional[np.ndarray] = None
        self._time_ms = 0
        self._next_temperature = 0


class StateEncoder(_Context):
    """Robot side: one per connection (or :meth:`reset` when it is new)."""

    def __init__(self, period: float = 1.0) -> None:
        self.temperatures_per_frame = max(1, round(TEMPERATURES_PER_SECOND * period))
        super().__init__()

    def encode(self, state: RobotState) -> bytes:
        layout = state.layout
        count = layout.joints
        if len(state.q) != count or len(state.tau) != count or len(state.temperature) != count:
            raise ValueError(f"state vectors do not match the layout's {count} joints")
        key = layout != self._layout
        if key:
            self.reset()
        encoders = quantize_encoders(state.q)
        torques = quantize_torques(state.tau)
        temperatures = quantize_temperatures(state.temperature)
        encoder_mode, encoder_bytes = _encode_field(encoders, self._encoders, 2)
        torque_mode, torque_bytes = _encode_field(torques, self._torques, 1)
        out = bytearray([(KEY if key else 0) | encoder_mode << 1 | torque_mode << 3])
        time_ms = int(round(state.time * 1000))
        put_svarint(out, time_ms - self._time_ms)
        if key:
            _put_layout(out, layout)
        out += encoder_bytes
        out += torque_bytes
        if key:
            start, chosen = 0, list(range(count))
            known = np.zeros(count, np.int64)
        else:
            start = self._next_temperature % max(count, 1)
            chosen = [(start + offset) % count
                      for offset in range(min(self.temperatures_per_frame, count))]
            known = self._temperatures
        put_varint(out, start)
        put_varint(out, len(chosen))
        for index in chosen:
            put_svarint(out, int(temperatures[index]) - int(known[index]))
            known[index] = temperatures[index]
        self._temperatures = known
        self._next_temperature = (start + len(chosen)) % max(count, 1)
        self._layout, self._encoders, self._torques = layout, encoders, torques
        self._time_ms = time_ms
        return bytes(out)


class StateDecoder(_Context):
    """Pilot side: rebuilds :class:`RobotState` (the last known temperature of each joint)."""

    def decode(self, data: Buffer) -> RobotState:
        try:
            return self._decode(data)
        except NeedMoreData as exc:
            raise BridgeProtocolError(f"truncated robot state: {exc}") from None

    def _decode(self, data: Buffer) -> RobotState:
        """Decode against the previous frame; the context only changes on success."""
        if not data:
            raise BridgeProtocolError("empty robot state")
        header = data[0]
        if header & ~0x1F:
            raise BridgeProtocolError(f"robot state header {header:#x} has unknown bits")
        key = bool(header & KEY)
        change, pos = get_svarint(data, 1, "time")
        if key:
            layout, pos = _get_layout(data, pos)
            old_encoders = old_torques = None
            known = np.zeros(layout.joints, np.int64)
            time_ms = change
        elif self._layout is None:
            raise BridgeProtocolError("robot state delta before any key frame")
        else:
            layout, old_encoders, old_torques = self._layout, self._encoders, self._torques
            known = self._temperatures.copy()
            time_ms = self._time_ms + change
        count = layout.joints
        encoders, pos = _decode_field(data, pos, (header >> 1) & 3, old_encoders, count, 2,
                                      "encoders")
        torques, pos = _decode_field(data, pos, (header >> 3) & 3, old_torques, count, 1,
                                     "torques")
        start, pos = get_varint(data, pos, "temperature start")
        many, pos = get_varint(data, pos, "temperature count")
        if many > count or (count and start >= count) or (not count and start) or \
                (key and (start or many != count)):
            raise BridgeProtocolError(f"temperatures {start}+{many} do not fit {count} joints")
        fresh: List[int] = []
        for offset in range(many):
            index = (start + offset) % count
            change_t, pos = get_svarint(data, pos, "temperature")
            value = int(known[index]) + change_t
            if not 0 <= value <= 65535:
                raise BridgeProtocolError(f"temperature of joint {index} leaves the code range")
            known[index] = value
            fresh.append(index)
        if pos != len(data):
            raise BridgeProtocolError(f"{len(data) - pos} bytes after the robot state")
        self._layout, self._encoders, self._torques = layout, encoders, torques
        self._temperatures, self._time_ms = known, time_ms
        return RobotState(layout, time_ms / 1000.0, encoders_from_codes(encoders),
                          torques_from_codes(torques), temperatures_from_codes(known),
                          tuple(fresh))


def split_by_chain(layout: Layout, values: Sequence[float]) -> List[Tuple[str, np.ndarray]]:
    """Cut a whole-robot vector into the chains of ``layout``."""
    out, start = [], 0
    for name, count in layout.counts:
        out.append((name, np.asarray(values[start:start + count])))
        start += count
    return out
