"""The 3-D view: librviz's window, drawn by a process of its own, embedded in the PI's.

Theory of operation
-------------------
As the paper's PI did, the view is RViz's own ``VisualizationFrame``: the
robot from ``/robot_description`` placed by ``/tf``, the camera's cloud with
its holes, and this PI's interactive markers.  librviz crashes now and then
under Mesa's software OpenGL (issue 31), so it runs in a render process
(:mod:`pilot.view3d_child`) kept alive by a
:class:`~pilot.view3d_process.RenderSupervisor`; this widget only embeds the
X window that process shows (``QWindow.fromWinId`` +
``QWidget.createWindowContainer``) and, while there is none, says why in the
view's place: "waiting for the pilot roscore", "starting", or "restarting --
it crashed: signal 11 (SIGSEGV)".  The rest of the PI never waits for it.

What must outlive a crash lives here: each task widget's pose marker (its
callback and where the pilot last left it) and the displays switched off.
Every new render process is told all of it again, so a restart is a blink,
not a loss.  A drag in the child comes back as ``moved`` and moves the task
widget's pose fields, as it did when librviz lived in the PI.

While the link is down a banner above the view says so, and how old the robot's pose and
the cloud it draws are: librviz keeps drawing the last of each as if it were now.

The embedded window belongs to the child: when the child dies its window is
gone, and we drop our container at once, before the next child can be
given the dead window's X id (the X server reuses a dead client's ids).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence

from python_qt_binding.QtCore import Qt, Signal
from python_qt_binding.QtWidgets import QLabel, QVBoxLayout, QWidget

from pilot.link_cut import LinkCut
from pilot.widgets.generic import LINK_DOWN_COLOUR
from pilot.view3d_process import ChildExit, RenderSupervisor
from pilot.view3d_protocol import (AddMarker, EnableDisplay, MarkerMoved, Message, RemoveMarker,
                                   RosNodes, UpdateMarker)

log = logging.getLogger("pilot.view3d")


@dataclass
class PoseMarker:
    """A task's marker as the PI knows it: where it is, and whom a drag tells."""

    pose: List[float]
    on_move: Callable[[Sequence[float]], None]
    kind: str = "disc"


