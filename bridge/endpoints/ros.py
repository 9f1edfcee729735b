"""ROS endpoints: topics with the original names on each side's roscore.

Theory of operation
-------------------
The node itself is :class:`nodekit.ros_node.RosNode` (shared with the ROS
nodes and the Pilot Interface).

:class:`RosSink` subscribes to a topic on the side where data starts and posts
each message to the UDP channel; :class:`RosSource` publishes on the other
side what arrives.  A message whose ``callerid`` is our own node is one we
published, so it is never sent back (no republish loops when both directions
carry the same name).  Latched topics keep their last message, which is sent
again when the link comes back and every few seconds, and the receiving side
publishes it latched -- once, unless it changed.

Images and point clouds are tiled (:mod:`bridge.wire.tiles`): a partial frame is
published with its missing regions black (images), NaN (float images) or NaN
points (clouds, marked ``is_dense = False``).  Black and NaN are also content
(a night sky, a point without depth), so the receiving side says what was lost:
just before each tiled frame it publishes a ``walkman_msgs/Arrival`` on
``<topic>/arrived`` (:func:`arrival_topic`) with the frame's header, the
fraction of cells that arrived and rectangles covering exactly the missing
ones.  Every other type travels as its serialized bytes, whole or not at all.
"""

from __future__ import annotations

import hashlib
import logging
import time
from dataclasses import dataclass
from io import BytesIO
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from bridge.config import Channel
from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.wire import compact, tiles
from yarp_lite.bottle import Bottle

log = logging.getLogger("bridge.ros")

LATCH_REPEAT = 5.0

# sensor_msgs/Image encodings this bridge can tile: (dtype, channels)
IMAGE_ENCODINGS: Dict[str, Tuple[Any, int]] = {
    "mono8": (np.uint8, 1), "8UC1": (np.uint8, 1), "bgr8": (np.uint8, 3),
    "rgb8": (np.uint8, 3), "8UC3": (np.uint8, 3), "bgra8": (np.uint8, 4),
    "rgba8": (np.uint8, 4), "8UC4": (np.uint8, 4), "mono16": (np.uint16, 1),
    "16UC1": (np.uint16, 1), "16UC3": (np.uint16, 3), "32FC1": (np.float32, 1),
    "32FC3": (np.float32, 3), "64FC1": (np.float64, 1),
}
FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
TILED_TYPES = ("sensor_msgs/Image", "sensor_msgs/PointCloud2")
ARRIVAL_TYPE = "walkman_msgs/Arrival"


def arrival_topic(topic: str) -> str:
    """Where the bridge says what of each frame on ``topic`` arrived."""
    return topic.rstrip("/") + "/arrived"


def message_class(type_name: str) -> type:
    import roslib.message

    cls = roslib.message.get_message_class(type_name)
    if cls is None:
        raise BridgeUsageError(f"ROS message type {type_name} is not installed")
    return cls


# -- codecs: messages <-> datagram bodies ---------------------------------------------


@dataclass(frozen=True)
class Rebuilt:
    """A tiled message as the receiver rebuilt it, with its account of what arrived."""

    msg: Any
    arrival: tiles.Arrival


def arrival_message(arrival: tiles.Arrival, header: Any) -> Any:
    """``walkman_msgs/Arrival`` for the frame whose ``header`` is given."""
    from walkman_msgs.msg import Arrival, Region

    return Arrival(header=header, height=arrival.height, width=arrival.width,
                   fraction=arrival.fraction, tiles=arrival.tiles,
                   tiles_arrived=arrival.tiles_arrived,
                   missing=[Region(r.x, r.y, r.width, r.height) for r in arrival.missing])


