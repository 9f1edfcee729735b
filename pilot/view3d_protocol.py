"""What the PI and its 3-D view's render process say to each other, sans-IO: JSON lines.

Theory of operation
-------------------
librviz runs in a child process (:mod:`pilot.view3d_child`) so that when it
crashes -- the llvmpipe heap corruption of issue 31 -- only the picture goes,
not the PI.  The PI owns what must survive a crash (the pose markers and where
the pilot left them, which displays are switched off) and tells every new
child again; the child owns nothing it cannot be told.  The two talk over one
stream socket, one JSON object per line (UTF-8, ``\\n``-terminated)::

    PI -> child   {"type": "go", "forget": ["/pi_view3d_<pid>", "/rviz_..."]}   (be the view:
                      build librviz's frame; first unregister a dead view's ROS nodes)
                  {"type": "add", "name": "drc_valve", "pose": [x, y, z, roll, pitch, yaw]}
                  {"type": "update", "name": ..., "pose": [...]}   (move an existing marker)
                  {"type": "remove", "name": ...}
                  {"type": "display", "name": "Cloud", "enabled": false}
                  {"type": "ping", "seq": 7}
    child -> PI   {"type": "window", "window": <X window id>, "pid": <pid>}   (embed me)
                  {"type": "nodes", "node": "/pi_view3d_<pid>",
                   "librviz": {"/rviz_...": "http://...:port/"}}  (the child's rospy node and
                      librviz's roscpp one: the next child unregisters them after a crash)
                  {"type": "moved", "name": ..., "pose": [...]}   (the pilot dragged it)
                  {"type": "pong", "seq": 7}

Poses are in the pelvis frame, metres and radians, always six finite numbers.
Nothing here touches a socket: :func:`encode` gives the bytes of a message,
and a :class:`Decoder` takes bytes as they arrive and gives whole messages,
never half of one (a line is consumed only once its ``\\n`` is there).  Each
decoder reads one direction: a child's message arriving at the child is the
peer's error.  :class:`LocalProtocolError` means we misused this API (a NaN
pose, an unknown message); :class:`RemoteProtocolError` means the peer sent
something illegal, and names the line's bad field -- the stream is then dead
(the PI kills the child, which restarts).
"""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple, Type, Union

from nodekit.scene import KINDS

#: A line longer than this is the peer's error (the longest real one, ``nodes``, is ~200 B).
MAX_LINE = 64 * 1024

Pose = Tuple[float, float, float, float, float, float]


class ProtocolError(Exception):
    """A message of the 3-D view's protocol could not be made or read."""


class LocalProtocolError(ProtocolError):
    """We asked for something the protocol cannot say (a bug of the caller)."""


class RemoteProtocolError(ProtocolError):
    """The peer sent bytes that are not a legal message in this direction."""


class Direction(enum.Enum):
    TO_CHILD = "PI -> child"
    TO_PI = "child -> PI"


# -- messages: PI -> child ------------------------------------------------------------------

@dataclass(frozen=True)
class Go:
    """Be the view now: build librviz's frame.  A child waits for it, so the PI can keep one
    warmed up (Python, Qt, librviz loaded, ROS registered) to take over from a dead one;
    ``forget`` are the dead one's ROS nodes, to unregister."""

    forget: Tuple[str, ...] = ()


@dataclass(frozen=True)
class AddMarker:
    """A draggable 6-DOF marker named ``name`` at ``pose`` (replaces one of that name),
    drawn as the object it stands for (``kind``: one of :data:`MARKER_KINDS`)."""

    name: str
    pose: Pose
    kind: str = "disc"


@dataclass(frozen=True)
class UpdateMarker:
    """Move the marker ``name`` to ``pose`` (the pilot typed it); unknown names are ignored."""

    name: str
    pose: Pose


@dataclass(frozen=True)
class RemoveMarker:
    name: str


@dataclass(frozen=True)
class EnableDisplay:
    """Switch one of :data:`pilot.view3d_child.RVIZ_CONFIG`'s displays on or off."""

    name: str
    enabled: bool


