"""The 3-D view's render process: librviz's frame and the PI's pose markers, nothing else.

Theory of operation
-------------------
With Mesa's software OpenGL (llvmpipe) librviz corrupts its heap about once in
20-30 starts and the process dies of SIGSEGV or ``free(): invalid next size``
(issue 31).  So librviz lives here, in a process of its own that the PI
(:mod:`pilot.view3d_process`) starts, embeds in its window and starts again
when it dies; the PI itself never loads librviz, Ogre or OpenGL.

The PI hands us one end of a socket pair (``--fd``) and speaks
:mod:`pilot.view3d_protocol` over it.  We load Python, Qt and librviz and
register our rospy node (``<pi>_view3d_<pid>``, a
:class:`~nodekit.ros_node.RosNode`), then wait for the PI's ``go``: the PI
keeps one of us warm beside the view it shows, to take over at once when that
one dies.  Once told to go:

1. On the GUI thread, RViz's ``VisualizationFrame`` is built from
   :data:`RVIZ_CONFIG` -- the robot from ``/robot_description`` placed by
   ``/tf``, the camera's cloud (lost tiles are NaN points: holes), the PI's
   markers -- and shown frameless, past the window manager and off-screen;
   we say :class:`~pilot.view3d_protocol.WindowReady` with its X window.
   The PI reparents that window into its own (``QWindow.fromWinId`` and
   ``QWidget.createWindowContainer``); from then on the X server sends the
   mouse over it to us directly, and the PI's layout sets its size.
2. An ``interactive_markers`` server (``/pilot_markers/<pi>``) shows the pose
   markers the PI asks for (add, update, remove; a new child is told them all
   again, at the poses the pilot left them); a drag's feedback, on a ROS
   thread, goes straight back to the PI as ``moved``.
3. librviz's own roscpp node is adopted by our RosNode, which registers it
   again after a roscore restart (roscpp never does), and both names are sent
   to the PI, which hands them to the next child to unregister if we die.

We exit when the PI closes the socket, and die with it
(``PR_SET_PDEATHSIG``).  For the crash itself the PI starts us in a folder of
our own: faulthandler writes every thread's stack to ``stacks.txt`` there
and the soft core limit is raised to the hard one, so the kernel's ``core``
(``core_pattern`` permitting) lands beside it.
"""

from __future__ import annotations

import argparse
import ctypes
import faulthandler
import logging
import math
import os
import resource
import signal
import socket
import sys
import threading
import time
from typing import Dict, List, Optional, Sequence

from pilot.view3d_protocol import (AddMarker, Decoder, Direction, EnableDisplay, Go, MarkerMoved,
                                   Message, Ping, Pong, RemoteProtocolError, RemoveMarker,
                                   RosNodes, UpdateMarker, WindowReady, encode)

log = logging.getLogger("pilot.view3d_child")

#: Where stacks of a fatal signal go, in the folder the PI chose for this child.
STACKS_FILE = "stacks.txt"

RVIZ_CONFIG = """
Visualization Manager:
  Global Options:
    Fixed Frame: pelvis
    Background Color: 40; 44; 52
    Frame Rate: 15
  Displays:
    - Class: rviz/Grid
      Name: Grid
      Enabled: true
      Cell Size: 0.5
      Plane Cell Count: 12
      Offset: {X: 0, Y: 0, Z: -1.0}
    - Class: rviz/RobotModel
      Name: Robot
      Enabled: true
      Robot Description: robot_description
    - Class: rviz/RobotModel
      Name: Preview
      Enabled: false
      Robot Description: robot_description
      TF Prefix: preview
      Alpha: 0.35
    - Class: rviz/PointCloud2
      Name: Cloud
      Enabled: true
      Topic: /multisense/points
      Style: Boxes
      Size (m): 0.03
      Color Transformer: RGB8
      Queue Size: 2
    - Class: rviz/InteractiveMarkers
      Name: Markers
      Enabled: true
      Update Topic: {markers}/update
      Show Descriptions: true
  Views:
    Current:
      Class: rviz/Orbit
      Distance: 3.2
      Focal Point: {X: 0.45, Y: 0.05, Z: -0.1}
      Pitch: 0.45
      Yaw: 3.6
"""


