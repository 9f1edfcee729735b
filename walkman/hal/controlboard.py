"""YARP 3.5's control-board protocol (``controlboardwrapper2``), as pure functions.

Theory of operation
-------------------
A YARP robot part is a *control board*: a device with the motor-control
interfaces (IPositionControl, IPositionDirect, IEncodersTimed, IControlMode,
...), remotized by the wrapper on four ports ``/<robot>/<chain>/``:

``rpc:i``       requests as Bottles of vocabs, answered by :func:`respond`,
                shaped as ``RPCMessagesParser.cpp`` shapes them: a get is
                ``[is] <what> <value...> [tsta] count time [ok]``, a set
                ``[ok]``, anything that failed or is not understood ``[fail]``.
``command:i``   streaming commands (``StreamingMessagesParser.cpp``): a
                PortablePair ``(head) (float64 vector)``, e.g.
                ``([dpos]) (q...)``, ``([dpog] n (joints)) (q...)``,
                ``([poss]) (q...)``, ``([vmos]) (v...)``; no reply.
``state:o``     the joint positions, a float64 Vector, with a Stamp envelope.
``stateExt:o``  ``jointData`` (22 fields: 11 vectors, each followed by an
                ``[ok]``/``[fail]`` validity), with the same envelope.

Units are YARP's: degrees, degrees/s, N*m.  What a device cannot do answers
``[fail]`` as the real wrapper answers it when its subdevice lacks the
interface.  Unlike the C++ parser, which dereferences missing lists, a
malformed request (an axis out of range, a list of the wrong length, a
missing field) is answered ``[fail]`` and reported through ``on_error`` with
what was wrong, so a peer's bytes never take the HAL down.

Our own additions, which standard clients neither send nor see:
a streaming head may end with ``(seq N)``, the state count the command
answers (the HAL measures sense->move latency with it); see
:func:`stream_seq`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, Tuple

from yarp_lite.bottle import Bottle, Vocab

PROTOCOL_VERSION = (1, 9, 0)  # ControlBoardWrapperCommon.h of YARP 3.5

OK, FAIL, IS, TIMESTAMP = Vocab("ok"), Vocab("fail"), Vocab("is"), Vocab("tsta")

#: Control modes (IControlMode) and interaction modes, as vocabs.
MODE_POSITION, MODE_DIRECT, MODE_VELOCITY, MODE_TORQUE = "pos", "posd", "vel", "torq"
MODE_IDLE, MODE_FORCE_IDLE, MODE_HW_FAULT = "idl", "fidl", "hwfa"
INTERACTION_STIFF, INTERACTION_COMPLIANT = "stif", "comp"
#: PID types of IPidControl: position, velocity, torque, current.
PID_TYPES = ("pos", "vel", "trq", "cur")

#: ``[get] X ...`` of the default branch whose value is one float per joint:
#: single-joint vocab -> (all-joints vocab, group vocab, device vector name).
JOINT_VECTORS = {
    "enc": ("encs", None, "encoders"),
    "esp": ("esps", None, "encoder_speeds"),
    "eac": ("eacs", None, "encoder_accelerations"),
    "pos": ("poss", "posg", "target_positions"),
    "dpo": ("dpos", "dpog", "direct_references"),
    "vmo": ("vmos", "vmog", "velocity_references"),
    "vel": ("vels", "velg", "ref_speeds"),
    "acc": ("accs", "accg", "ref_accelerations"),
    "tmp": ("tmps", None, "temperatures"),
}
_EVERY = {every: vector for every, _, vector in JOINT_VECTORS.values()}
_GROUPS = {group: vector for _, group, vector in JOINT_VECTORS.values() if group}
#: ``[set] X j v`` / ``[set] Xs (v...)`` / ``[set] Xg n (j...) (v...)``: position
#: moves, relative moves, reference speeds and accelerations (IPositionControl).
SETTERS = {
    "pos": ("poss", "posg", "position_move"),
    "rel": ("rels", "relg", "relative_move"),
    "vel": ("vels", "velg", "set_ref_speeds"),
    "acc": ("accs", "accg", "set_ref_accelerations"),
}


class ControlBoardError(Exception):
    """A request the protocol cannot carry out (the reply is ``[fail]``)."""


@dataclass
class Stamp:
    """YARP's Stamp: a count and a time, sent as an envelope ``"count time"``."""

    count: int = 0
    time: float = 0.0

    def update(self, time_s: float) -> "Stamp":
        self.count = (self.count + 1) % (2 ** 31 - 1)
        self.time = time_s
        return self

    def envelope(self) -> str:
        return f"{self.count} {self.time!r}"

    @classmethod
    def from_envelope(cls, text: str) -> Optional["Stamp"]:
        parts = text.split()
        try:
            return cls(int(parts[0]), float(parts[1])) if len(parts) == 2 else None
        except ValueError:
            return None