class ImageCodec:
    """``sensor_msgs/Image`` as standalone tiles (JPEG, PNG or zlib per tile)."""

    tiled = True

    def __init__(self, quality: int = 80, codec: str = "") -> None:
        self.quality = quality
        self.codec = codec

    def _choose(self, dtype: Any, channels: int) -> int:
        if self.codec:
            return tiles.CODEC_NAMES[self.codec]
        if dtype == np.uint8 and channels in (1, 3):
            return tiles.JPEG
        if dtype in (np.uint8, np.uint16):
            return tiles.PNG
        return tiles.ZLIB

    def encode(self, msg: Any) -> List[bytes]:
        if msg.encoding not in IMAGE_ENCODINGS:
            raise BridgeUsageError(f"image encoding {msg.encoding!r} cannot be tiled")
        dtype, channels = IMAGE_ENCODINGS[msg.encoding]
        dtype = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
        row_bytes = msg.width * channels * dtype.itemsize
        if msg.step < row_bytes or len(msg.data) < msg.step * msg.height:
            raise BridgeUsageError(f"image {msg.width}x{msg.height} {msg.encoding}: step "
                                   f"{msg.step} and {len(msg.data)} data bytes do not fit")
        rows = np.frombuffer(msg.data, np.uint8)[:msg.step * msg.height].reshape(
            msg.height, msg.step)[:, :row_bytes]
        pixels = np.ascontiguousarray(rows).view(dtype).astype(dtype.newbyteorder("="))
        pixels = pixels.reshape((msg.height, msg.width) if channels == 1 else
                                (msg.height, msg.width, channels))
        meta = compact.encode(Bottle([msg.header.stamp.secs, msg.header.stamp.nsecs,
                                      msg.header.frame_id, msg.encoding, msg.header.seq]))
        header = tiles.header_for(pixels, self._choose(pixels.dtype, channels), self.quality)
        return tiles.split(pixels, header, meta)

    def decode(self, canvas: tiles.Canvas, completeness: float) -> Rebuilt:
        from sensor_msgs.msg import Image

        secs, nsecs, frame_id, encoding, seq = header_fields(canvas.meta, "image", (
            _UINT32, _UINT32, str, str, _UINT32))
        msg = Image()
        msg.header.seq, msg.header.frame_id = int(seq), str(frame_id)
        msg.header.stamp.secs, msg.header.stamp.nsecs = int(secs), int(nsecs)
        msg.height, msg.width = canvas.header.height, canvas.header.width
        msg.encoding, msg.is_bigendian = str(encoding), 0
        pixels = canvas.pixels.astype(canvas.pixels.dtype.newbyteorder("<"))
        msg.step = msg.width * canvas.header.channels * pixels.dtype.itemsize
        msg.data = pixels.tobytes()
        return Rebuilt(msg, canvas.arrival())


_UINT32 = "uint32"
_FLAG = "flag"


def header_fields(meta: bytes, what: str, shape: Tuple[Any, ...]) -> List[Any]:
    """A tiled message's metadata, checked field by field (a peer's bytes)."""
    values = compact.decode(meta)
    if not isinstance(values, list) or len(values) != len(shape):
        raise BridgeProtocolError(f"{what} metadata holds {str(values)[:80]}, not "
                                  f"{len(shape)} fields")
    for index, (value, kind) in enumerate(zip(values, shape)):
        if kind == _UINT32:
            ok = isinstance(value, int) and 0 <= value < 1 << 32
        elif kind == _FLAG:
            ok = value in (0, 1) and isinstance(value, int)
        else:
            ok = isinstance(value, kind)
        if not ok:
            raise BridgeProtocolError(f"{what} metadata field {index} is {value!r}, not a "
                                      f"{getattr(kind, '__name__', kind)}")
    return values


class CloudCodec:
    """``sensor_msgs/PointCloud2`` as standalone small clouds (zlib per tile)."""

    tiled = True

    def encode(self, msg: Any) -> List[bytes]:
        if msg.point_step == 0 or msg.row_step < msg.width * msg.point_step or \
                len(msg.data) < msg.row_step * msg.height:
            raise BridgeUsageError(f"cloud {msg.width}x{msg.height}: point_step "
                                   f"{msg.point_step}, row_step {msg.row_step} and "
                                   f"{len(msg.data)} bytes do not fit")
        rows = np.frombuffer(msg.data, np.uint8)[:msg.row_step * msg.height].reshape(
            msg.height, msg.row_step)[:, :msg.width * msg.point_step]
        cells = np.ascontiguousarray(rows).reshape(msg.height, msg.width, msg.point_step)
        fields = [[f.name, f.offset, f.datatype, f.count] for f in msg.fields]
        nan_at = [f.offset + 4 * i for f in msg.fields if f.datatype == FLOAT32
                  for i in range(max(f.count, 1)) if f.offset + 4 * (i + 1) <= msg.point_step]
        meta = compact.encode(Bottle([msg.header.stamp.secs, msg.header.stamp.nsecs,
                                      msg.header.frame_id, int(msg.is_bigendian),
                                      int(msg.is_dense), msg.header.seq, fields]))
        header = tiles.header_for(cells, tiles.ZLIB, nan_offsets=nan_at[:64])
        return tiles.split(cells, header, meta)

    def decode(self, canvas: tiles.Canvas, completeness: float) -> Rebuilt:
        from sensor_msgs.msg import PointCloud2, PointField

        secs, nsecs, frame_id, bigendian, dense, seq, fields = header_fields(
            canvas.meta, "cloud", (_UINT32, _UINT32, str, _FLAG, _FLAG, _UINT32, list))
        if not all(isinstance(f, list) and len(f) == 4 and isinstance(f[0], str) and
                   all(isinstance(v, int) and 0 <= v < 1 << 32 for v in f[1:]) for f in fields):
            raise BridgeProtocolError(f"cloud metadata: fields {str(fields)[:80]} are not "
                                      f"(name offset datatype count) lists")
        msg = PointCloud2()
        msg.header.seq, msg.header.frame_id = int(seq), str(frame_id)
        msg.header.stamp.secs, msg.header.stamp.nsecs = int(secs), int(nsecs)
        msg.height, msg.width = canvas.header.height, canvas.header.width
        msg.fields = [PointField(str(n), int(o), int(d), int(c)) for n, o, d, c in fields]
        msg.is_bigendian = bool(bigendian)
        msg.point_step = canvas.header.channels
        msg.row_step = msg.point_step * msg.width
        msg.is_dense = bool(dense) and completeness >= 1.0
        msg.data = canvas.pixels.tobytes()
        return Rebuilt(msg, canvas.arrival())


