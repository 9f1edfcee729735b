"""The ROS endpoints: images and clouds as tiles, and the bridge's account of what arrived.

The codecs run here without a ROS node (sensor_msgs and walkman_msgs are plain
classes); the last test runs both bridges as processes on loopback with their
own roscores, a relay between them dropping chosen tiles, and reads what the
pilot bridge publishes on ``<topic>/arrived``.
"""

from __future__ import annotations

import re
import socket
import threading
from io import BytesIO
from typing import Callable, Dict, List, Tuple

import numpy as np
import pytest

from bridge.endpoints.ros import (CloudCodec, ImageCodec, Rebuilt, arrival_message,
                                  arrival_topic)
from bridge.flows import Carriage, FlowKey, Form, Route
from bridge.transport.udp_channel import Reassembler, UdpRoute, UdpStats, message_datagrams
from bridge.wire import compact, datagrams, tiles
from bridge.wire.link import TAG_SIZE
from bridge.wire.varint import get_varint
from bridge_harness import HERE, TwoPCs
from harness import wait_until
from nodekit.msgs import ensure_importable

ensure_importable()
from sensor_msgs.msg import Image, PointCloud2, PointField  # noqa: E402
from walkman_msgs.msg import Arrival  # noqa: E402

IMAGE_ID, CLOUD_ID = 30, 31


def route(ident: int, codec) -> UdpRoute:
    return UdpRoute.of(Route(FlowKey(ident, 0), f"flow{ident}", Carriage.DATAGRAMS, Form.ROS),
                       codec)


def black_image(height: int = 240, width: int = 320) -> Image:
    msg = Image(height=height, width=width, encoding="bgr8", step=3 * width,
                data=bytes(3 * width * height))
    msg.header.stamp.secs, msg.header.stamp.nsecs, msg.header.seq = 1700000000, 123456789, 7
    msg.header.frame_id = "left_camera_optical_frame"
    return msg


def nan_cloud(height: int = 60, width: int = 80) -> PointCloud2:
    points = np.full((height, width, 4), np.nan, np.float32)
    points[..., 3] = 0.0
    fields = [PointField(name, 4 * i, PointField.FLOAT32, 1)
              for i, name in enumerate(("x", "y", "z", "rgb"))]
    msg = PointCloud2(height=height, width=width, fields=fields, point_step=16,
                      row_step=16 * width, is_dense=False, data=points.tobytes())
    msg.header.stamp.secs, msg.header.stamp.nsecs = 1700000001, 5
    return msg


def cross(codec, msg, drop: Callable[[int], bool] = lambda index: False
          ) -> Tuple[Rebuilt, List[tiles.Tile]]:
    """``msg`` through a reassembler, dropping the data datagrams ``drop`` picks."""
    flow = route(IMAGE_ID, codec)
    bodies = codec.encode(msg)
    reassembler = Reassembler({flow.key: flow}, 0.4, UdpStats())
    out = []
    for index, raw in enumerate(message_datagrams(flow, 1, bodies)):
        if not drop(index):
            out += reassembler.feed(raw, now=0.0)
    out += reassembler.expire(now=1.0)
    (_, rebuilt), = out
    return rebuilt, [tiles.decode_tile(body)[0] for i, body in enumerate(bodies) if drop(i)]


def cells(rectangles, height: int, width: int) -> np.ndarray:
    """How many of the ``(x, y, w, h)`` rectangles cover each cell."""
    count = np.zeros((height, width), int)
    for x, y, w, h in rectangles:
        count[y:y + h, x:x + w] += 1
    return count


def test_a_black_image_and_a_cloud_without_depth_arrive_whole():
    """Black and NaN are content: what the bridge says is what was lost, here nothing."""
    for codec, msg in ((ImageCodec(80), black_image()), (CloudCodec(), nan_cloud())):
        rebuilt, _ = cross(codec, msg)
        report = arrival_message(rebuilt.arrival, rebuilt.msg.header)
        assert (report.fraction, report.missing) == (1.0, [])
        assert report.tiles == report.tiles_arrived == len(codec.encode(msg))
        assert report.header == msg.header and (report.height, report.width) == (msg.height,
                                                                                 msg.width)