class ControlBoardDevice(ABC):
    """What a robot part must offer to be served: YARP's interfaces, vectorised.

    Values in YARP's units (degrees); ``joints`` are axis indices, already
    checked by the parser.  Methods a device lacks raise
    :class:`ControlBoardError`, answered ``[fail]``.
    """

    @abstractmethod
    def axes(self) -> int: ...

    @abstractmethod
    def vector(self, name: str) -> List[float]:
        """A per-joint vector by name (``encoders``, ``temperatures``, ... see JOINT_VECTORS)."""

    @abstractmethod
    def axis_name(self, axis: int) -> str: ...

    def joint_type(self, axis: int) -> int:
        from yarp_lite.bottle import vocab_encode

        return vocab_encode("atrv")  # VOCAB_JOINTTYPE_REVOLUTE, sent as an int32

    @abstractmethod
    def limits(self, axis: int) -> Tuple[float, float]: ...

    def velocity_limits(self, axis: int) -> Tuple[float, float]:
        raise ControlBoardError("no velocity limits")

    @abstractmethod
    def torques(self) -> List[float]: ...

    def torque_range(self, axis: int) -> Tuple[float, float]:
        raise ControlBoardError("no torque ranges")

    @abstractmethod
    def control_modes(self) -> List[str]: ...

    @abstractmethod
    def set_control_modes(self, joints: Sequence[int], modes: Sequence[str],
                          owner: str = "") -> None: ...

    def interaction_modes(self) -> List[str]:
        return [INTERACTION_STIFF] * self.axes()

    def set_interaction_modes(self, joints: Sequence[int], modes: Sequence[str]) -> None:
        raise ControlBoardError("interaction modes cannot be changed")

    def pid(self, pid_type: str, axis: int) -> List[float]:
        """kp kd ki max_int max_output offset scale stiction_up stiction_down kff."""
        raise ControlBoardError("no PIDs")

    @abstractmethod
    def motion_done(self, joints: Sequence[int]) -> bool: ...

    @abstractmethod
    def command(self, what: str, joints: Sequence[int], values: Sequence[float],
                owner: str = "", seq: Optional[int] = None) -> None:
        """A move: ``position_move``, ``relative_move``, ``set_ref_speeds``,
        ``set_ref_accelerations``, ``direct`` (position direct), ``velocity_move``
        or ``stop`` (values empty).  ``owner`` names the sender (arbitration)."""


# -- the rpc:i parser --------------------------------------------------------------------


class _Malformed(ControlBoardError):
    """The request's shape is wrong (answered [fail], reported)."""


def respond(device: ControlBoardDevice, request: Bottle, stamp: Stamp, now: float,
            owner: str = "", on_error: Callable[[str], None] = lambda text: None) -> Bottle:
    """The wrapper's answer to one ``rpc:i`` request (``RPCMessagesParser::respond``)."""
    if len(request) < 2:  # the real wrapper's port answers a lone word (help too) so
        on_error(f"not understood: {request.to_text()[:120]}")
        return Bottle([Vocab("nak")])
    try:
        reply = _respond(device, request, stamp, now, owner)
    except _Malformed as exc:
        on_error(f"malformed request {request.to_text()[:120]}: {exc}")
        return Bottle([FAIL])
    except ControlBoardError as exc:
        on_error(f"{request.to_text()[:120]}: {exc}")
        return Bottle([FAIL])
    if reply is None:
        on_error(f"not understood: {request.to_text()[:120]}")
        return Bottle([FAIL])
    reply.append(OK)
    return reply


def _vocab(request: Bottle, index: int) -> str:
    """A vocab, or a string as YARP's ``asVocab32`` reads it (``yarp rpc`` sends words
    as strings: ``get axes`` works like ``[get] [axes]``)."""
    value = request[index] if len(request) > index else None
    if isinstance(value, Vocab):
        return str(value)
    return value[:4] if isinstance(value, str) else ""