class SerializedCodec:
    """Any other type: its ROS serialization, whole."""

    tiled = False

    def __init__(self, cls: type) -> None:
        self.cls = cls

    def encode(self, msg: Any) -> bytes:
        buffer = BytesIO()
        msg.serialize(buffer)
        return buffer.getvalue()

    def decode(self, data: bytes, completeness: float) -> Any:
        msg = self.cls()
        try:
            msg.deserialize(data)
        except Exception as exc:  # genpy raises several types on short input
            raise BridgeProtocolError(f"{self.cls._type} does not deserialize: {exc}") from None
        return msg


def codec_for(channel: Channel) -> Any:
    if channel.ros_type == "sensor_msgs/Image":
        return ImageCodec(channel.quality)
    if channel.ros_type == "sensor_msgs/PointCloud2":
        return CloudCodec()
    return SerializedCodec(message_class(channel.ros_type))


# -- the node ------------------------------------------------------------------------


#: A TCPROS handshake must complete within this many seconds and bytes.
class RosSink:
    """Subscribes to a topic and posts its messages to the link."""

    def __init__(self, channel: Channel, post: Callable[[Channel, Any], None]) -> None:
        import rospy

        self.channel = channel
        self._post = post
        self._own = rospy.get_name()
        self._latched: Optional[Any] = None
        self._latched_at = 0.0
        self.loops_prevented = 0
        self._subscriber = rospy.Subscriber(channel.label, message_class(channel.ros_type),
                                            self._on_message, queue_size=2,
                                            buff_size=1 << 24)

    def _on_message(self, msg: Any) -> None:
        header = getattr(msg, "_connection_header", None) or {}
        if header.get("callerid") == self._own:
            self.loops_prevented += 1
            return
        if self.channel.latch or header.get("latching") == "1":
            self._latched, self._latched_at = msg, time.monotonic()
        self._post(self.channel, msg)

    def repeat_latched(self, force: bool = False) -> None:
        if self._latched is not None and (force or
                                          time.monotonic() - self._latched_at > LATCH_REPEAT):
            self._latched_at = time.monotonic()
            self._post(self.channel, self._latched)

    def close(self) -> None:
        self._subscriber.unregister()


class RosSource:
    """Publishes on this side what arrived from the other (and, for a tiled frame, first
    what of it arrived, on :func:`arrival_topic`)."""

    def __init__(self, channel: Channel) -> None:
        import rospy

        self.channel = channel
        self._publisher = rospy.Publisher(channel.label, message_class(channel.ros_type),
                                          queue_size=2, latch=channel.latch)
        self._arrivals = None
        if channel.ros_type in TILED_TYPES:
            from nodekit.msgs import ensure_importable

            ensure_importable()
            self._arrivals = rospy.Publisher(arrival_topic(channel.label),
                                             message_class(ARRIVAL_TYPE), queue_size=2,
                                             latch=channel.latch)
        self._last_digest = b""
        self.published = 0

    def deliver(self, value: Any) -> bool:
        msg = value.msg if isinstance(value, Rebuilt) else value
        if self.channel.latch:
            buffer = BytesIO()
            msg.serialize(buffer)
            digest = hashlib.sha1(buffer.getvalue()).digest()
            if digest == self._last_digest:
                return True
            self._last_digest = digest
        if isinstance(value, Rebuilt) and self._arrivals is not None:
            self._arrivals.publish(arrival_message(value.arrival, msg.header))
        self._publisher.publish(msg)
        self.published += 1
        return True

    def close(self) -> None:
        self._publisher.unregister()
        if self._arrivals is not None:
            self._arrivals.unregister()