@dataclass(frozen=True)
class Ping:
    """Is the child's GUI thread alive?  It answers :class:`Pong` with the same ``seq``."""

    seq: int


# -- messages: child -> PI ------------------------------------------------------------------

@dataclass(frozen=True)
class WindowReady:
    """librviz's frame is made and shown off-screen: embed X window ``window``."""

    window: int
    pid: int


@dataclass(frozen=True)
class RosNodes:
    """The child's ROS nodes: its rospy node's name, librviz's roscpp node(s) name -> URI."""

    node: str
    librviz: Dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class MarkerMoved:
    """The pilot dragged marker ``name`` to ``pose``."""

    name: str
    pose: Pose


@dataclass(frozen=True)
class Pong:
    seq: int


ToChild = Union[Go, AddMarker, UpdateMarker, RemoveMarker, EnableDisplay, Ping]
ToPi = Union[WindowReady, RosNodes, MarkerMoved, Pong]
Message = Union[ToChild, ToPi]

#: The wire name of each message, and the direction it travels in.
TYPES: Dict[str, Tuple[Type[Any], Direction]] = {
    "go": (Go, Direction.TO_CHILD), "add": (AddMarker, Direction.TO_CHILD), "update": (UpdateMarker, Direction.TO_CHILD),
    "remove": (RemoveMarker, Direction.TO_CHILD), "display": (EnableDisplay, Direction.TO_CHILD),
    "ping": (Ping, Direction.TO_CHILD),
    "window": (WindowReady, Direction.TO_PI), "nodes": (RosNodes, Direction.TO_PI),
    "moved": (MarkerMoved, Direction.TO_PI), "pong": (Pong, Direction.TO_PI),
}
_NAMES = {cls: name for name, (cls, _) in TYPES.items()}


# -- fields: one check per kind, used both ways ---------------------------------------------

def _name(value: Any) -> str:
    if not isinstance(value, str) or not value or len(value) > 200:
        raise ValueError(f"must be a non-empty string of at most 200 characters, "
                         f"got {value!r:.60}")
    return value


def _pose(value: Any) -> Pose:
    if not isinstance(value, (list, tuple)) or len(value) != 6 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in value):
        raise ValueError(f"must be 6 finite numbers (x y z roll pitch yaw), got {value!r:.80}")
    return tuple(float(v) for v in value)  # type: ignore[return-value]


#: How a marker is drawn: the shared scene's kinds of object, or the plain disc of a pose
#: without an object.
MARKER_KINDS = ("disc", *KINDS)


def _kind(value: Any) -> str:
    if value not in MARKER_KINDS:
        raise ValueError(f"must be one of {', '.join(MARKER_KINDS)}, got {value!r:.40}")
    return value


def _int(value: Any) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < 1 << 63:
        raise ValueError(f"must be a whole number 0 <= n < 2**63, got {value!r:.60}")
    return value


def _bool(value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"must be true or false, got {value!r:.60}")
    return value


def _names(value: Any) -> Tuple[str, ...]:
    if not isinstance(value, (list, tuple)) or len(value) > 100:
        raise ValueError(f"must be a list of at most 100 names, got {value!r:.80}")
    return tuple(_name(v) for v in value)


def _nodes(value: Any) -> Dict[str, str]:
    if not isinstance(value, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                              for k, v in value.items()):
        raise ValueError(f"must map node names to URIs (strings), got {value!r:.80}")
    return dict(value)


#: Each message's fields and their checks, in wire order.
FIELDS: Dict[Type[Any], Dict[str, Any]] = {
    Go: {"forget": _names},
    AddMarker: {"name": _name, "pose": _pose, "kind": _kind},
    UpdateMarker: {"name": _name, "pose": _pose},
    RemoveMarker: {"name": _name}, EnableDisplay: {"name": _name, "enabled": _bool},
    Ping: {"seq": _int}, WindowReady: {"window": _int, "pid": _int},
    RosNodes: {"node": _name, "librviz": _nodes}, MarkerMoved: {"name": _name, "pose": _pose},
    Pong: {"seq": _int},
}