def _axis(device: ControlBoardDevice, request: Bottle, index: int) -> int:
    value = request[index] if len(request) > index else None
    if not isinstance(value, int) or isinstance(value, (bool, Vocab)):
        raise _Malformed(f"item {index} must be an axis number, got {value!r}")
    if not 0 <= value < device.axes():
        raise _Malformed(f"axis {value} out of range 0..{device.axes() - 1}")
    return int(value)


def _number(request: Bottle, index: int) -> float:
    value = request[index] if len(request) > index else None
    if isinstance(value, (int, float)) and not isinstance(value, (bool, Vocab)) \
            and math.isfinite(value):
        return float(value)
    raise _Malformed(f"item {index} must be a finite number, got {value!r}")


def _list(request: Bottle, index: int, length: Optional[int] = None) -> list:
    value = request[index] if len(request) > index else None
    if not isinstance(value, list):
        raise _Malformed(f"item {index} must be a list, got {value!r}")
    if length is not None and len(value) != length:
        raise _Malformed(f"item {index} has {len(value)} values, expected {length}")
    return value


def _numbers(request: Bottle, index: int, length: int) -> List[float]:
    values = _list(request, index, length)
    return [_number(Bottle(values), k) for k in range(len(values))]


def _group(device: ControlBoardDevice, request: Bottle, index: int) -> List[int]:
    """``n (j...)`` at ``index``: a joint list with its announced length."""
    count = request[index] if len(request) > index else None
    if not isinstance(count, int) or isinstance(count, Vocab):
        raise _Malformed(f"item {index} must be a joint count, got {count!r}")
    joints = _list(request, index + 1, count)
    return [_axis(device, Bottle(joints), k) for k in range(len(joints))]


def _stamped(reply: Bottle, stamp: Stamp, now: float) -> Bottle:
    stamp.update(now)
    reply.extend((TIMESTAMP, stamp.count, stamp.time))
    return reply


def _respond(device: ControlBoardDevice, request: Bottle, stamp: Stamp, now: float,
             owner: str) -> Optional[Bottle]:
    code, interface = _vocab(request, 0), _vocab(request, 1)
    if interface == "prot":
        return Bottle([Vocab("prot"), *PROTOCOL_VERSION]) if code == "get" else None
    if interface == "icmd":
        return _control_mode(device, request, code, stamp, now, owner)
    if interface == "intm":
        return _interaction_mode(device, request, code, stamp, now)
    if interface == "torq":
        return _torque(device, request, code, stamp, now)
    if interface == "pid":
        return _pid(device, request, code)
    if interface in ("iimp", "reca", "ivar", "icur", "ipwm"):
        raise ControlBoardError(f"this robot has no [{interface}] interface")
    if code == "get":
        return _get(device, request, interface, stamp, now)
    if code == "set":
        return _set(device, request, interface, owner)
    return None


def _get(device: ControlBoardDevice, request: Bottle, what: str, stamp: Stamp,
         now: float) -> Optional[Bottle]:
    reply = Bottle([IS, request[1]])
    axes = device.axes()
    if what in JOINT_VECTORS:
        reply.append(float(device.vector(JOINT_VECTORS[what][2])[_axis(device, request, 2)]))
    elif what in _EVERY:
        reply.append(Bottle(float(v) for v in device.vector(_EVERY[what])))
    elif what in _GROUPS:
        vector = device.vector(_GROUPS[what])
        reply.append(Bottle(float(vector[j]) for j in _group(device, request, 2)))
    elif what == "axes":
        reply.append(axes)
    elif what == "don":
        reply.append(int(device.motion_done([_axis(device, request, 2)])))
    elif what == "dons":
        reply.append(int(device.motion_done(range(axes))))
    elif what == "dong":
        reply.append(int(device.motion_done(_group(device, request, 2))))
    elif what == "llim":
        reply.extend(float(v) for v in device.limits(_axis(device, request, 2)))
    elif what == "vlim":
        reply.extend(float(v) for v in device.velocity_limits(_axis(device, request, 2)))
    elif what == "name":
        reply.append(device.axis_name(_axis(device, request, 2)))
    elif what == "type":
        reply.append(device.joint_type(_axis(device, request, 2)))
    else:
        raise ControlBoardError(f"[get] [{what}] is not served by this robot")
    return _stamped(reply, stamp, now)


