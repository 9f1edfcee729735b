"""The Pilot Interface's ROS node: everything it shows and sends, as plain events.

Theory of operation
-------------------
The PI is a ROS node on the pilot's roscore.  It speaks to the robot only
through the pilot gateway's topics (``/M/switch``, ``/M/command`` in;
``/M/status`` latched, ``/M/warning``, ``/M/countdown``, ``/pilot/sent_commands``
out) and reads what the bridge brings to the pilot PC (``/joint_states``,
``/joint_temperatures``, the camera and the cloud, and the bridge's account
of what of each frame arrived on ``<topic>/arrived``); the only YARP port it
reads is the local bridge's own ``/bridge/pilot/status:o`` (the link's state).
Loss is never guessed from the pixels: a black sky or a point without depth is
content, and a frame no bridge reported on (the lab) arrived whole.

:class:`PilotLink` turns every message into an event -- a small dataclass
handed to ``post`` from whichever thread received it -- so the Qt side
(:mod:`pilot.app`) queues them onto the GUI thread and tests collect them in
a list.  Heavy decoding (pixels, points) happens here, off the GUI thread.

Recovery: :class:`~nodekit.ros_node.RosNode` registers again after a roscore
restart, the gateway's status topics are latched (a restarted PI shows the
current state at once), and the bridge status port is reconnected by a
:class:`~nodekit.connections.ConnectionKeeper`.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from nodekit.scene import SceneError, SceneObject, checked

log = logging.getLogger("pilot.link")

IMAGE_TOPIC = "/multisense/left/image_color"
CLOUD_TOPIC = "/multisense/points"


# -- events ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StatusEvent:
    module: str
    state: str
    data: str
    values: Tuple[float, ...]
    seq: int
    stamp: float          # when the gateway received it (wall clock, s)


@dataclass(frozen=True)
class WarningEvent:
    module: str
    text: str
    stamp: float


@dataclass(frozen=True)
class CountdownEvent:
    module: str
    command: str          # the command as YARP text (``turn 0.5``)
    remaining: float
    state: str            # waiting, sent, cancelled
    sender: str


@dataclass(frozen=True)
class SentEvent:
    module: str
    port: str             # switch or command
    text: str
    seq: int
    sender: str
    station: int
    stamp: float


@dataclass(frozen=True)
class JointsEvent:
    names: Tuple[str, ...]
    position: np.ndarray
    effort: np.ndarray
    stamp: float


@dataclass(frozen=True)
class BatteryEvent:
    """The robot's battery (``/battery``, the HAL's batteryWrapper stream)."""

    percent: float
    voltage: float
    current: float        # A drawn (positive while discharging)
    stamp: float


@dataclass(frozen=True)
class TemperaturesEvent:
    names: Tuple[str, ...]
    celsius: np.ndarray
    stamp: float


@dataclass(frozen=True)
class ImageEvent:
    rgb: np.ndarray       # H x W x 3 uint8
    stamp_ns: int         # the header's stamp: what the bridge's arrival report names


@dataclass(frozen=True)
class CloudEvent:
    points: int
    stamp_ns: int
    #: the points' x y z in :data:`frame` (N x 3), what footsteps are placed from; None
    #: when the cloud has no x y z fields
    xyz: Optional[np.ndarray] = field(default=None, compare=False, repr=False)
    frame: str = ""


Rectangle = Tuple[int, int, int, int]   # x, y, width, height (cells)


@dataclass(frozen=True)
class ArrivalEvent:
    """The pilot bridge's account of what of one frame arrived (``walkman_msgs/Arrival``)."""

    topic: str            # the frame's topic (IMAGE_TOPIC, CLOUD_TOPIC)
    stamp_ns: int
    height: int
    width: int
    fraction: float       # of the cells (pixels, points)
    missing: Tuple[Rectangle, ...]   # exactly the cells that did not arrive


@dataclass(frozen=True)
class BridgeEvent:
    status: Dict[str, Any]
    stamp: float


@dataclass(frozen=True)
class LinkEvent:
    """The link to the robot (``/bridge/link``): up, down, direct (the lab) or unknown."""

    state: str
    reason: str
    since: float          # seconds in this state, as of now
    queued: int           # pilot commands the pilot bridge holds for the link


