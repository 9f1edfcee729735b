"""Task widgets: a Generic Widget plus one button per pilot command, in the task's order.

Theory of operation
-------------------
A DRC task widget (paper, Figure 14) lays out its module's commands in the
order its state machine meets them (``valvedatasent, reach, approach, grasp,
turn, ungrasp, move_away, home``), each with its number fields beside it
(a pose for ``...datasent``, an angle for ``turn``, a distance for
``go_straight``), and enables only the commands the current state accepts.
One class serves every task module: the buttons come from the module's
:class:`~pilot.catalogue.Catalogue`, only the fields' starting values differ
(:data:`STARTING_VALUES`).  Dangerous commands are :class:`TimedButton` s.

A ``...datasent`` pose can be typed, or dragged: the 3-D view's interactive
marker for the module calls :meth:`TaskWidget.set_pose` (position and roll,
pitch, yaw in the pelvis frame) and the fields follow it.

The drive widget (:class:`DriveWidget`, Figure 14) adds a steering slider: the
pilot sets the angle the wheel should be at, and ``steer`` sends the
``turn_left``/``turn_right`` that takes it there from the angle the robot
measures (the module's status), shown beside it; the throttle is
``accelerate``'s SECONDS and AMOUNT fields.
"""

from __future__ import annotations

import logging
import math
from typing import Dict, List, Optional, Sequence

from python_qt_binding.QtCore import Qt
from python_qt_binding.QtWidgets import (QGridLayout, QHBoxLayout, QLabel, QPushButton, QSlider,
                                         QWidget)

from pilot.catalogue import Catalogue
from pilot.link import StatusEvent
from pilot.widgets.generic import (FIELDS_PER_LINE, GenericWidget, WheelOnlyWhenChosen,
                                   number_field)
from pilot.widgets.timed_button import TimedButton
from walkman.gym.lifecycle import State, lifecycle_of_status
from walkman.model.mjcf import PILOT_POSES

log = logging.getLogger("pilot.tasks")


def _pose(text: str) -> List[float]:
    return [float(v) for v in text.split()[1:]]


#: Where each field starts: the pilots' estimate of each part of the scene (the marker's
#: starting pose), and the usual angles and distances where the module has none (its own
#: defaults fill the others: :attr:`pilot.catalogue.CommandSpec.defaults`).
STARTING_VALUES: Dict[str, Dict[str, List[float]]] = {
    "drc_valve": {"valvedatasent": _pose(PILOT_POSES["valve"])},
    "drc_door": {"doordatasent": _pose(PILOT_POSES["door"])},
    "drc_drive": {"steeringwheeldatasent": _pose(PILOT_POSES["car"])},
    "drc_plug": {"plugdatasent": _pose(PILOT_POSES["plug"])},
    "drc_wall": {"walldatasent": _pose(PILOT_POSES["wall"])},
    "walking": {"go_straight": [0.5], "turn": [0.3], "step_side": [0.1],
                "step_up": [0.05, 0.33], "step_down": [0.05, 0.33]},
    "gaze_control": {"look_at": [1.0, 0.2, 0.1], "set_time": [1.5]},
}
#: Modules that have a task widget; the others get the Generic Widget alone.
TASK_MODULES = tuple(STARTING_VALUES)


def pose_command(name: str) -> bool:
    return name.endswith("datasent")