def _set(device: ControlBoardDevice, request: Bottle, what: str, owner: str) -> Optional[Bottle]:
    axes = device.axes()
    for single, (every, group, method) in SETTERS.items():
        if what == single:
            device.command(method, [_axis(device, request, 2)], [_number(request, 3)], owner)
        elif what == every:
            device.command(method, range(axes), _numbers(request, 2, axes), owner)
        elif what == group:
            joints = _group(device, request, 2)
            device.command(method, joints, _numbers(request, 4, len(joints)), owner)
        else:
            continue
        return Bottle()
    if what == "vmos":
        device.command("velocity_move", range(axes), _numbers(request, 2, axes), owner)
    elif what == "sto":
        device.command("stop", [_axis(device, request, 2)], [], owner)
    elif what == "stos":
        device.command("stop", range(axes), [], owner)
    elif what == "stog":
        device.command("stop", _group(device, request, 2), [], owner)
    else:
        raise ControlBoardError(f"[set] [{what}] is not served by this robot")
    return Bottle()


def _modes(request: Bottle, index: int, length: int) -> List[str]:
    values = _list(request, index, length)
    if not all(isinstance(v, str) for v in values):
        raise _Malformed(f"item {index} must hold mode vocabs, got {values}")
    return [_vocab(Bottle(values), k) for k in range(len(values))]


def _control_mode(device: ControlBoardDevice, request: Bottle, code: str, stamp: Stamp,
                  now: float, owner: str) -> Optional[Bottle]:
    method, axes = _vocab(request, 2), device.axes()
    if code == "set":
        if method == "cmog":
            joints = _group(device, request, 3)
            device.set_control_modes(joints, _modes(request, 5, len(joints)), owner)
        elif method == "cmds":
            device.set_control_modes(range(axes), _modes(request, 3, axes), owner)
        else:  # cmod, and the legacy form [set] [icmd] <anything> j mode
            device.set_control_modes([_axis(device, request, 3)], [_vocab(request, 4)], owner)
        return Bottle()
    if code != "get":
        return None
    modes = device.control_modes()
    if method == "cmds":
        reply = Bottle([IS, Vocab("cmds"), Bottle(Vocab(m) for m in modes)])
    elif method == "cmod":
        axis = _axis(device, request, 3)
        reply = Bottle([IS, axis, Vocab(modes[axis])])
    elif method == "cmog":
        reply = Bottle([IS, Vocab("cmog"),
                        Bottle(Vocab(modes[j]) for j in _group(device, request, 3))])
    else:  # the real wrapper logs it and answers a bare timestamp and [ok]
        reply = Bottle()
    return _stamped(reply, stamp, now)


def _interaction_mode(device: ControlBoardDevice, request: Bottle, code: str, stamp: Stamp,
                      now: float) -> Optional[Bottle]:
    method, axes = _vocab(request, 2), device.axes()
    if code == "set":
        if method == "mode":
            device.set_interaction_modes([_axis(device, request, 3)], [_vocab(request, 4)])
        elif method == "modg":
            joints = _group(device, request, 3)
            device.set_interaction_modes(joints, _modes(request, 5, len(joints)))
        elif method == "mods":
            device.set_interaction_modes(range(axes), _modes(request, 3, axes))
        else:
            raise ControlBoardError(f"[set] [intm] [{method}] is not understood")
        return Bottle()
    if code != "get":
        raise _Malformed("an interaction-mode request must be [get] or [set]")
    modes = device.interaction_modes()
    if method == "mode":
        reply = Bottle([Vocab(modes[_axis(device, request, 3)])])
    elif method == "modg":
        reply = Bottle([Bottle(Vocab(modes[j]) for j in _group(device, request, 3))])
    elif method == "mods":
        reply = Bottle([Bottle(Vocab(m) for m in modes)])
    else:
        raise ControlBoardError(f"[get] [intm] [{method}] is not understood")
    return _stamped(reply, stamp, now)