class View3D(QWidget):
    """librviz's window from its render process, or what the 3-D view is waiting for."""

    #: A line for the pilot's log: the view died (and why), the view is back.
    said = Signal(str)

    def __init__(self, pi_name: str, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("view3d")
        self.pi_name = pi_name
        self.markers_topic = f"/pilot_markers/{pi_name}"
        self.layout_ = QVBoxLayout(self)
        self.layout_.setContentsMargins(0, 0, 0, 0)
        #: While the link is down: how old the robot's pose and the cloud drawn are.
        self.cut = LinkCut()
        self.robot_at: Optional[float] = None    # when the last joint states came
        self.cloud_at: Optional[float] = None    # when the last cloud came
        self.link_banner = QLabel("")
        self.link_banner.setObjectName("view3d_link")
        self.link_banner.setWordWrap(True)
        self.link_banner.setStyleSheet(f"color: {LINK_DOWN_COLOUR}; font-weight: bold;")
        self.link_banner.setVisible(False)
        self.layout_.addWidget(self.link_banner)
        self.status = QLabel("3-D view: waiting for the pilot roscore")
        self.status.setObjectName("view3d_status")
        self.status.setAlignment(Qt.AlignCenter)
        self.status.setWordWrap(True)
        self.layout_.addWidget(self.status, 1)
        self.container: Optional[QWidget] = None
        self.supervisor: Optional[RenderSupervisor] = None
        self.markers: Dict[str, PoseMarker] = {}
        self.displays: Dict[str, bool] = {}
        self.embedded_pid: Optional[int] = None     # the child whose window we show
        self._down_at: Optional[float] = None
        self.deaths: List[ChildExit] = []          # every render process that ended
        #: librviz's roscpp node(s) in the current child (name -> URI), once it said.
        self.ros_nodes: Dict[str, str] = {}
        self.setMinimumSize(360, 300)

    def start(self) -> None:
        """Start the render process (once this PI's ROS node is registered)."""
        from python_qt_binding.QtGui import QGuiApplication

        if self.supervisor is not None:
            return
        platform = QGuiApplication.platformName()
        if platform != "xcb":
            self._say(f"3-D view: librviz draws on an X display only (Qt platform {platform})")
            return
        self.supervisor = RenderSupervisor(self.pi_name, self.markers_topic)
        self.supervisor.up.connect(self._up)
        self.supervisor.down.connect(self._down)
        self.supervisor.message.connect(self._message)
        self.supervisor.start()
        self._say("3-D view: starting librviz")

    def cannot_start(self, why: str) -> None:
        """The render process will not start (this PI's ROS side did not open): say why in
        the view's place instead of waiting for the roscore."""
        self._say(f"3-D view: not started -- {why}")

    # -- what the PI asks ------------------------------------------------------------------

    def add_pose_marker(self, name: str, start: Sequence[float],
                        on_move: Callable[[Sequence[float]], None], kind: str = "disc") -> None:
        """A draggable 6-DOF marker named ``name``, drawn as a ``kind`` of object;
        ``on_move`` gets x y z roll pitch yaw."""
        self.markers[name] = PoseMarker(list(start), on_move, kind)
        self._send(AddMarker(name, tuple(start), kind))

    def move_pose_marker(self, name: str, pose: Sequence[float]) -> None:
        """The marker follows a pose typed elsewhere."""
        if name in self.markers:
            self.markers[name].pose = list(pose)
            self._send(UpdateMarker(name, tuple(pose)))

    def remove_pose_marker(self, name: str) -> None:
        if self.markers.pop(name, None) is not None:
            self._send(RemoveMarker(name))

    def set_display_enabled(self, name: str, enabled: bool) -> None:
        """Switch one of RViz's displays (``Grid``, ``Robot``, ``Cloud``, ``Markers``)."""
        self.displays[name] = enabled
        self._send(EnableDisplay(name, enabled))

    def applied(self) -> Callable[[], bool]:
        """A condition that turns true once the render process has applied everything asked
        of it so far (markers, displays); false while there is none.  If that process dies
        meanwhile (librviz's own crash), the next one is asked afresh: it is given every
        marker and display when it is embedded, so its answer means the same."""
        asked: Dict[str, Optional[int]] = {"pid": None, "seq": None}

        def check() -> bool:
            supervisor, pid = self.supervisor, self.embedded_pid
            if supervisor is None or pid is None or supervisor.pid != pid:
                return False
            if asked["pid"] != pid:
                asked["pid"], asked["seq"] = pid, supervisor.ping()
                return False
            return supervisor.answered_seq >= asked["seq"]
        check()                    # ask the process now running at once
        return check

    def close_view(self) -> None:
        if self.supervisor is not None:
            self.supervisor.close()
        self._drop_container()

    # -- what the robot sends (through the PI's link) -------------------------------------

    def on_joints(self, event) -> None:
        self.robot_at = self.cut.clock()

    def on_cloud(self, event) -> None:
        self.cloud_at = self.cut.clock()

    def on_link(self, event) -> None:
        self.cut.on_link(event)
        self.tick()

    def tick(self) -> None:
        """The banner's ages, each second of a cut (the window's timer)."""
        banner = self.cut.banner_of([("the robot", self.robot_at),
                                     ("the cloud", self.cloud_at)])
        self.link_banner.setText(banner)
        self.link_banner.setVisible(bool(banner))

    # -- what the render process says ------------------------------------------------------

    def _up(self, window: int, pid: int) -> None:
        from python_qt_binding.QtGui import QWindow

        self._drop_container()
        foreign = QWindow.fromWinId(window)
        container = QWidget.createWindowContainer(foreign, self)
        container.setObjectName("view3d_window")
        container.setMinimumSize(200, 150)
        self.layout_.addWidget(container, 1)
        self.container = container
        self.embedded_pid = pid
        self.status.hide()
        if self._down_at is not None:
            self.said.emit(f"3-D view back (pid {pid}), {time.monotonic() - self._down_at:.1f} s "
                           f"after it {self.deaths[-1].reason.split(':')[0]}")
            self._down_at = None
        for name, marker in self.markers.items():      # a new child knows nothing yet
            self._send(AddMarker(name, tuple(marker.pose), marker.kind))
        for name, enabled in self.displays.items():
            self._send(EnableDisplay(name, enabled))

    def _down(self, exit: ChildExit, delay: float) -> None:
        self._drop_container()
        self.ros_nodes = {}
        self.deaths.append(exit)
        if self._down_at is None:
            self._down_at = time.monotonic()
        when = "" if delay == 0 else f", next try in {delay:g} s"
        self._say(f"3-D view restarting \N{EM DASH} it {exit.reason}{when}")
        self.said.emit(f"3-D view (pid {exit.pid}) {exit.reason}: restarting it{when}; the rest "
                       f"of the PI is unaffected")

    def _message(self, message: Message) -> None:
        if isinstance(message, MarkerMoved):
            marker = self.markers.get(message.name)
            if marker is not None:
                marker.pose = list(message.pose)
                marker.on_move(list(message.pose))
        elif isinstance(message, RosNodes):
            self.ros_nodes = dict(message.librviz)

    def _send(self, message: Message) -> None:
        if self.supervisor is not None and self.embedded_pid is not None:
            self.supervisor.send(message)

    def _say(self, text: str) -> None:
        self.status.setText(text)
        self.status.show()

    def _drop_container(self) -> None:
        """Forget the embedded window now (its X id may soon be another client's)."""
        self.embedded_pid = None
        if self.container is not None:
            container, self.container = self.container, None
            self.layout_.removeWidget(container)
            container.hide()
            container.deleteLater()
