"""The 3-D view: librviz in the window -- the robot, the point cloud, interactive markers.

Theory of operation
-------------------
As the paper's PI did, the view embeds RViz's own ``VisualizationFrame``
(Debian's ``python3-rviz`` bindings) configured from :data:`RVIZ_CONFIG`: the
robot model from ``/robot_description`` placed by ``/tf`` (both from
``walkman-joint-state``), the camera's cloud (missing regions are NaN points:
they leave holes you can see), and this PI's interactive markers.

Each task widget with a ``...datasent`` pose gets a 6-DOF interactive marker
(an ``interactive_markers`` server of this PI, ``/pilot_markers/<pi>``); the
pilot drags it onto the cloud where the valve (door, wheel) is, and the
marker's feedback, arriving on a ROS thread, is handed to the GUI thread to
move the widget's pose fields.  The frame is created once the PI's ROS node is
up (librviz needs the master); until then the view says what it waits for.
"""

from __future__ import annotations

import math
from typing import Callable, Dict, List, Sequence

from python_qt_binding.QtCore import QObject, Qt, Signal
from python_qt_binding.QtWidgets import QLabel, QVBoxLayout, QWidget

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


class _Feedback(QObject):
    moved = Signal(str, object)     # marker name, [x y z roll pitch yaw]


class View3D(QWidget):
    """librviz's frame plus this PI's pose markers; starts empty until ROS is up."""

    def __init__(self, pi_name: str, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("view3d")
        self.markers_topic = f"/pilot_markers/{pi_name}"
        self.layout_ = QVBoxLayout(self)
        self.layout_.setContentsMargins(0, 0, 0, 0)
        self.placeholder = QLabel("3-D view: waiting for the pilot roscore")
        self.layout_.addWidget(self.placeholder)
        self.frame = None

        self.server = None
        self.feedback = _Feedback()
        self._targets: Dict[str, Callable[[Sequence[float]], None]] = {}
        self._starts: Dict[str, Sequence[float]] = {}
        self.feedback.moved.connect(self._moved, Qt.QueuedConnection)
        self.setMinimumSize(360, 300)

    def start(self) -> None:
        """Create the librviz frame (on the GUI thread, once the ROS node is registered)."""
        if self.frame is not None:
            return
        from rviz import bindings as rviz

        frame = rviz.VisualizationFrame()
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
        self.layout_.removeWidget(self.placeholder)
        self.placeholder.deleteLater()
        self.layout_.addWidget(frame)
        self.frame = frame

        from interactive_markers.interactive_marker_server import InteractiveMarkerServer

        self.server = InteractiveMarkerServer(self.markers_topic.lstrip("/"))
        for name in list(self._targets):
            self._add_marker(name, self._starts[name])

    def add_pose_marker(self, name: str, start: Sequence[float],
                        on_move: Callable[[Sequence[float]], None]) -> None:
        """A draggable 6-DOF marker named ``name``; ``on_move`` gets x y z roll pitch yaw."""
        self._targets[name] = on_move
        self._starts[name] = list(start)
        if self.server is not None:
            self._add_marker(name, start)

    def _add_marker(self, name: str, pose: Sequence[float]) -> None:
        from visualization_msgs.msg import (InteractiveMarker, InteractiveMarkerControl,
                                            Marker)

        marker = InteractiveMarker()
        marker.header.frame_id = "pelvis"
        marker.name, marker.description, marker.scale = name, name, 0.3
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = pose[:3]
        q = rpy_to_quaternion(*pose[3:6])
        (marker.pose.orientation.x, marker.pose.orientation.y, marker.pose.orientation.z,
         marker.pose.orientation.w) = q
        body = InteractiveMarkerControl(always_visible=True)
        disc = Marker(type=Marker.CYLINDER)
        disc.scale.x = disc.scale.y = 0.25
        disc.scale.z = 0.03
        disc.color.r, disc.color.g, disc.color.b, disc.color.a = 1.0, 0.55, 0.0, 0.8
        body.markers.append(disc)
        marker.controls.append(body)
        for axis, (x, y, z) in {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}.items():
            for mode in (InteractiveMarkerControl.MOVE_AXIS, InteractiveMarkerControl.ROTATE_AXIS):
                control = InteractiveMarkerControl()
                control.name = f"{'move' if mode == InteractiveMarkerControl.MOVE_AXIS else 'rotate'}_{axis}"
                half = math.sqrt(0.5)            # a unit quaternion per axis, as RViz wants
                control.orientation.w = half
                control.orientation.x, control.orientation.y, control.orientation.z = \
                    x * half, z * half, y * half
                control.interaction_mode = mode
                marker.controls.append(control)
        self.server.insert(marker, lambda feedback, n=name: self._on_feedback(n, feedback))
        self.server.applyChanges()

    def _on_feedback(self, name: str, feedback) -> None:    # a ROS thread
        p, o = feedback.pose.position, feedback.pose.orientation
        self.feedback.moved.emit(name, [p.x, p.y, p.z, *quaternion_to_rpy(o.x, o.y, o.z, o.w)])

    def _moved(self, name: str, pose) -> None:              # the GUI thread
        target = self._targets.get(name)
        if target is not None:
            target(pose)

    def close_view(self) -> None:
        if self.server is not None:
            self.server.clear()
            self.server.applyChanges()