@dataclass(frozen=True)
class CommandStateEvent:
    """A command's life moved on (``/pilot/command_states``): any pilot's command."""

    module: str
    port: str
    seq: int
    text: str
    sender: str
    station: int
    state: str            # sent queued delivered accepted refused expired cancelled
    reason: str
    stamp: float


@dataclass(frozen=True)
class StopEvent:
    """The robot's answer to this PI's stop-all or release."""

    word: str             # stop_all or release
    ok: bool
    message: str
    round_trip_ms: float
    stamp: float


@dataclass(frozen=True)
class RosEvent:
    up: bool
    again: bool = False   # the master restarted and our topics are registered again
    failed: str = ""      # why the link's topics did not open (nothing can be sent)


@dataclass(frozen=True)
class SceneEvent:
    """The pilots' shared 3-D scene as the gateway holds it (``/pilot/scene``)."""

    objects: Tuple[SceneObject, ...]


Post = Callable[[Any], None]


# -- pure decoding -------------------------------------------------------------------------


def image_pixels(encoding: str, height: int, width: int, data: bytes) -> Optional[np.ndarray]:
    """An 8-bit colour or mono ``sensor_msgs/Image`` as H x W x 3 RGB, or None."""
    channels = {"rgb8": 3, "bgr8": 3, "mono8": 1, "rgba8": 4, "bgra8": 4}.get(encoding)
    if channels is None or len(data) < height * width * channels:
        return None
    pixels = np.frombuffer(data, np.uint8, height * width * channels)
    pixels = pixels.reshape(height, width, channels)
    if channels == 1:
        return np.repeat(pixels, 3, axis=2)
    if encoding.startswith("bgr"):
        pixels = pixels[:, :, 2::-1]
    return np.ascontiguousarray(pixels[:, :, :3])


def arrival_event(topic: str, msg: Any) -> ArrivalEvent:
    """A ``walkman_msgs/Arrival`` about a frame on ``topic`` as an event."""
    return ArrivalEvent(topic, msg.header.stamp.to_nsec(), msg.height, msg.width,
                        float(msg.fraction),
                        tuple((r.x, r.y, r.width, r.height) for r in msg.missing))


# -- the node ------------------------------------------------------------------------------


@dataclass
class _Sender:
    switch: Any
    command: Any