def test_the_report_names_exactly_the_tiles_that_were_lost_with_the_frames_header():
    image = black_image()
    image.data = np.random.default_rng(5).integers(
        0, 256, 240 * 320 * 3, dtype=np.uint8).tobytes()
    rebuilt, lost = cross(ImageCodec(80), image, drop=lambda index: index in (1, 4))
    report = arrival_message(rebuilt.arrival, rebuilt.msg.header)
    assert report.header.stamp == image.header.stamp and report.header.seq == 7
    shown = cells([(r.x, r.y, r.width, r.height) for r in report.missing], 240, 320)
    expected = cells([(t.x, t.y, t.width, t.height) for t in lost], 240, 320)
    assert np.array_equal(shown, expected) and len(lost) == 2
    assert report.tiles_arrived == report.tiles - 2
    assert report.fraction == pytest.approx(1 - expected.mean(), abs=1e-6)
    pixels = np.frombuffer(rebuilt.msg.data, np.uint8).reshape(240, 320, 3)
    assert not pixels[expected.astype(bool)].any()           # the lost cells are black
    # What the pilot roscore carries: the same report after ROS serialization.
    buffer = BytesIO()
    report.serialize(buffer)
    again = Arrival()
    again.deserialize(buffer.getvalue())
    assert (again.header, again.missing, again.tiles) == (report.header, report.missing,
                                                          report.tiles)
    assert again.fraction == np.float32(report.fraction)     # a float32 on the wire


def test_a_cloud_reports_its_lost_points_and_is_not_dense():
    cloud = nan_cloud()
    cloud.data = np.random.default_rng(6).random((60, 80, 4), dtype=np.float32).tobytes()
    cloud.is_dense = True
    rebuilt, lost = cross(CloudCodec(), cloud, drop=lambda index: index == 0)
    assert not rebuilt.msg.is_dense
    arrival = rebuilt.arrival
    shown = cells([(r.x, r.y, r.width, r.height) for r in arrival.missing], 60, 80)
    expected = cells([(t.x, t.y, t.width, t.height) for t in lost], 60, 80)
    assert np.array_equal(shown, expected) and 0 < arrival.fraction < 1


def test_the_arrival_topic_is_beside_the_frames():
    assert arrival_topic("/multisense/left/image_color") == \
        "/multisense/left/image_color/arrived"
    assert arrival_topic("/multisense/points/") == "/multisense/points/arrived"


# -- through both bridges ---------------------------------------------------------------------

#: A partial frame goes out ``gather`` after its first tile, unless the next frame is whole
#: first (then it is superseded, never published): frames at 1 Hz, gathered for 0.6 s -- a
#: tile the relay let through arrives within it even on a 2-core box at load 70 (with 0.2 s
#: one did not: the bridge rightly published the frame without it, a loss the test did not
#: make).
CONFIG = f"""<bridge period="0.5" gather="0.6">
  <ros_topics>
    <topic name="/multisense/left/image_color" type="sensor_msgs/Image" id="{IMAGE_ID}"
           direction="robot_to_pilot" channel="udp" quality="70"/>
    <topic name="/multisense/points" type="sensor_msgs/PointCloud2" id="{CLOUD_ID}"
           direction="robot_to_pilot" channel="udp"/>
  </ros_topics>
</bridge>
"""
Stamp = Tuple[int, int]


