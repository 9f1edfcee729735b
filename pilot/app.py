"""``walkman-pilot``: the Pilot Interface window, composed from a named layout.

Theory of operation
-------------------
:class:`PilotWindow` builds the widgets a layout names (:mod:`pilot.layouts`)
for the modules of the bridge configuration, starts a :class:`~pilot.link.PilotLink`
and routes its events -- posted from ROS and YARP threads -- through one Qt
signal onto the GUI thread, where :meth:`PilotWindow.dispatch` hands each to
the widgets that show it.  A timer refreshes ages twice a second.  The 3-D view
starts once the ROS node is registered.  Several PIs may run at once, on one
pilot PC or several: each has its own name (``--name``, shown in every pilot's
log beside its commands) and its own markers.

Killing a PI loses nothing: commands are in the gateway or the bridge once
sent, countdowns run in the gateway, and a new PI with the same layout shows
the current state from the latched status topics.
"""

from __future__ import annotations

import argparse
import faulthandler
import logging
import os
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Sequence, Set, Tuple

from bridge import config as bridge_config
from nodekit.scene import TASK_OBJECTS
from pilot.catalogue import catalogue_of
from pilot.layouts import DEFAULT_LAYOUTS, Layout, LayoutError, Widget, load_layout
from pilot.preview import PreviewGate

if TYPE_CHECKING:       # at run time imported where the widgets are (Qt first)
    from pilot.widgets.tasks import TaskWidget
from walkman import MODELS_DIR

log = logging.getLogger("pilot.app")
DEFAULT_CONFIG = MODELS_DIR / "bridge_drc.xml"


#: The window's size where the screen has room (the GUI tests' Xvfb screen is 1400x900).
PREFERRED_SIZE = (1400, 900)


def window_size(available) -> tuple:
    """The preferred size, or the screen's room where it is smaller (a 1366x768 laptop):
    the window opens whole on the screen, and grows with it when the pilot maximises it."""
    return (min(PREFERRED_SIZE[0], available.width()), min(PREFERRED_SIZE[1], available.height()))


def configured_modules(path: Path) -> Dict[str, List[str]]:
    """The GYM modules of a bridge configuration and their declared states."""
    config = bridge_config.load(path)
    return {name: list(statuses) for name, statuses in config.gym_modules.items()}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="walkman-pilot",
        description="The Pilot Interface: the robot's modules, 3-D view, camera and status.")
    parser.add_argument("--layout", default="main-pilot",
                        help="layout name in the layouts file (default %(default)s)")
    parser.add_argument("--layouts", type=Path, default=DEFAULT_LAYOUTS,
                        help="layouts file (default %(default)s)")
    parser.add_argument("--list-layouts", action="store_true", help="list the layouts and exit")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG,
                        help="bridge configuration listing the modules (default %(default)s)")
    parser.add_argument("--name", default="",
                        help="this PI's name in every pilot's log (default pi_<host>_<pid>)")
    parser.add_argument("--advanced", action="store_true",
                        help="advanced mode: every button enabled (the pilot knows the risk)")
    parser.add_argument("--screenshot", type=Path,
                        help="save a screenshot of the window there after --screenshot-after s")
    parser.add_argument("--screenshot-after", type=float, default=8.0)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    options = build_parser().parse_args(argv)
    try:
        modules = configured_modules(options.config)
        id_names = bridge_config.load(options.config).id_names()
        if options.list_layouts:
            from pilot.layouts import parse_layouts

            for name, layout in parse_layouts(options.layouts.read_text(), str(options.layouts),
                                              list(modules)).items():
                print(f"{name:20s} {layout.description}")
            return 0
        layout = load_layout(options.layout, options.layouts, list(modules))
    except (LayoutError, bridge_config.ConfigError, OSError) as exc:
        print(f"walkman-pilot: {exc}", file=sys.stderr)
        return 2
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY") and \
            os.environ.get("QT_QPA_PLATFORM", "") not in ("offscreen", "minimal"):
        print("walkman-pilot: no display (DISPLAY is not set); run it on a desktop, under "
              "xvfb-run, or pilot with rostopic (launch_scripts/pilot_pc.sh --no-gui)",
              file=sys.stderr)
        return 2
    from nodekit.logs import configure_logging

    configure_logging("pilot")
    faulthandler.enable()   # a crash in Qt leaves every thread's stack on stderr (librviz's
    #                         render process keeps its own: pilot.view3d_child)
    name = options.name or f"pi_{os.uname().nodename.replace('-', '_')}_{os.getpid()}"
    from python_qt_binding.QtWidgets import QApplication

    app = QApplication.instance() or QApplication(sys.argv[:1])
    window = PilotWindow(layout, modules, name, advanced=options.advanced, id_names=id_names)
    window.show()
    window.start()
    from python_qt_binding.QtCore import QTimer

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: app.quit())
    keep_python_awake = QTimer()        # lets Python see the signals while Qt runs
    keep_python_awake.timeout.connect(lambda: None)
    keep_python_awake.start(200)
    if options.screenshot is not None:
        QTimer.singleShot(int(options.screenshot_after * 1000),
                          lambda: window.screenshot(options.screenshot))
    print(f"walkman-pilot: {name} window up (layout {layout.name})", flush=True)
    code = app.exec_()
    window.close_link()
    return code


