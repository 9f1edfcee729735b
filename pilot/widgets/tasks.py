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


def _pose(text: str) -> List[float]:
    return [float(v) for v in text.split()[1:]]


#: Where each field starts: the pilots' estimate of each part of the scene (the marker's
#: starting pose), and the usual angles and distances.
STARTING_VALUES: Dict[str, Dict[str, List[float]]] = {
    "drc_valve": {"valvedatasent": _pose(PILOT_POSES["valve"]), "turn": [math.pi / 2]},
    "drc_door": {"doordatasent": _pose(PILOT_POSES["door"]), "turn": [0.6], "open": [0.5]},
    "drc_drive": {"steeringwheeldatasent": _pose(PILOT_POSES["car"]), "turn_left": [0.3],
                  "turn_right": [0.3], "accelerate": [1.0, 1.0]},
    "drc_plug": {"plugdatasent": _pose(PILOT_POSES["plug"])},
    "drc_wall": {"walldatasent": _pose(PILOT_POSES["wall"])},
    "walking": {"go_straight": [0.5], "turn": [0.3], "step_side": [0.1]},
    "gaze_control": {"look_at": [1.0, 0.2, 0.1], "set_time": [1.5]},
}
#: Modules that have a task widget; the others get the Generic Widget alone.
TASK_MODULES = tuple(STARTING_VALUES)


def pose_command(name: str) -> bool:
    return name.endswith("datasent")


class TaskWidget(GenericWidget):
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
            values = starting.get(name, [])
            fields = []
            for column, label in enumerate(spec.fields[:len(values)] if spec.fewest == 0
                                           else spec.fields):
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
        self.refresh()

    def do(self, name: str) -> bool:
        return self.send(name, [f.value() for f in self.fields.get(name, [])])

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


#: Task widgets with more than the buttons: the others are :class:`TaskWidget` s.
SPECIAL_TASK_WIDGETS = {"drc_drive": DriveWidget}


def task_widget_class(module: str) -> type:
    return SPECIAL_TASK_WIDGETS.get(module, TaskWidget)
