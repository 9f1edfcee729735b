"""ROS endpoints: topics with the original names on each side's roscore.

Theory of operation
-------------------
:class:`RosNode` wraps rospy's one node per process: it waits for the local
master (so the bridge may start before roscore), and every second checks that
the master still knows our topics -- a restarted roscore forgets every node,
and rospy never registers again by itself -- registering them again when it
does not.

:class:`RosSink` subscribes to a topic on the side where data starts and posts
each message to the UDP channel; :class:`RosSource` publishes on the other
side what arrives.  A message whose ``callerid`` is our own node is one we
published, so it is never sent back (no republish loops when both directions
carry the same name).  Latched topics keep their last message, which is sent
again when the link comes back and every few seconds, and the receiving side
publishes it latched -- once, unless it changed.

rospy reads the handshake of every inbound connection in its accept thread,
with no deadline and no size limit: one silent client stalls every topic and
service of the node, and a header that declares 2 GB is buffered until it
arrives.  :func:`guard_tcpros` (installed by :class:`RosNode`) gives each
handshake a thread of its own (at most :data:`MAX_HANDSHAKES` at once), a
deadline and a size limit, so our nodes keep serving under hostile peers.

Images and point clouds are tiled (:mod:`bridge.tiles`): a partial frame is
published with its missing regions black (images), NaN (float images) or NaN
points (clouds, marked ``is_dense = False``).  Every other type travels as its
serialized bytes, whole or not at all.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from io import BytesIO
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from bridge import compact, tiles
from bridge.config import Channel
from bridge.errors import BridgeProtocolError, BridgeUsageError
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


def message_class(type_name: str) -> type:
    import roslib.message

    cls = roslib.message.get_message_class(type_name)
    if cls is None:
        raise BridgeUsageError(f"ROS message type {type_name} is not installed")
    return cls


# -- codecs: messages <-> datagram bodies ---------------------------------------------


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

    def decode(self, canvas: tiles.Canvas, completeness: float) -> Any:
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
        return msg


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

    def decode(self, canvas: tiles.Canvas, completeness: float) -> Any:
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
        return msg


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
HANDSHAKE_TIMEOUT = 5.0
MAX_HANDSHAKE_BYTES = 1 << 20
#: Inbound handshakes read at once; further connections are closed at once.
MAX_HANDSHAKES = 64


class _HandshakeBudget:
    """A socket seen by rospy's header reader: its ``recv`` stops at the byte limit."""

    def __init__(self, sock: Any) -> None:
        self._sock = sock
        self.received = 0

    def recv(self, size: int) -> bytes:
        from rosgraph.network import ROSHandshakeException

        data = self._sock.recv(size)
        self.received += len(data)
        if self.received > MAX_HANDSHAKE_BYTES:
            raise ROSHandshakeException(f"handshake header over {MAX_HANDSHAKE_BYTES} bytes: "
                                        f"refused")
        return data


def guard_tcpros() -> None:
    """Bound rospy's inbound TCPROS handshakes in time, size and threads (idempotent)."""
    from rosgraph import network
    from rospy.impl import tcpros_base

    if getattr(tcpros_base, "_walkman_guarded", False):
        return
    read_header = network.read_ros_handshake_header
    serve = tcpros_base.TCPROSServer._tcp_server_callback
    slots = threading.BoundedSemaphore(MAX_HANDSHAKES)

    def bounded_read(sock: Any, buffer: Any, buff_size: int) -> Dict[str, str]:
        previous = sock.gettimeout()
        sock.settimeout(HANDSHAKE_TIMEOUT if previous is None
                        else min(previous, HANDSHAKE_TIMEOUT))
        try:
            return read_header(_HandshakeBudget(sock), buffer, buff_size)
        finally:
            sock.settimeout(previous)

    def threaded(server: Any, sock: Any, address: Any) -> None:
        if not slots.acquire(blocking=False):
            log.warning("TCPROS: %d handshakes already running; refused %s:%s",
                        MAX_HANDSHAKES, *address[:2])
            sock.close()
            return

        def run() -> None:
            try:
                serve(server, sock, address)   # rospy logs and closes on any failure
            finally:
                slots.release()

        threading.Thread(target=run, name="tcpros handshake", daemon=True).start()

    tcpros_base.read_ros_handshake_header = bounded_read
    tcpros_base.TCPROSServer._tcp_server_callback = threaded
    tcpros_base._walkman_guarded = True


class RosNode:
    """rospy's node for this process: started when the master answers, kept registered."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.ready = threading.Event()
        self._stop = threading.Event()
        self._on_ready: List[Callable[[], None]] = []
        self._master_pid: Optional[int] = None
        self._thread = threading.Thread(target=self._run, name="bridge ros", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def when_ready(self, action: Callable[[], None]) -> None:
        self._on_ready.append(action)

    def _master(self):
        import rosgraph

        return rosgraph.Master(self.name)

    def _run(self) -> None:
        import rosgraph
        import rospy

        announced = False
        while not self._stop.is_set() and not rosgraph.is_master_online():
            if not announced:
                log.info("waiting for the ROS master at %s", rosgraph.get_master_uri())
                announced = True
            self._stop.wait(1.0)
        if self._stop.is_set():
            return
        guard_tcpros()
        rospy.init_node(self.name, anonymous=False, disable_signals=True)
        self._master_pid = self._pid()
        log.info("ROS node %s registered with %s", rospy.get_name(), rosgraph.get_master_uri())
        for action in self._on_ready:
            action()
        self.ready.set()
        while not self._stop.wait(1.0):
            pid = self._pid()
            if pid is not None and pid != self._master_pid:
                log.warning("the ROS master restarted; registering our topics again")
                if self._register_again():
                    self._master_pid = pid

    def _pid(self) -> Optional[int]:
        try:
            return int(self._master().getPid())
        except Exception:  # noqa: BLE001 -- master down: keep the old one
            return None

    def _register_again(self) -> bool:
        import rospy
        from rospy.impl.registration import (RegManager, get_registration_listeners,
                                             get_service_manager, get_topic_manager)

        manager = next((l for l in get_registration_listeners().listeners
                        if isinstance(l, RegManager)), None)
        master = self._master()
        uri = rospy.core.get_node_uri()
        try:
            for topic, type_name in get_topic_manager().get_publications():
                master.registerPublisher(topic, type_name, uri)
            for topic, type_name in get_topic_manager().get_subscriptions():
                publishers = master.registerSubscriber(topic, type_name, uri)
                if manager is not None:
                    manager.publisher_update(topic, publishers)
            for service, service_uri in get_service_manager().get_services():
                master.registerService(service, service_uri, uri)
        except Exception as exc:  # noqa: BLE001 -- try again next second
            log.warning("registering again failed: %s", exc)
            return False
        return True

    def stop(self) -> None:
        self._stop.set()
        if self.ready.is_set():
            import rospy

            rospy.signal_shutdown("bridge stopping")


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
    """Publishes on this side what arrived from the other."""

    def __init__(self, channel: Channel) -> None:
        import rospy

        self.channel = channel
        self._publisher = rospy.Publisher(channel.label, message_class(channel.ros_type),
                                          queue_size=2, latch=channel.latch)
        self._last_digest = b""
        self.published = 0

    def deliver(self, msg: Any) -> bool:
        if self.channel.latch:
            buffer = BytesIO()
            msg.serialize(buffer)
            digest = hashlib.sha1(buffer.getvalue()).digest()
            if digest == self._last_digest:
                return True
            self._last_digest = digest
        self._publisher.publish(msg)
        self.published += 1
        return True

    def close(self) -> None:
        self._publisher.unregister()