# -- the window ---------------------------------------------------------------------------

from python_qt_binding.QtCore import QObject, Qt, QTimer, Signal  # noqa: E402
from python_qt_binding.QtWidgets import (QApplication, QCheckBox, QHBoxLayout, QLabel,  # noqa: E402
                                         QMainWindow, QPushButton, QSplitter,
                                         QScrollArea, QTabWidget, QVBoxLayout, QWidget)

from pilot import link as events  # noqa: E402


#: The method of a widget that shows each kind of event (a widget without it ignores it).
ROUTES = {events.StatusEvent: "on_status", events.WarningEvent: "on_warning",
          events.CountdownEvent: "on_countdown", events.SentEvent: "on_sent",
          events.JointsEvent: "on_joints", events.TemperaturesEvent: "on_temperatures",
          events.ImageEvent: "on_image", events.CloudEvent: "on_cloud",
          events.ArrivalEvent: "on_arrival",
          events.BridgeEvent: "on_bridge", events.LinkEvent: "on_link",
          events.CommandStateEvent: "on_command_state", events.BatteryEvent: "on_battery"}


class _Events(QObject):
    arrived = Signal(object)


class PilotWindow(QMainWindow):
    def __init__(self, layout: Layout, modules: Dict[str, List[str]], name: str,
                 advanced: bool = False, id_names: Optional[Dict[int, str]] = None) -> None:
        super().__init__()
        self.id_names = id_names if id_names is not None else \
            bridge_config.load(DEFAULT_CONFIG).id_names()
        self.layout_spec = layout
        self.name = name
        self.modules = modules
        self.setWindowTitle(f"Walk-Man Pilot Interface - {layout.name} - {name}")
        self.events = _Events()
        self.events.arrived.connect(self.dispatch, Qt.QueuedConnection)
        self.module_widgets: Dict[str, List[Any]] = {m: [] for m in modules}
        self.view3d = self.camera = self.status = self.link_widget = self.log = None
        self.ros_up = False
        self.started_at = time.monotonic()
        self.ready_after: Optional[float] = None
        self.advanced_box = QCheckBox("advanced mode (every button enabled)")
        self.advanced_box.setObjectName("advanced")
        self.advanced_box.setChecked(advanced)
        self.advanced_box.toggled.connect(lambda _: self._tick())

        central = QWidget()
        outer = QVBoxLayout(central)
        self.banner = QLabel("connecting to the pilot roscore...")
        self.banner.setObjectName("banner")
        self.banner.setWordWrap(True)     # a long reason never widens the window past the screen
        top = QHBoxLayout()
        top.addWidget(self.banner, 1)
        # In every layout: one click holds the whole robot (HAL and every module).
        self.stop_button = QPushButton("STOP ALL")
        self.stop_button.setObjectName("stop_all")
        self.stop_button.setStyleSheet("background-color: #c00000; color: white; "
                                       "font-weight: bold; font-size: 16px; padding: 6px 18px;")
        self.stop_button.setToolTip("hold the robot now: the HAL keeps every joint where it "
                                    "is and every module pauses (over a bad link too)")
        self.stop_button.clicked.connect(lambda: self._stop_all("stop_all"))
        self.release_button = QPushButton("release")
        self.release_button.setObjectName("release")
        self.release_button.setToolTip("let the HAL move again; each module stays paused "
                                       "until you resume it")
        self.release_button.clicked.connect(lambda: self._stop_all("release"))
        top.addWidget(self.stop_button)
        top.addWidget(self.release_button)
        outer.addLayout(top)
        splitter = QSplitter(Qt.Horizontal)
        self.tabs = QTabWidget()
        self.tabs.setObjectName("tabs")
        for title, widgets in layout.tabs:
            self.tabs.addTab(self._column(widgets), title)
        splitter.addWidget(self.tabs)
        if layout.side:
            splitter.addWidget(self._column(layout.side, scroll=False))
        outer.addWidget(splitter, 1)
        outer.addWidget(self.advanced_box)
        self.setCentralWidget(central)
        self.resize(*window_size(QApplication.primaryScreen().availableGeometry()))

        needs_camera = any(w.kind in ("camera", "view3d") for w in layout.widgets())
        self.link = events.PilotLink(name, list(modules), self.events.arrived.emit,
                                     camera=needs_camera)
        self.preview = PreviewGate(self._state_of, self._show_ghost, self._note)
        self.ghost: Optional[Any] = None          # the shown preview's placements
        self.ghosts_shown = 0                     # how many previews were shown so far
        self._kinematics: Optional[Any] = None    # for the ghost's links, made when first shown
        self.cloud: Optional[events.CloudEvent] = None   # the head camera's last, with x y z
        self._edited: Set[str] = set()            # scene objects this window has dragged
        self.timer = QTimer(self)
        self.timer.timeout.connect(self._tick)
        self.timer.start(500)

    # -- building --------------------------------------------------------------------------

    def _column(self, widgets: List[Widget], scroll: bool = True) -> QWidget:
        column = QWidget()
        layout = QVBoxLayout(column)
        for spec in widgets:
            for widget in self._make(spec):
                layout.addWidget(widget)
        layout.addStretch(0)
        if not scroll or any(w.kind in ("view3d", "camera") for w in widgets):
            return column
        area = QScrollArea()
        area.setWidgetResizable(True)
        area.setWidget(column)
        return area

    def _make(self, spec: Widget) -> List[QWidget]:
        from pilot.widgets.camera import CameraView
        from pilot.widgets.generic import GenericWidget
        from pilot.widgets.link import LinkWidget
        from pilot.widgets.log import LogView
        from pilot.widgets.status import StatusTab
        from pilot.widgets.tasks import TASK_MODULES, task_widget_class
        from pilot.widgets.view3d import View3D

        advanced = self.advanced_box.isChecked
        if spec.kind in ("task", "generic"):
            catalogue = catalogue_of(spec.module, self.modules.get(spec.module, []))
            cls = task_widget_class(spec.module) \
                if spec.kind == "task" and spec.module in TASK_MODULES else GenericWidget
            widget = cls(catalogue, self, advanced)
            self.module_widgets[spec.module].append(widget)
            return [widget]
        if spec.kind == "modules":
            out = []
            for module in self.modules:
                widget = GenericWidget(catalogue_of(module, self.modules[module]),
                                       self, advanced)
                self.module_widgets[module].append(widget)
                out.append(widget)
            return out
        if spec.kind == "view3d":
            self.view3d = View3D(self.name)
            self.view3d.said.connect(lambda text: self.log is not None and self.log.note(text))
            return [self.view3d]
        if spec.kind == "camera":
            self.camera = CameraView()
            return [self.camera]
        if spec.kind == "status":
            self.status = StatusTab(list(self.modules))
            return [self.status]
        if spec.kind == "link":
            self.link_widget = LinkWidget(self.id_names)
            return [self.link_widget]
        if spec.kind == "log":
            self.log = LogView(self.name)
            return [self.log]
        raise LayoutError(f"no widget '{spec}'")

    # what widgets call (the link is created after them)
    def switch(self, module: str, word: str) -> str:
        return self.link.switch(module, word)

    def command(self, module: str, name: str, numbers=(), dangerous: bool = False) -> str:
        return self.preview.command(
            module, name, numbers, dangerous,
            lambda: self.link.command(module, name, numbers, dangerous))

    def _placed(self, widget: TaskWidget, pose: Sequence[float]) -> None:
        """The pilot dragged a task's object: its fields follow, and every pilot is told."""
        if widget.module in TASK_OBJECTS:
            self._dragged(widget.module, TASK_OBJECTS[widget.module], pose)
        else:
            widget.set_pose(pose)

    def _on_scene(self, event: events.SceneEvent) -> None:
        """Another pilot placed an object: the marker and the task's fields follow it (what
        this window dragged is already shown, and a late echo must not pull a marker being
        dragged; a PI restarted under the same name takes its earlier edits from the scene)."""
        for obj in event.objects:
            if obj.sender == self.name and obj.name in self._edited:
                continue
            self._show_object(obj.name, obj.kind, None if obj.removed else list(obj.pose))

    def place(self, name: str, kind: str, pose: Sequence[float], removed: bool = False,
              dragged: bool = False) -> str:
        """This pilot put (or took away) an object of the shared scene: shown here at once
        (a ``dragged`` marker is already where the pilot holds it), every pilot told; '' or
        why it did not leave."""
        self._edited.add(name)
        self._show_object(name, kind, None if removed else list(pose[:6]), marker=not dragged)
        return self.link.place(name, kind, pose[:6], removed)

    def _show_object(self, name: str, kind: str, pose: Optional[List[float]],
                     marker: bool = True) -> None:
        """An object's marker, and the widgets that take its pose, follow it (None: gone)."""
        for widget in self.task_widgets():
            if widget.module == name and pose is not None:
                widget.set_pose(pose)
            if kind == "footstep" and hasattr(widget, "footstep_moved"):
                widget.footstep_moved(name, pose)
        if self.view3d is None or not marker:
            return
        if pose is None:
            self.view3d.remove_pose_marker(name)
        elif name in self.view3d.markers:
            self.view3d.move_pose_marker(name, pose)
        else:                                       # an object no widget of ours has
            self.view3d.add_pose_marker(name, pose,
                                        lambda p, n=name, k=kind: self._dragged(n, k, p),
                                        kind=kind)

    def _dragged(self, name: str, kind: str, pose: Sequence[float]) -> None:
        """A marker of the shared scene dragged here (a Qt slot: never raises)."""
        try:
            problem = self.place(name, kind, pose, dragged=True)
        except Exception as exc:  # noqa: BLE001 -- PyQt aborts the process on a slot's exception
            log.exception("pilot: %s dragged, not placed", name)
            problem = f"{name} not placed: {exc}"
        if problem:
            self._note(problem)

    def soles(self) -> Optional[Dict[str, Tuple[float, ...]]]:
        """Each sole's pose (x, y, z, roll, pitch, yaw) in the pelvis frame from the robot's last joint
        state -- where a new footstep is placed from -- or None before the first one."""
        if self.preview.posture is None:
            return None
        from walkman.modules.walking import sole_poses

        return sole_poses(self.kinematics(), self.preview.posture)

    def kinematics(self) -> Any:
        """The robot's kinematics (pinocchio: made when first needed, not at the PI's start)."""
        if self._kinematics is None:
            from walkman.control.kinematics import Kinematics

            self._kinematics = Kinematics()
        return self._kinematics

    def footsteps_from_camera(self, distance: float) -> Tuple[List[Tuple[float, ...]], str]:
        """Footsteps ``distance`` m ahead, placed on what the head camera's last cloud shows,
        by the robot's last joint state (:mod:`pilot.camera_footsteps`); ([], why) if not."""
        from pilot.camera_footsteps import footsteps_from_camera

        return footsteps_from_camera(self.cloud, self.preview.posture, self.kinematics(),
                                     distance, time.time())

    def _state_of(self, module: str) -> Optional[str]:
        return next((w.state for w in self.module_widgets.get(module, [])
                     if w.state is not None), None)

    def _note(self, text: str) -> None:
        log.info("pilot: %s", text)
        if self.log is not None:
            self.log.note(text)

    def _show_ghost(self, module: str, posture: Sequence[float]) -> None:
        """The preview's posture as the 3-D view's translucent second robot."""
        self.ghost = self.kinematics().link_placements(posture)
        self.ghosts_shown += 1
        self.link.publish_ghost(self.ghost)
        if self.view3d is not None:
            self.view3d.set_display_enabled("Preview", True)

    def _hide_ghost(self) -> None:
        if self.ghost is not None and self.view3d is not None:
            self.view3d.set_display_enabled("Preview", False)
        self.ghost = None

    def cancel(self, module: str, seq: int = 0) -> str:
        return self.link.cancel(module, seq)

    def _stop_all(self, word: str) -> None:
        problem = self.link.stop_all(word)
        text = problem or ("STOP ALL sent: waiting for the robot's answer" if word == "stop_all"
                           else "release sent")
        self.banner.setText(text)
        if self.log is not None:
            self.log.note(text)

    def _on_stop(self, event: events.StopEvent) -> None:
        what = "STOP ALL" if event.word == "stop_all" else "release"
        text = (f"{what}: {event.message} ({event.round_trip_ms:.0f} ms)" if event.ok else
                f"{what} NOT confirmed: {event.message}")
        self.banner.setText(text)
        self.banner.setStyleSheet("" if event.ok and event.word == "release" else
                                  "color: #c00000; font-weight: bold;")
        if self.log is not None:
            self.log.note(text)

    # -- running ---------------------------------------------------------------------------

    def start(self) -> None:
        self.link.start()

    def close_link(self) -> None:
        if self.view3d is not None:
            self.view3d.close_view()
        self.link.close()

    def closeEvent(self, event) -> None:  # noqa: N802 -- Qt's name
        self.close_link()
        super().closeEvent(event)

    def task_widgets(self) -> List[Any]:
        from pilot.widgets.tasks import TaskWidget

        return [w for ws in self.module_widgets.values() for w in ws if isinstance(w, TaskWidget)]

    def dispatch(self, event: Any) -> None:
        """One event on the GUI thread; a widget's bug is logged, never fatal to the PI."""
        try:
            self._dispatch(event)
        except Exception:  # noqa: BLE001 -- PyQt aborts the process on a slot's exception
            log.exception("pilot: showing %s failed", type(event).__name__)

    def _dispatch(self, event: Any) -> None:
        if isinstance(event, events.StopEvent):
            self._on_stop(event)
            return
        if isinstance(event, events.RosEvent) and event.failed:
            self.ros_up = False       # its widgets' sends are refused ("not connected")
            self.banner.setText(f"{self.name}: its ROS side did not open, nothing can be "
                                f"sent -- {event.failed}")
            self.banner.setStyleSheet("color: #c00000; font-weight: bold;")
            log.error("pilot: %s cannot pilot: its ROS side did not open", self.name)
            if self.view3d is not None:
                self.view3d.cannot_start("this PI's ROS side did not open")
            return
        if isinstance(event, events.RosEvent):
            self.ros_up = event.up
            self.banner.setText(f"{self.name}: on the pilot roscore "
                                f"({os.environ.get('ROS_MASTER_URI', 'default master')})")
            if self.ready_after is None:
                self.ready_after = time.monotonic() - self.started_at
                log.info("pilot: %s usable %.2f s after its window was made", self.name,
                         self.ready_after)
            if event.again:
                self.banner.setText(f"{self.name}: registered again with a restarted roscore "
                                    f"({time.strftime('%H:%M:%S')})")
                return
            if self.view3d is not None:
                self.view3d.start()                 # librviz's own process
                for widget in self.task_widgets():
                    pose = widget.pose()
                    if pose is not None:
                        self.view3d.add_pose_marker(
                            widget.module, pose, lambda p, w=widget: self._placed(w, p),
                            kind=TASK_OBJECTS.get(widget.module, "disc"))
            return
        if isinstance(event, events.SceneEvent):
            self._on_scene(event)
            return
        if isinstance(event, events.JointsEvent):
            self.preview.on_joints(event.names, event.position)
        if isinstance(event, events.CloudEvent) and event.xyz is not None:
            self.cloud = event                   # what footsteps are placed from
        if isinstance(event, events.CountdownEvent) and event.sender == self.name:
            if event.state == "waiting":
                self.preview.countdown_left(event.module, event.remaining)
            else:
                self.preview.countdown_over(event.module)
                self._hide_ghost()               # sent or cancelled: the preview is over
        module = getattr(event, "module", None)
        # Which widgets show an event, and with which method: the module's own, then the rest.
        method = ROUTES.get(type(event))
        if method is None:
            return
        sinks = list(self.module_widgets.get(module, [])) if module else []
        if isinstance(event, events.LinkEvent):     # every module's widgets show the link
            sinks = [w for widgets in self.module_widgets.values() for w in widgets]
        sinks += [self.status, self.log, self.camera, self.link_widget, self.view3d]
        for sink in sinks:
            if sink is not None and hasattr(sink, method):
                getattr(sink, method)(event)

    def _tick(self) -> None:
        if self.ghost is not None:               # RViz looks the ghost's frames up anew
            self.link.publish_ghost(self.ghost)
        for widgets in self.module_widgets.values():
            for widget in widgets:
                widget.tick()
        for sink in (self.status, self.link_widget, self.camera, self.view3d):
            if sink is not None:
                sink.tick()

    def screenshot(self, path: Path) -> bool:
        """The window as the screen shows it (librviz's GL content included)."""
        from python_qt_binding.QtWidgets import QApplication

        screen = QApplication.primaryScreen()
        geometry = self.frameGeometry()
        image = screen.grabWindow(0, geometry.x(), geometry.y(), geometry.width(),
                                  geometry.height())
        return image.save(str(path))


if __name__ == "__main__":
    sys.exit(main())