def rpy_to_quaternion(roll: float, pitch: float, yaw: float) -> List[float]:
    """x y z w of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy]


def quaternion_to_rpy(x: float, y: float, z: float, w: float) -> List[float]:
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return [roll, pitch, yaw]


#: Each kind of object as boxes and cylinders in its own frame (the pose the pilot gives the
#: task: the valve turns about x, the drill's bit points along x...): shape, size (x y z),
#: offset (x y z), colour (r g b).
OBJECT_SHAPES = {
    "disc": [("cylinder", (0.25, 0.25, 0.03), (0, 0, 0), (1.0, 0.55, 0.0))],
    "valve": [("cylinder", (0.03, 0.30, 0.30), (0, 0, 0), (0.8, 0.1, 0.1)),
              ("cylinder", (0.12, 0.05, 0.05), (0.06, 0, 0), (0.3, 0.3, 0.3))],
    "steering_wheel": [("cylinder", (0.36, 0.36, 0.03), (0, 0, 0), (0.1, 0.1, 0.1)),
                       ("cylinder", (0.04, 0.04, 0.3), (0, 0, -0.15), (0.2, 0.2, 0.2))],
    # the lever, and the patch of door around it (the whole panel would hide the robot)
    "door": [("box", (0.03, 0.12, 0.03), (0, 0.06, 0), (0.8, 0.8, 0.2)),
             ("box", (0.02, 0.30, 0.30), (0.05, 0.0, 0), (0.7, 0.55, 0.35))],
    "drill": [("box", (0.03, 0.04, 0.10), (0, 0, 0), (0.9, 0.5, 0.1)),
              ("box", (0.18, 0.05, 0.05), (0.06, 0, 0.07), (0.9, 0.5, 0.1)),
              ("cylinder", (0.10, 0.008, 0.008), (0.20, 0, 0.07), (0.7, 0.7, 0.75))],
    "plug": [("box", (0.05, 0.05, 0.08), (0, 0, -0.10), (0.1, 0.3, 0.8)),
             ("box", (0.024, 0.06, 0.024), (0, 0, 0), (0.9, 0.9, 0.9))],
    "footstep": [("box", (0.22, 0.12, 0.02), (0, 0, 0), (0.2, 0.7, 0.3))],
}


def object_markers(kind: str) -> list:
    """The visualization markers that draw one kind of object (a disc if unknown)."""
    from visualization_msgs.msg import Marker

    out = []
    for shape, size, offset, colour in OBJECT_SHAPES.get(kind, OBJECT_SHAPES["disc"]):
        part = Marker(type=Marker.CYLINDER if shape == "cylinder" else Marker.CUBE)
        part.scale.x, part.scale.y, part.scale.z = size
        part.pose.position.x, part.pose.position.y, part.pose.position.z = offset
        if shape == "cylinder" and size[0] < size[1]:      # a wheel turning about x
            part.pose.orientation.y = part.pose.orientation.w = math.sqrt(0.5)
            part.scale.x, part.scale.z = size[1], size[0]
        elif shape == "cylinder" and size[0] > size[2]:    # a bit along x
            part.pose.orientation.y = part.pose.orientation.w = math.sqrt(0.5)
            part.scale.x, part.scale.y, part.scale.z = size[1], size[2], size[0]
        else:
            part.pose.orientation.w = 1.0
        part.color.r, part.color.g, part.color.b = colour
        part.color.a = 0.8
        out.append(part)
    return out


def pose_marker(name: str, pose: Sequence[float], kind: str = "disc"):
    """The object (``kind``) with a move and a rotate ring per axis, at ``pose`` (pelvis
    frame)."""
    from visualization_msgs.msg import InteractiveMarker, InteractiveMarkerControl

    marker = InteractiveMarker()
    marker.header.frame_id = "pelvis"
    marker.name, marker.description, marker.scale = name, name, 0.3
    marker.pose = ros_pose(pose)
    body = InteractiveMarkerControl(always_visible=True)
    body.markers.extend(object_markers(kind))
    marker.controls.append(body)
    half = math.sqrt(0.5)            # a unit quaternion per axis, as RViz wants
    for axis, (x, y, z) in {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}.items():
        for mode, verb in ((InteractiveMarkerControl.MOVE_AXIS, "move"),
                           (InteractiveMarkerControl.ROTATE_AXIS, "rotate")):
            control = InteractiveMarkerControl()
            control.name = f"{verb}_{axis}"
            control.orientation.w = half
            control.orientation.x, control.orientation.y, control.orientation.z = \
                x * half, z * half, y * half
            control.interaction_mode = mode
            marker.controls.append(control)
    return marker


def ros_pose(pose: Sequence[float]):
    from geometry_msgs.msg import Pose

    out = Pose()
    out.position.x, out.position.y, out.position.z = pose[:3]
    (out.orientation.x, out.orientation.y, out.orientation.z,
     out.orientation.w) = rpy_to_quaternion(*pose[3:6])
    return out


def pose_of(ros) -> List[float]:
    """x y z roll pitch yaw of a geometry_msgs/Pose."""
    p, o = ros.position, ros.orientation
    return [p.x, p.y, p.z, *quaternion_to_rpy(o.x, o.y, o.z, o.w)]


def process_started() -> float:
    """When this process began, on the monotonic clock (from /proc: its start in ticks)."""
    with open("/proc/self/stat") as stat:
        ticks = int(stat.read().rsplit(")", 1)[1].split()[19])
    with open("/proc/uptime") as uptime:
        up = float(uptime.read().split()[0])
    return time.monotonic() - (up - ticks / os.sysconf("SC_CLK_TCK"))


def die_with_parent() -> None:
    """SIGKILL when the PI dies, even with our GUI thread stuck (Linux only)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        log.warning("cannot ask to die with the PI (prctl): the socket's end will do")
    if os.getppid() == 1:             # the PI died before we asked
        sys.exit(1)