def encode(message: Message) -> bytes:
    """One line of UTF-8 JSON; :class:`LocalProtocolError` for what the protocol cannot say."""
    kind = _NAMES.get(type(message))
    if kind is None:
        raise LocalProtocolError(f"not a message of the 3-D view's protocol: {message!r:.80}")
    body: Dict[str, Any] = {"type": kind}
    for name, check in FIELDS[type(message)].items():
        try:
            value = check(getattr(message, name))
        except ValueError as exc:
            raise LocalProtocolError(f"{kind}: field {name!r} {exc}") from None
        body[name] = list(value) if isinstance(value, tuple) else value
    line = json.dumps(body, allow_nan=False, separators=(",", ":")).encode() + b"\n"
    if len(line) > MAX_LINE:
        raise LocalProtocolError(f"{kind}: {len(line)} bytes, over the {MAX_LINE}-byte limit")
    return line


def decode_line(line: bytes, direction: Direction) -> Message:
    """One line (without its ``\\n``) read in ``direction``; :class:`RemoteProtocolError`
    naming what is wrong with it."""
    try:
        body = json.loads(line.decode("utf-8"), parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError) as exc:
        raise RemoteProtocolError(f"{direction.value}: not a JSON line ({exc}): "
                                  f"{line[:60]!r}") from None
    if not isinstance(body, dict):
        raise RemoteProtocolError(f"{direction.value}: a line must be a JSON object, "
                                  f"got {line[:60]!r}")
    kind = body.get("type")
    known = TYPES.get(kind) if isinstance(kind, str) else None
    if known is None:
        raise RemoteProtocolError(f"{direction.value}: unknown message type {kind!r:.40}")
    cls, travels = known
    if travels is not direction:
        raise RemoteProtocolError(f"{direction.value}: {kind!r} travels {travels.value} only")
    checks = FIELDS[cls]
    extra = set(body) - set(checks) - {"type"}
    if extra:
        raise RemoteProtocolError(f"{direction.value}: {kind}: unknown field(s) "
                                  f"{sorted(extra)!r:.80}")
    values = {}
    for name, check in checks.items():
        if name not in body:
            raise RemoteProtocolError(f"{direction.value}: {kind}: field {name!r} missing")
        try:
            values[name] = check(body[name])
        except ValueError as exc:
            raise RemoteProtocolError(f"{direction.value}: {kind}: field {name!r} {exc}") \
                from None
    return cls(**values)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


class Decoder:
    """Bytes in, whole messages out, for one direction; never consumes half a line."""

    def __init__(self, direction: Direction) -> None:
        self.direction = direction
        self._buffer = bytearray()
        self._ended = False
        self._error: Optional[RemoteProtocolError] = None

    def feed(self, data: bytes) -> None:
        """Bytes as they arrived; ``b""`` means the peer closed the stream."""
        if self._ended and data:
            raise LocalProtocolError("data after the end of the stream")
        if not data:
            self._ended = True
        self._buffer += data

    @property
    def ended(self) -> bool:
        """The peer closed the stream and every whole line has been read."""
        return self._ended and not self._buffer

    def next_message(self) -> Optional[Message]:
        """The next whole message, or None until more bytes arrive (or after the end)."""
        if self._error is not None:
            raise self._error
        end = self._buffer.find(b"\n")
        if end < 0:
            if len(self._buffer) > MAX_LINE:
                self._fail(f"{self.direction.value}: a line of over {MAX_LINE} bytes")
            if self._ended and self._buffer:
                self._fail(f"{self.direction.value}: the stream ended in the middle of a "
                           f"line: {bytes(self._buffer[:60])!r}")
            return None
        if end > MAX_LINE:
            self._fail(f"{self.direction.value}: a line of {end} bytes, over {MAX_LINE}")
        line = bytes(self._buffer[:end])
        try:
            message = decode_line(line, self.direction)
        except RemoteProtocolError as exc:
            self._error = exc
            raise
        del self._buffer[:end + 1]
        return message

    def messages(self) -> List[Message]:
        """Every whole message buffered now."""
        out = []
        while True:
            message = self.next_message()
            if message is None:
                return out
            out.append(message)

    def _fail(self, why: str) -> None:
        self._error = RemoteProtocolError(why)
        raise self._error