def _torque(device: ControlBoardDevice, request: Bottle, code: str, stamp: Stamp,
            now: float) -> Optional[Bottle]:
    if code != "get":
        raise ControlBoardError("torque control is not offered: the joints are position servos")
    method = _vocab(request, 2)
    reply = Bottle([IS, request[1]])
    if method == "axes":
        reply.append(device.axes())
    elif method == "trq":
        reply.append(float(device.torques()[_axis(device, request, 3)]))
    elif method == "trqs":
        reply.append(Bottle(float(v) for v in device.torques()))
    elif method == "rng":
        reply.extend(float(v) for v in device.torque_range(_axis(device, request, 3)))
    elif method == "rngs":
        ranges = [device.torque_range(j) for j in range(device.axes())]
        reply.append(Bottle(low for low, _ in ranges))
        reply.append(Bottle(high for _, high in ranges))
    else:
        raise ControlBoardError(f"[get] [torq] [{method}] is not served by this robot")
    return _stamped(reply, stamp, now)


def _pid(device: ControlBoardDevice, request: Bottle, code: str) -> Optional[Bottle]:
    if code != "get":
        raise ControlBoardError("PIDs are read-only on this robot")
    method, pid_type = _vocab(request, 2), _vocab(request, 3)
    if pid_type not in PID_TYPES:
        raise _Malformed(f"item 3 must be a PID type {PID_TYPES}, got {request[3:4]}")
    reply = Bottle([IS, request[1]])
    if method == "pid":
        reply.append(Bottle(float(v) for v in device.pid(pid_type, _axis(device, request, 4))))
    elif method == "pids":
        reply.append(Bottle(Bottle(float(v) for v in device.pid(pid_type, j))
                            for j in range(device.axes())))
    else:
        raise ControlBoardError(f"[get] [pid] [{method}] is not served by this robot")
    return reply


# -- command:i (streaming) ----------------------------------------------------------------


@dataclass(frozen=True)
class StreamCommand:
    what: str                  # a ControlBoardDevice.command verb
    joints: Tuple[int, ...]
    values: Tuple[float, ...]
    seq: Optional[int] = None  # our extension: the state count this answers


#: Streaming head vocab -> (device verb, index of the joint count in the head or
#: None for every joint, or "single" for ``[dpo] j`` / ``[vmo] j``).
STREAMS = {
    "dpos": ("direct", None), "dpog": ("direct", 1), "dpo": ("direct", "single"),
    "poss": ("position_move", None),
    "vmos": ("velocity_move", None), "vmog": ("velocity_move", 1),
    "vmo": ("velocity_move", "single"),
}


def stream_seq(head: Sequence[object]) -> Optional[int]:
    """Our extension: a head ending in ``(seq N)`` names the state it answers."""
    last = head[-1] if head else None
    if isinstance(last, list) and len(last) == 2 and str(last[0]) == "seq" \
            and isinstance(last[1], int):
        return int(last[1])
    return None


def decode_stream(message: Bottle, axes: int) -> StreamCommand:
    """Validate one ``command:i`` message (raises ControlBoardError naming the problem)."""
    if len(message) != 2 or not isinstance(message[0], list) or not isinstance(message[1], list):
        raise ControlBoardError(f"a streaming command is (head) (values): {message.to_text()[:80]}")
    head, body = Bottle(message[0]), message[1]
    verb = _vocab(head, 0)
    if verb not in STREAMS:
        raise ControlBoardError(f"streaming command [{verb or head[:1]}] is not served; "
                                f"try {', '.join('[' + k + ']' for k in STREAMS)}")
    what, count_at = STREAMS[verb]
    if len(body) > axes:
        raise ControlBoardError(f"[{verb}] carries {len(body)} values for {axes} axes")
    values = tuple(_numbers(Bottle([body]), 0, len(body)))
    try:
        if count_at is None:
            joints: Tuple[int, ...] = tuple(range(axes))
        elif count_at == "single":
            joints = (_axis(_Axes(axes), head, 1),)
        else:
            joints = tuple(_group(_Axes(axes), head, int(count_at)))
    except _Malformed as exc:
        raise ControlBoardError(f"[{verb}]: {exc}") from None
    if len(values) != len(joints):
        raise ControlBoardError(f"[{verb}] has {len(values)} values for {len(joints)} joints")
    return StreamCommand(what, joints, values, stream_seq(head))


class _Axes:
    """Just enough of a device for the index checks of decode_stream."""

    def __init__(self, axes: int) -> None:
        self._axes = axes

    def axes(self) -> int:
        return self._axes