class TaskWidget(GenericWidget):
    #: commands whose numbers the widget gathers itself (no fields of their own)
    gathered: frozenset = frozenset()

    def __init__(self, catalogue: Catalogue, sender, advanced=lambda: False,
                 parent: Optional[QWidget] = None) -> None:
        self.buttons: Dict[str, QPushButton] = {}
        self.fields: Dict[str, list] = {}
        super().__init__(catalogue, sender, advanced, parent)
        self.setObjectName(f"task_{catalogue.module}")
        panel = QWidget()
        grid = QGridLayout(panel)
        grid.setContentsMargins(0, 0, 0, 0)
        starting = STARTING_VALUES.get(self.module, {})
        row = 0
        for name, spec in catalogue.commands.items():
            button = TimedButton(name) if spec.dangerous else QPushButton(name)
            button.setObjectName(f"do_{name}")
            if spec.dangerous:
                button.fire.connect(lambda n=name: self.do(n))
                self.timed[name] = button
            else:
                button.clicked.connect(lambda _=False, n=name: self.do(n))
            grid.addWidget(button, row, 0)
            values = starting.get(name) or list(spec.defaults)
            fields = []
            labels = [] if name in self.gathered else \
                spec.fields[:len(values)] if spec.fewest == 0 else spec.fields
            for column, label in enumerate(labels):
                field = number_field()
                field.setObjectName(f"{name}_{label}")
                field.setToolTip(f"{label} ({spec.usage})")
                if column < len(values):
                    field.setValue(values[column])
                caption = QLabel(label.lower())
                # A pose's six numbers in two lines of three: in one line they ran past
                # the right edge of a 1600-pixel screen, behind a scroll bar.
                line, place = divmod(column, FIELDS_PER_LINE)
                grid.addWidget(caption, row + line, 1 + 2 * place)
                grid.addWidget(field, row + line, 2 + 2 * place)
                fields.append(field)
            self.fields[name] = fields
            self.buttons[name] = button
            row += max(1, -(-len(fields) // FIELDS_PER_LINE))
        self.task_area.addWidget(panel)
        # Each command has its row here, with the scene's values: the generic row would show
        # the same command again, all zeros, and either could be sent.
        self.command_entry.setVisible(False)
        self.refresh()

    def do(self, name: str) -> bool:
        return self.send(name, self.numbers(name))

    def numbers(self, name: str) -> List[float]:
        """What ``name`` is sent with: its fields' values."""
        return [f.value() for f in self.fields.get(name, [])]

    def set_pose(self, pose: Sequence[float]) -> None:
        """The marker moved: the pose command's first fields follow (x y z roll pitch yaw)."""
        for name, fields in self.fields.items():
            if pose_command(name):
                for field, value in zip(fields, pose):
                    field.setValue(float(value))

    def pose(self) -> Optional[List[float]]:
        for name, fields in self.fields.items():
            if pose_command(name):
                return [f.value() for f in fields[:6]]
        return None

    def refresh_commands(self, state: Optional[str]) -> None:
        running = state is not None and lifecycle_of_status(state) == State.RUNNING
        legal = set(self.catalogue.legal(state)) if running else set()
        for name, button in getattr(self, "buttons", {}).items():
            waiting = isinstance(button, TimedButton) and button.waiting
            button.setEnabled(self.advanced() or name in legal or waiting)


class SteeringSlider(WheelOnlyWhenChosen, QSlider):
    """The wheel angle the pilot wants, in degrees (the wheel only when chosen)."""


class DriveWidget(TaskWidget):
    """drc_drive's widget with a steering slider and the wheel's measured angle."""

    #: Degrees the slider spans either way (the module turns at most 3.2 rad at a time).
    RANGE_DEG = 180

    def __init__(self, catalogue: Catalogue, sender, advanced=lambda: False,
                 parent: Optional[QWidget] = None) -> None:
        self.measured: Optional[float] = None     # rad, from the last status
        super().__init__(catalogue, sender, advanced, parent)
        row = QWidget()
        line = QHBoxLayout(row)
        line.setContentsMargins(0, 0, 0, 0)
        self.slider = SteeringSlider(Qt.Horizontal)
        self.slider.setObjectName("steering")
        self.slider.setRange(-self.RANGE_DEG, self.RANGE_DEG)
        self.slider.setTickInterval(45)
        self.slider.setTickPosition(QSlider.TicksBelow)
        self.wanted_label = QLabel()
        self.measured_label = QLabel("measured: --")
        self.steer_button = QPushButton("steer")
        self.steer_button.setObjectName("steer")
        self.steer_button.clicked.connect(self.steer)
        self.slider.valueChanged.connect(lambda _: self._show_wanted())
        line.addWidget(QLabel("steering"))
        line.addWidget(self.slider, 1)
        line.addWidget(self.wanted_label)
        line.addWidget(self.measured_label)
        line.addWidget(self.steer_button)
        self.task_area.addWidget(row)
        self._show_wanted()
        self.refresh()

    def wanted(self) -> float:
        """The wheel angle the slider asks, rad (left positive, as the module's)."""
        return math.radians(self.slider.value())

    def _show_wanted(self) -> None:
        self.wanted_label.setText(f"{self.slider.value():+d}\u00b0")

    def on_status(self, event: StatusEvent) -> None:
        if len(event.values) >= 5:
            self.measured = event.values[4]
            self.measured_label.setText(f"measured: {math.degrees(self.measured):+.0f}\u00b0")
        super().on_status(event)

    def steer(self) -> bool:
        """Turn the wheel from where the robot measures it to where the slider says."""
        if self.measured is None:
            self.show_problem("the wheel's angle is not known yet (steeringwheeldatasent first)")
            return False
        change = self.wanted() - self.measured
        if abs(change) < 0.01:
            self.show_problem("the wheel is already there")
            return False
        if abs(change) > 3.2:
            self.show_problem(f"{math.degrees(abs(change)):.0f}\u00b0 is more than one turn "
                              f"of the hand (at most 183\u00b0): steer in two steps")
            return False
        return self.send("turn_left" if change > 0 else "turn_right", [abs(change)])

    def refresh_commands(self, state: Optional[str]) -> None:
        super().refresh_commands(state)
        if hasattr(self, "steer_button"):
            turns = self.buttons.get("turn_left")
            self.steer_button.setEnabled(turns is not None and turns.isEnabled())


class WalkingWidget(TaskWidget):
    """walking's widget: footsteps the pilots place in the shared 3-D scene.

    "add footstep" puts one more footstep in the scene (the first 0.15 m ahead of the left
    sole, each next one on the other side, a stride ahead of that foot's last), every
    pilot sees it and may drag it; ``footsteps`` sends them all in order as sole poses in
    the pelvis frame -- the walking module refuses, before a foot lifts, any it cannot make.
    """

    gathered = frozenset({"footsteps"})
    #: m: the first footstep ahead of the sole, and a foot's stride from its last footstep
    FIRST_AHEAD, STRIDE = 0.15, 0.30

    def __init__(self, catalogue: Catalogue, sender, advanced=lambda: False,
                 parent: Optional[QWidget] = None) -> None:
        self.footsteps: Dict[str, List[float]] = {}    # name -> x y z roll pitch yaw (pelvis)
        super().__init__(catalogue, sender, advanced, parent)
        row = QWidget()
        line = QHBoxLayout(row)
        line.setContentsMargins(0, 0, 0, 0)
        self.add_button = QPushButton("add footstep")
        self.add_button.setObjectName("add_footstep")
        self.add_button.setToolTip("one more footstep in the 3-D view, for every pilot: drag "
                                   "it where the foot should go, then send footsteps")
        self.add_button.clicked.connect(self.add_footstep)
        self.clear_button = QPushButton("clear footsteps")
        self.clear_button.setObjectName("clear_footsteps")
        self.clear_button.clicked.connect(self.clear_footsteps)
        self.footsteps_label = QLabel()
        self.footsteps_label.setObjectName("footsteps_placed")
        line.addWidget(self.add_button)
        line.addWidget(self.clear_button)
        line.addWidget(self.footsteps_label, 1)
        self.task_area.addWidget(row)
        camera = QWidget()
        line = QHBoxLayout(camera)
        line.setContentsMargins(0, 0, 0, 0)
        self.camera_button = QPushButton("footsteps from the camera")
        self.camera_button.setObjectName("footsteps_from_camera")
        self.camera_button.setToolTip(
            "place footsteps on the ground the head camera sees, this far ahead, to where the "
            "feet next stand together (an edge, or there): look, then send footsteps; at an "
            "edge, again (pitch the head down first: the ground under the toes must be seen)")
        self.camera_button.clicked.connect(self.footsteps_from_camera)
        self.camera_distance = number_field()
        self.camera_distance.setObjectName("camera_distance")
        self.camera_distance.setRange(0.1, 5.0)
        self.camera_distance.setValue(1.0)
        self.camera_distance.setSuffix(" m")
        line.addWidget(self.camera_button)
        line.addWidget(self.camera_distance)
        line.addStretch(1)
        self.task_area.addWidget(camera)
        self._show_count()
        self.refresh()

    def ordered(self) -> List[str]:
        """The footsteps' names in the order the feet take them (``footstep_N`` by N)."""
        return sorted(self.footsteps, key=footstep_number)

    def numbers(self, name: str) -> List[float]:
        if name != "footsteps":
            return super().numbers(name)
        # X Y Z ROLL PITCH YAW of each sole, in the order the feet take them
        return [v for step in self.ordered() for v in self.footsteps[step][:6]]

    def do(self, name: str) -> bool:
        if name == "footsteps" and not self.footsteps:
            self.show_problem("no footsteps placed: add footstep, drag each where the foot "
                              "goes in the 3-D view, then send footsteps")
            return False
        return super().do(name)

    def next_footstep(self) -> Optional[List[float]]:
        """Where the next footstep goes, or None while the feet's posture is unknown."""
        names = self.ordered()
        from walkman.modules.walking import sole_ahead   # pinocchio: not at the PI's start

        # at the height and pitch of what it comes from: the pilot drags it onto what is there
        if len(names) >= 2:               # a stride ahead of this foot's last footstep
            return list(sole_ahead(self.footsteps[names[-2]], self.STRIDE))
        soles = self.sender_.soles()
        if soles is None:
            return None
        if not names:                     # the left foot first, a bit ahead of its sole
            return list(sole_ahead(soles["left"], self.FIRST_AHEAD))
        return list(sole_ahead(soles["right"], self.STRIDE))   # then the right, a stride on

    def add_footstep(self) -> None:
        """(A Qt slot: PyQt5 aborts the PI on an exception here -- none gets out.)"""
        try:
            self._add_footstep()
        except Exception as exc:  # noqa: BLE001
            log.exception("pilot: adding a footstep failed")
            self.show_problem(f"no footstep added: {exc}")

    def _add_footstep(self) -> None:
        pose = self.next_footstep()
        if pose is None:
            self.show_problem("the feet's posture is not known yet (no joint state from the "
                              "robot): a footstep is placed from where they are")
            return
        number = 1 + max((footstep_number(name) for name in self.footsteps), default=0)
        name = f"footstep_{number}"
        self.footstep_moved(name, pose)
        problem = self.sender_.place(name, "footstep", pose)
        if problem:
            self.show_problem(problem)

    def footsteps_from_camera(self) -> None:
        """The footsteps of the leg ahead, placed from the camera's cloud in the shared
        scene (where every pilot sees, and may drag, them), the ones placed before cleared.
        (A Qt slot: nothing gets out.)"""
        try:
            from walkman.control.ground_ahead import first_leg

            steps, problem = self.sender_.footsteps_from_camera(self.camera_distance.value())
            if problem:
                self.show_problem(problem)
                return
            leg = first_leg(steps)
            spec = self.catalogue.commands.get("footsteps")
            most = spec.most // 6 if spec is not None and spec.most else len(leg)
            if len(leg) > most:      # what one command carries: the rest after a look again
                self.show_problem(f"{len(leg)} footsteps to the next edge or the goal: the "
                                  f"first {most} placed (one command's), place again there")
                leg = leg[:most]
            self.clear_footsteps()
            for number, pose in enumerate(leg, 1):
                name = f"footstep_{number}"
                self.footstep_moved(name, pose)
                problem = self.sender_.place(name, "footstep", pose)
                if problem:
                    self.show_problem(problem)
        except Exception as exc:  # noqa: BLE001
            log.exception("pilot: footsteps from the camera failed")
            self.show_problem(f"no footsteps from the camera: {exc}")

    def clear_footsteps(self) -> None:
        """(A Qt slot: nothing gets out.)"""
        try:
            for name in self.ordered():
                pose = self.footsteps.pop(name)
                problem = self.sender_.place(name, "footstep", pose, removed=True)
                if problem:
                    self.show_problem(problem)
        except Exception as exc:  # noqa: BLE001
            log.exception("pilot: clearing the footsteps failed")
            self.show_problem(f"footsteps not all cleared: {exc}")
        self._show_count()

    def footstep_moved(self, name: str, pose: Optional[Sequence[float]]) -> None:
        """A footstep placed, dragged (here or by another pilot), or removed (None)."""
        if pose is None:
            self.footsteps.pop(name, None)
        else:
            self.footsteps[name] = [float(v) for v in pose[:6]]
        self._show_count()

    def _show_count(self) -> None:
        count = len(self.footsteps)
        self.footsteps_label.setText(f"{count} footstep{'s' if count != 1 else ''} placed")


def footstep_number(name: str) -> int:
    """N of ``footstep_N`` (0 for another name: first)."""
    tail = name.rsplit("_", 1)[-1]
    return int(tail) if tail.isdigit() else 0


#: Task widgets with more than the buttons: the others are :class:`TaskWidget` s.
SPECIAL_TASK_WIDGETS = {"drc_drive": DriveWidget, "walking": WalkingWidget}


def task_widget_class(module: str) -> type:
    return SPECIAL_TASK_WIDGETS.get(module, TaskWidget)