def keep_crash_evidence() -> None:
    """Stacks in ``stacks.txt`` and a core file here (the working folder), if we crash."""
    faulthandler.enable(open(STACKS_FILE, "w"), all_threads=True)
    _, hard = resource.getrlimit(resource.RLIMIT_CORE)
    try:
        resource.setrlimit(resource.RLIMIT_CORE, (hard, hard))
    except (ValueError, OSError):
        pass  # no core file then; stacks.txt still records a crash


# -- the process ---------------------------------------------------------------------------

from python_qt_binding.QtCore import QObject, QSocketNotifier, Qt, Signal  # noqa: E402


class RenderChild(QObject):
    """One socket to the PI, one RViz frame, one marker server; GUI thread unless said."""

    ros_ready = Signal()

    def __init__(self, sock: socket.socket, pi_name: str, markers_topic: str) -> None:
        super().__init__()
        from nodekit.ros_node import RosNode

        self.sock = sock
        self.markers_topic = markers_topic
        self.go: Optional[Go] = None            # the PI's word to be the view
        self.ros_up = False
        self.decoder = Decoder(Direction.TO_CHILD)
        self.markers: Dict[str, Sequence[float]] = {}   # name -> pose, as the PI last said
        self.kinds: Dict[str, str] = {}                # name -> how it is drawn
        self.displays: Dict[str, bool] = {}
        self.frame = None
        self.server = None
        self._send_lock = threading.Lock()
        self.notifier = QSocketNotifier(sock.fileno(), QSocketNotifier.Read, self)
        self.notifier.activated.connect(self._readable)
        self.ros = RosNode(f"{pi_name}_view3d_{os.getpid()}")
        self.ros.when_ready(self.ros_ready.emit)
        self.ros_ready.connect(self._on_ros_ready, Qt.QueuedConnection)
        self.phases: Dict[str, float] = {}     # phase -> when it ended (monotonic)

    def start(self) -> None:
        self.phases["imports"] = time.monotonic()
        self.ros.start()

    def send(self, message: Message) -> None:
        """Any thread; a PI gone away ends us."""
        data = encode(message)
        try:
            with self._send_lock:
                self.sock.sendall(data)
        except OSError as exc:
            log.info("3-D view: the PI went away (%s): exiting", exc)
            os._exit(0)

    # -- from the PI -----------------------------------------------------------------------

    def _readable(self) -> None:
        try:
            data = self.sock.recv(65536)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        self.decoder.feed(data)
        try:
            messages = self.decoder.messages()
        except RemoteProtocolError as exc:
            log.error("3-D view: the PI said something illegal: %s", exc)
            self._quit(3)
            return
        for message in messages:
            self._apply(message)
        if self.decoder.ended:
            self._quit(0)

    def _apply(self, message: Message) -> None:
        if isinstance(message, Go):
            if self.go is None:
                self.go = message
                self.phases["told to go"] = time.monotonic()
                self._build_when_ready()
        elif isinstance(message, Ping):
            self.send(Pong(message.seq))
        elif isinstance(message, AddMarker):
            self.markers[message.name] = message.pose
            self.kinds[message.name] = message.kind
            self._show_marker(message.name, insert=True)
        elif isinstance(message, UpdateMarker):
            if message.name in self.markers:
                self.markers[message.name] = message.pose
                self._show_marker(message.name, insert=False)
        elif isinstance(message, RemoveMarker):
            if self.markers.pop(message.name, None) is not None and self.server is not None:
                self.server.erase(message.name)
                self.server.applyChanges()
        elif isinstance(message, EnableDisplay):
            self.displays[message.name] = message.enabled
            self._enable_displays()

    def _show_marker(self, name: str, insert: bool) -> None:
        if self.server is None:
            return                       # shown when the server is made
        pose = self.markers[name]
        if insert:
            self.server.insert(pose_marker(name, pose, self.kinds.get(name, "disc")),
                               lambda feedback, n=name: self._dragged(n, feedback))
        else:
            self.server.setPose(name, ros_pose(pose))
        self.server.applyChanges()

    def _dragged(self, name: str, feedback) -> None:        # a ROS thread
        self.send(MarkerMoved(name, tuple(pose_of(feedback.pose))))

    def _enable_displays(self) -> None:
        if self.frame is None:
            return
        group = self.frame.getManager().getRootDisplayGroup()
        for index in range(group.numDisplays()):
            display = group.getDisplayAt(index)
            wanted = self.displays.get(display.getName())
            if wanted is not None and display.isEnabled() != wanted:
                display.setEnabled(wanted)
                log.info("3-D view: display %s %s", display.getName(), "on" if wanted else "off")

    # -- once ROS is up and the PI said go -------------------------------------------------

    def _on_ros_ready(self) -> None:
        self.ros_up = True
        self.phases["ROS"] = time.monotonic()
        self._build_when_ready()

    def _build_when_ready(self) -> None:
        if self.ros_up and self.go is not None and self.frame is None:
            self._build()

    def _build(self) -> None:
        from python_qt_binding.QtWidgets import QApplication
        from rviz import bindings as rviz

        frame = rviz.VisualizationFrame()
        # A top-level the window manager never sees, out of sight until the PI embeds it; set
        # before librviz makes its native windows (changed after, Qt would make them again,
        # the OpenGL one moved under a new parent).
        frame.setWindowFlags(Qt.Window | Qt.FramelessWindowHint |
                             Qt.X11BypassWindowManagerHint)
        frame.setSplashPath("")
        frame.initialize()
        config = rviz.Config()
        rviz.YamlConfigReader().readString(config,
                                           RVIZ_CONFIG.replace("{markers}", self.markers_topic))
        frame.load(config)
        # Hidden, not replaced: setStatusBar(None) deletes the bar that owns rviz's fps label,
        # and rviz writes to that label whenever statusBar() is again the address it kept
        # (rviz#895/#896) -- a new bar allocated where the old one was freed is: heap
        # corruption ("malloc(): unaligned tcache chunk", once in many runs).  The menus
        # live in the menu bar and rviz keeps pointers to them too.
        frame.menuBar().hide()
        frame.statusBar().hide()
        frame.setHideButtonVisibility(False)
        frame.move(-10000, -10000)
        frame.resize(640, 480)
        frame.show()
        QApplication.processEvents()
        self.frame = frame
        self._enable_displays()
        self.send(WindowReady(int(frame.winId()), os.getpid()))
        self.phases["librviz"] = time.monotonic()
        marks = [("python", process_started()),
                 *sorted(self.phases.items(), key=lambda phase: phase[1])]
        log.info("3-D view: window up %.2f s after the PI's go, %.2f s after our start (%s)",
                 marks[-1][1] - self.phases["told to go"], marks[-1][1] - marks[0][1],
                 ", ".join(f"{name} {end - begin:.2f} s" for (_, begin), (name, end)
                           in zip(marks, marks[1:])))

        from interactive_markers.interactive_marker_server import InteractiveMarkerServer

        self.server = InteractiveMarkerServer(self.markers_topic.lstrip("/"))
        for name in list(self.markers):
            self._show_marker(name, insert=True)
        threading.Thread(target=self._adopt, name="adopt librviz", daemon=True).start()

    def _adopt(self) -> None:                               # its own thread: the master
        import rosgraph

        from nodekit.ros_node import nodes_of_this_process

        own = f"/{self.ros.name}"
        forget = list(self.go.forget) if self.go is not None else []
        try:
            if forget:
                import rosnode

                rosnode.cleanup_master_blacklist(rosgraph.Master(own), forget)
                log.info("3-D view: unregistered the dead view's nodes %s", ", ".join(forget))
            self.ros.adopt()
            found = nodes_of_this_process(rosgraph.Master(own))
        except Exception as exc:  # noqa: BLE001 -- the master went away meanwhile
            log.warning("3-D view: cannot list our ROS nodes: %s", exc)
            return
        self.send(RosNodes(own, {n: uri for n, uri in found.items() if n != own}))

    def _quit(self, code: int) -> None:
        if self.server is not None:
            self.server.clear()
            self.server.applyChanges()
        self.ros.stop()
        from python_qt_binding.QtWidgets import QApplication

        QApplication.instance().exit(code)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m pilot.view3d_child",
        description="The PI's 3-D view (librviz) in a process of its own; started by the PI.")
    parser.add_argument("--fd", type=int, required=True,
                        help="the PI's end of the socket pair (pilot.view3d_protocol)")
    parser.add_argument("--pi", required=True, help="the PI's name (our node is <pi>_view3d_<pid>)")
    parser.add_argument("--markers", required=True,
                        help="the interactive marker server's topic (/pilot_markers/<pi>)")
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    options = build_parser().parse_args(argv)
    from nodekit.logs import configure_logging

    configure_logging("view3d")
    keep_crash_evidence()
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # ^C is the PI's to handle: it closes us
    sock = socket.socket(fileno=options.fd)
    from python_qt_binding.QtWidgets import QApplication

    app = QApplication(sys.argv[:1])
    child = RenderChild(sock, options.pi, options.markers)
    child.start()
    from rviz import bindings  # noqa: F401 -- loaded (Ogre...) while the ROS thread registers
    return app.exec_()


if __name__ == "__main__":
    sys.exit(main())