class DroppingRelay:
    """Between the robot bridge and the pilot bridge's UDP port: forwards every datagram
    but the data tiles ``drop(flow id, nth message of the flow, part index)`` picks, and
    keeps those tiles by flow and frame stamp.  Datagrams are authenticated, not
    encrypted: the relay reads them, as anything on the path could, and alters none."""

    def __init__(self, target_port: int, drop: Callable[[int, int, int], bool]) -> None:
        self.target = ("127.0.0.1", target_port)
        self.drop = drop
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.dropped: Dict[Tuple[int, Stamp], List[tiles.Tile]] = {}
        self._messages: Dict[int, List[int]] = {}     # flow id -> message numbers seen
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dropping relay", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                raw = self.sock.recv(65536)
            except socket.timeout:
                continue
            _, start = get_varint(raw, 0, "counter")
            inner = raw[start:-TAG_SIZE]
            if not datagrams.is_report(inner):
                part = datagrams.decode(inner)
                seen = self._messages.setdefault(part.id, [])
                if part.message not in seen:
                    seen.append(part.message)
                if not part.is_repair and self.drop(part.id, seen.index(part.message),
                                                    part.index):
                    tile, _ = tiles.decode_tile(part.body)
                    secs, nsecs = compact.decode(tile.meta)[:2]
                    self.dropped.setdefault((part.id, (secs, nsecs)), []).append(tile)
                    continue
            self.sock.sendto(raw, self.target)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


def drop_some(ident: int, nth: int, index: int) -> bool:
    """Every other frame loses tiles: two of the image's, the first of the cloud's."""
    if nth % 2 == 0:
        return False
    return index in ((1, 3) if ident == IMAGE_ID else (0,))


REPORT = re.compile(r"^arrived (image|cloud) (\d+) (\d+) ([\d.]+) (\d+) (\d+) (\S+)$")


def test_the_pilot_bridge_reports_the_tiles_the_link_dropped(tmp_path, lite):
    config = tmp_path / "bridge.xml"
    config.write_text(CONFIG)
    pcs = TwoPCs(tmp_path, lite, config)
    relay = DroppingRelay(pcs.udp_ports["pilot"], drop_some)
    try:
        pcs.start_name_servers()
        for side in (pcs.robot, pcs.pilot):
            pcs.start_roscore(side)
        pcs.start_bridge(pcs.robot, "--peer-udp-port", str(relay.port))
        pcs.start_bridge(pcs.pilot)
        pcs.wait_linked(60)
        probe = pcs.pilot.python(str(HERE / "arrival_probe.py"), name="arrival probe")
        probe.wait_for("probe ready", 30)
        pcs.robot.python(str(HERE / "camera_publisher.py"), "1", "0", "320", "240",
                         name="camera")
        for kind in ("image", "cloud"):
            probe.wait_for(rf"^arrived {kind} ", 60, count=8)
        wait_until(lambda: all(any(re.match(rf"^{kind} {secs} {nsecs}$", line)
                                   for line in probe.lines)
                               for kind, secs, nsecs, *_ in reports(probe.lines)), 10,
                   message="each reported frame published")
    finally:
        relay.close()
        pcs.close()
    sizes = {"image": (240, 320), "cloud": (60, 80)}
    losses = {"image": 0, "cloud": 0}
    for kind, secs, nsecs, fraction, sent, arrived, missing in reports(probe.lines):
        ident = IMAGE_ID if kind == "image" else CLOUD_ID
        lost = relay.dropped.get((ident, (secs, nsecs)), [])
        expected = cells([(t.x, t.y, t.width, t.height) for t in lost], *sizes[kind])
        shown = cells(missing, *sizes[kind])
        where = f"{kind} {secs}.{nsecs:09d}: reported {missing}, dropped {lost}"
        assert np.array_equal(shown, expected), where
        assert fraction == pytest.approx(1 - expected.mean(), abs=1e-5), where
        assert sent - arrived == len(lost), where
        losses[kind] += bool(lost)
    assert losses["image"] >= 2 and losses["cloud"] >= 2, losses   # and whole frames too
    assert len(reports(probe.lines)) - sum(losses.values()) >= 4


def reports(lines: List[str]) -> List[Tuple]:
    """The probe's ``arrived`` lines: kind, secs, nsecs, fraction, tiles, arrived, rectangles."""
    out = []
    for match in filter(None, map(REPORT.match, list(lines))):
        kind, secs, nsecs, fraction, sent, arrived, missing = match.groups()
        rectangles = [] if missing == "-" else [tuple(map(int, r.split(",")))
                                                for r in missing.split(";")]
        out.append((kind, int(secs), int(nsecs), float(fraction), int(sent), int(arrived),
                    rectangles))
    return out