def encode_stream(what: str, values: Sequence[float], joints: Optional[Sequence[int]] = None,
                  seq: Optional[int] = None) -> Bottle:
    """A streaming command as a client sends it: ``direct``, ``position_move``, ``velocity_move``."""
    every = {"direct": "dpos", "position_move": "poss", "velocity_move": "vmos"}[what]
    group = {"direct": "dpog", "velocity_move": "vmog"}.get(what)
    if joints is None:
        head = Bottle([Vocab(every)])
    elif group is None:
        raise ControlBoardError(f"{what} streams every joint; use rpc for a group")
    else:
        head = Bottle([Vocab(group), len(joints), Bottle(int(j) for j in joints)])
    if seq is not None:
        head.append(Bottle(["seq", int(seq)]))
    return Bottle([head, Bottle(float(v) for v in values)])


# -- stateExt:o (jointData) -------------------------------------------------------------

JOINT_DATA_FIELDS = ("jointPosition", "jointVelocity", "jointAcceleration", "motorPosition",
                     "motorVelocity", "motorAcceleration", "torque", "pwmDutycycle", "current",
                     "controlMode", "interactionMode")


@dataclass(frozen=True)
class JointData:
    """``yarp::dev::impl::jointData``: None marks a field not valid."""

    position: Optional[Tuple[float, ...]]
    velocity: Optional[Tuple[float, ...]] = None
    acceleration: Optional[Tuple[float, ...]] = None
    torque: Optional[Tuple[float, ...]] = None
    control_modes: Optional[Tuple[str, ...]] = None
    interaction_modes: Optional[Tuple[str, ...]] = None


def encode_joint_data(data: JointData, axes: int) -> Bottle:
    """The 22 fields, in the order of jointData.thrift; an invalid field is zeros + [fail]."""
    from yarp_lite.bottle import Int32, vocab_encode

    floats = {"jointPosition": data.position, "jointVelocity": data.velocity,
              "jointAcceleration": data.acceleration, "torque": data.torque}
    codes = {"controlMode": data.control_modes, "interactionMode": data.interaction_modes}
    out = Bottle()
    for field in JOINT_DATA_FIELDS:
        if field in codes:
            modes = codes[field]
            out.append(Bottle(Int32(vocab_encode(m)) for m in modes) if modes is not None
                       else Bottle(Int32(0) for _ in range(axes)))
            valid = modes is not None
        else:
            values = floats.get(field)
            out.append(Bottle(float(v) for v in values) if values is not None
                       else Bottle(0.0 for _ in range(axes)))
            valid = values is not None
        out.append(OK if valid else FAIL)
    return out


def decode_joint_data(bottle: Bottle) -> JointData:
    """Read ``stateExt:o`` (raises ControlBoardError when it is not a jointData)."""
    from yarp_lite.bottle import vocab_decode

    if len(bottle) != 2 * len(JOINT_DATA_FIELDS):
        raise ControlBoardError(f"jointData has 22 fields, got {len(bottle)}")
    axes = len(bottle[0]) if isinstance(bottle[0], list) else 0
    fields = {}
    for k, name in enumerate(JOINT_DATA_FIELDS):
        values, valid = bottle[2 * k], bottle[2 * k + 1]
        if not isinstance(values, list) or str(valid) not in ("ok", "fail"):
            raise ControlBoardError(f"jointData field {name} is malformed")
        if str(valid) == "ok" and len(values) != axes:
            raise ControlBoardError(f"jointData field {name} has {len(values)} values, "
                                    f"jointPosition {axes}")
        if name in ("controlMode", "interactionMode"):
            if not all(isinstance(v, int) for v in values):
                raise ControlBoardError(f"jointData field {name} must hold int32 codes")
            fields[name] = tuple(vocab_decode(int(v)) for v in values) if str(valid) == "ok" \
                else None
        else:
            if not all(isinstance(v, float) for v in values):
                raise ControlBoardError(f"jointData field {name} must hold float64 values")
            fields[name] = tuple(values) if str(valid) == "ok" else None
    return JointData(fields["jointPosition"], fields["jointVelocity"],
                     fields["jointAcceleration"], fields["torque"], fields["controlMode"],
                     fields["interactionMode"])