class PilotLink:
    """The PI's ROS node and the bridge status reader; ``post`` gets every event."""

    def __init__(self, name: str, modules: Sequence[str], post: Post,
                 camera: bool = True, bridge_status: str = "/bridge/pilot/status:o") -> None:
        self.name = name
        self.modules = list(modules)
        self.post = post
        self.camera = camera
        self.bridge_status = bridge_status
        self._senders: Dict[str, _Sender] = {}
        self._ros = None
        self._keeper = None
        self._status_port = None
        self._tf = None             # /tf (the preview's ghost), once on the pilot roscore
        self._scene_edits = None    # /pilot/scene_edit, likewise
        self._every_pilots_commands: Tuple[Any, ...] = ()   # what any pilot sent, its fate
        self._lock = threading.Lock()

    # -- life ----------------------------------------------------------------------------

    def start(self) -> None:
        from nodekit.ros_node import RosNode
        from nodekit.msgs import ensure_importable

        ensure_importable()
        self._ros = RosNode(self.name)
        self._ros.when_ready(self._open_topics)
        self._ros.when_registered_again(lambda: self.post(RosEvent(True, again=True)))
        self._ros.when_failed(lambda why: self.post(RosEvent(False, failed=why)))
        self._ros.start()
        threading.Thread(target=self._open_bridge_status, name="pilot bridge status",
                         daemon=True).start()

    def close(self) -> None:
        if self._keeper is not None:
            self._keeper.stop()
        if self._status_port is not None:
            self._status_port.close()
        if self._ros is not None:
            self._ros.stop()

    @property
    def ready(self) -> bool:
        return self._ros is not None and self._ros.ready.is_set()

    # -- sending -------------------------------------------------------------------------

    def switch(self, module: str, word: str) -> str:
        """Send a lifecycle command; returns "" or why it could not leave."""
        sender = self._senders.get(module)
        problem = self._cannot_send(module, sender, "switch")
        if problem:
            return problem
        from walkman_msgs.msg import Switch

        sender.switch.publish(Switch(command=word, seq=0, sender=self.name))
        return ""

    def command(self, module: str, name: str, numbers: Sequence[float] = (),
                dangerous: bool = False) -> str:
        """Send a command (a dangerous one counts down at the gateway; again cancels it)."""
        sender = self._senders.get(module)
        problem = self._cannot_send(module, sender, "command")
        if problem:
            return problem
        bad = [v for v in numbers if not math.isfinite(v)]
        if bad:
            return f"{name}: {bad[0]} is not a finite number"
        from walkman_msgs.msg import Command

        sender.command.publish(Command(command=name, words=[], numbers=list(map(float, numbers)),
                                       text="", dangerous=dangerous, countdown=0.0, seq=0,
                                       sender=self.name))
        return ""

    def place(self, name: str, kind: str, pose: Sequence[float], removed: bool = False) -> str:
        """Tell the gateway where this pilot put an object of the shared scene; returns ""
        or why it did not leave (a marker's drag calls it from a Qt slot: it never raises
        for ROS's sake)."""
        if self._scene_edits is None:
            return "the PI is not connected to the pilot roscore yet"
        import rospy
        from walkman_msgs.msg import SceneObject as SceneObjectMsg

        try:
            self._scene_edits.publish(SceneObjectMsg(
                name=name, kind=kind, pose=[float(v) for v in pose], sender=self.name,
                removed=removed))
        except rospy.ROSException as exc:    # shut down, or a closed or unregistered topic
            log.warning("pilot: %s not placed in the shared scene: %s", name, exc)
            return f"{name} not placed in the shared scene: {exc}"
        return ""

    def _on_scene(self, msg: Any) -> None:
        objects = []
        for item in msg.objects:
            try:
                objects.append(checked(item.name, item.kind, list(item.pose), item.sender,
                                       item.station, item.stamp, bool(item.removed)))
            except SceneError as exc:
                log.warning("pilot: a scene object dropped: %s", exc)
        self.post(SceneEvent(tuple(objects)))

    def publish_ghost(self, placements) -> None:
        """The preview's posture on ``/tf`` under ``preview/`` (the 3-D view's ghost); the
        PI's timer calls it, a Qt slot: a ROS error is logged, never raised."""
        if self._tf is None:
            return
        import rospy
        from nodekit.tf import tf_message

        try:
            self._tf.publish(tf_message(placements, rospy.Time.now(), prefix="preview"))
        except rospy.ROSException as exc:    # shut down, or a closed or unregistered topic
            log.warning("pilot: the preview's ghost not published on /tf: %s", exc)

    def cancel(self, module: str, seq: int = 0) -> str:
        """Ask the gateway to take back the module's queued command ``seq`` (0: all of
        them); returns at once, the answer comes as command states (and, if the gateway
        could not be asked, as this PI's warning)."""
        if self._ros is None or not self._ros.ready.is_set():
            return "the PI is not connected to the pilot roscore yet"

        def ask() -> None:
            import rospy
            from walkman_msgs.srv import Cancel

            try:
                rospy.wait_for_service(f"/{module}/cancel", timeout=5.0)
                answer = rospy.ServiceProxy(f"/{module}/cancel", Cancel)(seq)
                text = answer.message
            except (rospy.ROSException, rospy.ServiceException) as exc:
                text = f"not cancelled: the gateway did not answer ({exc})"
            self.post(WarningEvent(module, f"cancel: {text}", time.time()))

        threading.Thread(target=ask, name=f"cancel {module}", daemon=True).start()
        return ""

    def stop_all(self, word: str = "stop_all") -> str:
        """The pilot's stop-all (or ``release``) through the gateway's ``/pilot/<word>``;
        returns at once, the robot's answer comes back as a :class:`StopEvent`."""
        if self._ros is None or not self._ros.ready.is_set():
            return "the PI is not connected to the pilot roscore yet"

        def ask() -> None:
            import rospy
            from walkman_msgs.srv import StopAll

            try:
                rospy.wait_for_service(f"/pilot/{word}", timeout=5.0)
                answer = rospy.ServiceProxy(f"/pilot/{word}", StopAll)()
                self.post(StopEvent(word, bool(answer.ok), answer.message,
                                    float(answer.round_trip_ms), time.time()))
            except (rospy.ROSException, rospy.ServiceException) as exc:
                self.post(StopEvent(word, False, f"the gateway did not answer ({exc})", 0.0,
                                    time.time()))

        threading.Thread(target=ask, name=word, daemon=True).start()
        return ""

    def hears_every_pilot(self) -> bool:
        """True once the gateway's record of every pilot's commands (and their fates) reaches
        us: a command sent before is missing from this PI's log, as from a PI started later
        (each is published once)."""
        from nodekit.ros_node import handshaken

        subscribers = self._every_pilots_commands
        return bool(subscribers) and all(handshaken(s) > 0 for s in subscribers)

    def cannot_send(self, module: str) -> str:
        """Why a switch or command to ``module`` would go nowhere now, or "".

        A ROS publisher drops what it publishes while no subscriber is connected (at
        start, a moment after registering; while the gateway is down): refused, not lost.
        """
        sender = self._senders.get(module)
        return (self._cannot_send(module, sender, "switch")
                or self._cannot_send(module, sender, "command"))

    @staticmethod
    def _cannot_send(module: str, sender: Optional[_Sender], topic: str) -> str:
        if sender is None:
            return "the PI is not connected to the pilot roscore yet"
        if getattr(sender, topic).get_num_connections() == 0:
            return (f"no gateway listens to /{module}/{topic} on the pilot roscore yet "
                    f"(is walkman-pilot-gateway running?); nothing was sent")
        return ""

    # -- ROS -------------------------------------------------------------------------------

    def _open_topics(self) -> None:
        import rospy
        from sensor_msgs.msg import BatteryState, Image, JointState, PointCloud2
        from bridge.endpoints.ros import arrival_topic
        from walkman_msgs.msg import (Arrival, Command, CommandState, Countdown,
                                      JointTemperatures, Link, SentCommand, Status, Switch,
                                      Warning)

        for module in self.modules:
            self._senders[module] = _Sender(
                rospy.Publisher(f"/{module}/switch", Switch, queue_size=10),
                rospy.Publisher(f"/{module}/command", Command, queue_size=10))
            rospy.Subscriber(f"/{module}/status", Status, self._on_status)
            rospy.Subscriber(f"/{module}/warning", Warning, self._on_warning)
            rospy.Subscriber(f"/{module}/countdown", Countdown, self._on_countdown)
        self._every_pilots_commands = (
            rospy.Subscriber("/pilot/sent_commands", SentCommand, self._on_sent),
            rospy.Subscriber("/pilot/command_states", CommandState, self._on_command_state,
                             queue_size=200))
        rospy.Subscriber("/bridge/link", Link, self._on_link)
        rospy.Subscriber("/joint_states", JointState, self._on_joints, queue_size=1)
        from tf2_msgs.msg import TFMessage
        from walkman_msgs.msg import Scene, SceneObject as SceneObjectMsg
        self._tf = rospy.Publisher("/tf", TFMessage, queue_size=2)
        self._scene_edits = rospy.Publisher("/pilot/scene_edit", SceneObjectMsg, queue_size=20)
        rospy.Subscriber("/pilot/scene", Scene, self._on_scene, queue_size=5)
        rospy.Subscriber("/battery", BatteryState, self._on_battery, queue_size=1)
        rospy.Subscriber("/joint_temperatures", JointTemperatures, self._on_temperatures,
                         queue_size=1)
        if self.camera:
            rospy.Subscriber(IMAGE_TOPIC, Image, self._on_image, queue_size=1,
                             buff_size=1 << 22)
            rospy.Subscriber(CLOUD_TOPIC, PointCloud2, self._on_cloud, queue_size=1,
                             buff_size=1 << 22)
            for topic in (IMAGE_TOPIC, CLOUD_TOPIC):   # a few frames' worth: they are small
                rospy.Subscriber(arrival_topic(topic), Arrival,
                                 lambda msg, topic=topic: self.post(arrival_event(topic, msg)),
                                 queue_size=8)
        # Subscribers connect to the publishers a moment after registering: until then a
        # message published here would go nowhere, and another pilot's command would be
        # missing from this PI's log (the gateway publishes each once).
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and (
                any(map(self.cannot_send, self.modules)) or not self.hears_every_pilot()):
            time.sleep(0.05)
        self.post(RosEvent(True))
        log.info("pilot: %s on the pilot roscore, %d modules", self.name, len(self.modules))

    def _on_status(self, msg: Any) -> None:
        self.post(StatusEvent(msg.module, msg.state, msg.data, tuple(msg.values), msg.seq,
                              msg.header.stamp.to_sec()))

    def _on_warning(self, msg: Any) -> None:
        self.post(WarningEvent(msg.module, msg.text, msg.header.stamp.to_sec() or time.time()))

    def _on_countdown(self, msg: Any) -> None:
        self.post(CountdownEvent(msg.module, msg.command, float(msg.remaining), msg.state,
                                 msg.sender))

    def _on_sent(self, msg: Any) -> None:
        self.post(SentEvent(msg.module, msg.port, msg.text, msg.seq, msg.sender, msg.station,
                            msg.header.stamp.to_sec() or time.time()))

    def _on_link(self, msg: Any) -> None:
        stamp = msg.header.stamp.to_sec()
        since = float(msg.since) + (max(0.0, time.time() - stamp) if stamp else 0.0)
        self.post(LinkEvent(msg.state, msg.reason, since, int(msg.queued)))

    def _on_command_state(self, msg: Any) -> None:
        self.post(CommandStateEvent(msg.module, msg.port, int(msg.seq), msg.text, msg.sender,
                                    int(msg.station), msg.state, msg.reason,
                                    msg.header.stamp.to_sec() or time.time()))

    def _on_joints(self, msg: Any) -> None:
        self.post(JointsEvent(tuple(msg.name), np.array(msg.position, float),
                              np.array(msg.effort, float), msg.header.stamp.to_sec()))

    def _on_battery(self, msg: Any) -> None:
        self.post(BatteryEvent(100.0 * msg.percentage, msg.voltage, -msg.current,
                               msg.header.stamp.to_sec()))

    def _on_temperatures(self, msg: Any) -> None:
        self.post(TemperaturesEvent(tuple(msg.name), np.array(msg.celsius, float),
                                    msg.header.stamp.to_sec()))

    def _on_image(self, msg: Any) -> None:
        rgb = image_pixels(msg.encoding, msg.height, msg.width, msg.data)
        if rgb is None:
            log.warning("pilot: camera image in encoding %s (%dx%d) is not shown",
                        msg.encoding, msg.width, msg.height)
            return
        self.post(ImageEvent(rgb, msg.header.stamp.to_nsec()))

    def _on_cloud(self, msg: Any) -> None:
        from walkman.head_camera import cloud_xyz

        offsets = {f.name: f.offset for f in msg.fields}
        xyz = None
        if {"x", "y", "z"} <= offsets.keys():
            try:
                xyz = cloud_xyz(bytes(msg.data), msg.point_step,
                                (offsets["x"], offsets["y"], offsets["z"]))
            except ValueError as exc:
                log.warning("pilot: %s: %s", CLOUD_TOPIC, exc)
        self.post(CloudEvent(msg.width * msg.height, msg.header.stamp.to_nsec(), xyz,
                             msg.header.frame_id))

    # -- the bridge's status (YARP, local) --------------------------------------------------

    def _open_bridge_status(self) -> None:
        from bridge.status import from_bottle
        from bridge.errors import BridgeProtocolError
        from nodekit.connections import ConnectionKeeper
        from yarp_lite.errors import YarpError
        from yarp_lite.port import Port

        def on_status(bottle) -> None:
            try:
                self.post(BridgeEvent(from_bottle(bottle), time.time()))
            except BridgeProtocolError as exc:
                log.warning("pilot: %s: %s", self.bridge_status, exc)

        try:
            port = Port(reader=on_status)
            port.open(f"/pilot/{self.name}/bridge_status:i", wait=math.inf)
        except YarpError as exc:
            log.warning("pilot: no YARP name server for the bridge status: %s", exc)
            return
        self._status_port = port
        self._keeper = ConnectionKeeper(period=1.0)
        self._keeper.want(self.bridge_status, port.name, port, ours_is_source=False)
        self._keeper.start()
