"""The Generic Widget (paper, Figure 13): the graphical face of one GYM module.

Theory of operation
-------------------
Every module widget inherits it: a LED and the decoded status with its age
(green running, grey when the status is stale, red "not running" when the
module never spoke or went silent), the lifecycle buttons of Figure 8 -- each
enabled only when the module's lifecycle allows it -- the module's warnings in
red with their history, and a command entry built from the module's
:class:`~pilot.catalogue.Catalogue`: its commands, one number field per
argument, a timed send for dangerous ones.  A refused command (by the module,
its state machine or the gateway) shows the reason in the warnings.

While the link to the robot is down (``/bridge/link``, :mod:`nodekit.link_watch`)
every module's widget says so at once, in blue: "link down for 12 s; module last
heard running" (a status a second old says no more than one of a minute: nothing
crosses), or "module silent since before the cut (last: running)" for one the pilot
had already seen go silent.  It keeps the buttons the last known state allows (what
is sent waits for the link, and expires if it waits past its validity), and goes back
to its usual colours when the link returns.  Only a module silent while the link is
up reads "not running".  Commands held for the link
(``/pilot/command_states``: queued) are listed with a "cancel queued" button; one refused
or expired on the robot is shown among the warnings with why.

"Advanced mode" (the paper's: commands usually hidden are shown and all the
buttons enabled, the pilot knowing the risk) is one switch for the window.
The widget holds no ROS or threads: the window feeds it events and calls
:meth:`tick` twice a second.
"""

from __future__ import annotations

import time
from typing import Callable, Dict, List, Optional

from python_qt_binding.QtCore import Qt
from python_qt_binding.QtWidgets import (QComboBox, QDoubleSpinBox, QGridLayout, QGroupBox,
                                         QHBoxLayout, QLabel, QLineEdit, QListWidget,
                                         QListWidgetItem, QPushButton, QVBoxLayout, QWidget)
from python_qt_binding.QtGui import QColor

from pilot.catalogue import Catalogue, catalogue_of, legal_switches
from pilot.link_cut import age_text
from pilot.link import (CommandStateEvent, CountdownEvent, LinkEvent, StatusEvent,
                        WarningEvent)
from pilot.widgets.timed_button import TimedButton
from walkman.gym.lifecycle import State, lifecycle_of_status

#: Number fields side by side before the next line: three label-and-field pairs fit the
#: task area of the main-pilot layout at 1400 pixels (six ran past the right edge).
FIELDS_PER_LINE = 3
#: A status older than this is grey (the module sends one every 0.5 s; the bridge every T).
STALE_S = 3.0
#: Silent this long (or never heard): "not running".
ABSENT_S = 10.0
#: The colour of "link down": neither the module's health (green, yellow) nor its death (red).
LINK_DOWN_COLOUR = "#2f6fd0"
SWITCH_ORDER = ["start", "pause", "resume", "stop", "quit"]
WARNING_HISTORY = 200


class GenericWidget(QGroupBox):
    def __init__(self, catalogue: Catalogue, sender, advanced: Callable[[], bool] = lambda: False,
                 parent: Optional[QWidget] = None) -> None:
        super().__init__(f"/{catalogue.module}", parent)
        self.setObjectName(f"generic_{catalogue.module}")
        self.catalogue = catalogue
        self.module = catalogue.module
        self.sender_ = sender
        self.advanced = advanced
        self.state: Optional[str] = None        # the module's last status word
        self.heard_at: Optional[float] = None   # monotonic time of the last status
        self.status_stamp = 0.0                 # the gateway's stamp of it (wall clock)
        self.link_down_at: Optional[float] = None   # monotonic time the link went down
        self.silent_before_cut = False   # absent already when the link went down
        self.status_text = ""            # the last status as shown: its word and data
        self.timed: Dict[str, TimedButton] = {}
        outer = QVBoxLayout(self)

        top = QHBoxLayout()
        self.led = QLabel("\u25cf")
        self.led.setObjectName("led")
        self.status_label = QLabel("not running")
        self.status_label.setObjectName("status")
        self.age_label = QLabel("")
        top.addWidget(self.led)
        top.addWidget(self.status_label, 1)
        top.addWidget(self.age_label)
        outer.addLayout(top)

        # Everything a pilot acts with: hidden while the module was never heard (nobody
        # launched it), so a page of modules shows only buttons that can work.
        self.body = QWidget()
        body = QVBoxLayout(self.body)
        body.setContentsMargins(0, 0, 0, 0)
        switches = QHBoxLayout()
        self.switch_buttons: Dict[str, QPushButton] = {}
        for word in SWITCH_ORDER:
            button = QPushButton(word)
            button.setObjectName(f"switch_{word}")
            button.clicked.connect(lambda _=False, w=word: self._switch(w))
            switches.addWidget(button)
            self.switch_buttons[word] = button
        body.addLayout(switches)

        self.task_area = QVBoxLayout()     # task widgets put their panel here
        body.addLayout(self.task_area)

        #: The generic row: pick any command, type its numbers (a task widget, which has a
        #: row of its own for each command, hides it: one command, one set of fields).
        self.command_entry = self._command_entry()
        body.addWidget(self.command_entry)
        held = QHBoxLayout()
        self.queued_label = QLabel("")
        self.queued_label.setObjectName("queued")
        self.queued_label.setWordWrap(True)
        self.queued_label.setStyleSheet(f"color: {LINK_DOWN_COLOUR};")
        self.cancel_button = QPushButton("cancel queued")
        self.cancel_button.setObjectName("cancel_queued")
        self.cancel_button.setToolTip("take back every command still waiting for the link "
                                      "(one already on its way to the robot cannot be)")
        self.cancel_button.clicked.connect(self._cancel_queued)
        held.addWidget(self.queued_label, 1)
        held.addWidget(self.cancel_button)
        body.addLayout(held)
        self.queued: Dict[int, str] = {}       # seq -> text: commands waiting for the link
        self.warnings = QListWidget()
        self.warnings.setObjectName("warnings")
        self.warnings.setMaximumHeight(90)
        self.warnings.setWordWrap(True)     # a warning reads whole, not cut at the edge
        body.addWidget(self.warnings)
        outer.addWidget(self.body)
        self.refresh()

    # -- the command entry ----------------------------------------------------------------

    def _command_entry(self) -> QWidget:
        box = QWidget()
        grid = QGridLayout(box)
        grid.setContentsMargins(0, 0, 0, 0)
        self.command_box = ChoiceBox()
        self.command_box.setObjectName("command")
        self.command_box.addItems(list(self.catalogue.commands))
        self.free_text = QLineEdit()
        self.free_text.setPlaceholderText("command and numbers, e.g. look_at 1.0 0.4 0.1")
        self.free_text.setVisible(not self.catalogue.commands)
        self.command_box.setVisible(bool(self.catalogue.commands))
        self.fields_row = QGridLayout()
        self.number_fields: List[QDoubleSpinBox] = []
        self.send_button = QPushButton("send")
        self.send_button.setObjectName("send")
        self.send_button.clicked.connect(self._send_entry)
        grid.addWidget(QLabel("command"), 0, 0)
        grid.addWidget(self.command_box, 0, 1)
        grid.addWidget(self.free_text, 0, 1)
        grid.addLayout(self.fields_row, 1, 0, 1, 3)
        grid.addWidget(self.send_button, 0, 2)
        self.command_box.currentTextChanged.connect(self._command_chosen)
        self._command_chosen(self.command_box.currentText())
        return box

    def _command_chosen(self, name: str) -> None:
        while self.fields_row.count():
            item = self.fields_row.takeAt(0)
            if item.widget() is not None:
                item.widget().deleteLater()
        self.number_fields = []
        spec = self.catalogue.commands.get(name)
        if spec is None:
            return
        for index, label in enumerate(spec.fields):
            line, place = divmod(index, FIELDS_PER_LINE)
            self.fields_row.addWidget(QLabel(label), line, 2 * place)
            field = number_field()
            field.setObjectName(f"arg_{label}")
            self.fields_row.addWidget(field, line, 2 * place + 1)
            self.number_fields.append(field)
        self.send_button.setText("send (3 s, click again to cancel)" if spec.dangerous
                                 else "send")

    def _send_entry(self) -> None:
        if not self.catalogue.commands:
            words = self.free_text.text().split()
            if not words:
                return
            try:
                numbers = [float(w) for w in words[1:]]
            except ValueError:
                self.show_problem(f"'{' '.join(words[1:])}' are not all numbers")
                return
            self.send(words[0], numbers)
            return
        name = self.command_box.currentText()
        self.send(name, [f.value() for f in self.number_fields])

    # -- sending --------------------------------------------------------------------------

    def send(self, name: str, numbers: List[float]) -> bool:
        """Send a command after the checks the catalogue allows; a refusal is shown."""
        spec = self.catalogue.commands.get(name)
        if spec is not None:
            problem = spec.check(numbers)
            if problem is None and not self.advanced() and self.catalogue.table is not None \
                    and name not in self.catalogue.legal(self.state or ""):
                problem = (f"{name} is not accepted in state {self.state or 'unknown'} "
                           f"(now: {', '.join(self.catalogue.legal(self.state or '')) or 'none'})")
            if problem is not None:
                self.show_problem(problem)
                return False
        problem = self.sender_.command(self.module, name, numbers,
                                       dangerous=bool(spec and spec.dangerous))
        if problem:
            self.show_problem(problem)
            return False
        return True

    def _switch(self, word: str) -> None:
        problem = self.sender_.switch(self.module, word)
        if problem:
            self.show_problem(problem)

    # -- events ---------------------------------------------------------------------------

    def on_status(self, event: StatusEvent) -> None:
        self.state = event.state
        self.heard_at = time.monotonic() - max(0.0, time.time() - event.stamp)
        self.status_stamp = event.stamp
        self.status_text = status_text(event, self.catalogue)
        self.refresh()

    def on_warning(self, event: WarningEvent) -> None:
        stamp = time.strftime("%H:%M:%S", time.localtime(event.stamp))
        item = QListWidgetItem(f"{stamp}  {event.text}")
        item.setForeground(QColor("#d00000"))
        self.warnings.insertItem(0, item)
        while self.warnings.count() > WARNING_HISTORY:
            self.warnings.takeItem(self.warnings.count() - 1)

    def on_countdown(self, event: CountdownEvent) -> None:
        words = event.command.replace("(", " ").replace(")", " ").split()  # "(turn 1.5)"
        name = words[0] if words else ""
        button = self.timed.get(name)
        if button is not None:
            button.show_countdown(event.remaining, event.state)
        spec = self.catalogue.commands.get(name)
        if spec is not None and self.command_box.currentText() == name:
            self.send_button.setText(
                f"{name}: {event.remaining:.1f} s - click to cancel" if event.state == "waiting"
                else "send (3 s, click again to cancel)")
        self.refresh()            # a waiting timed button stays clickable (to cancel)

    def on_command_state(self, event: CommandStateEvent) -> None:
        if event.module != self.module:
            return
        if event.state == "queued":
            self.queued[event.seq] = event.text
        else:
            self.queued.pop(event.seq, None)
        if event.state in ("refused", "expired", "interrupted"):
            self.on_warning(WarningEvent(self.module, f"`{event.text}` {event.state}: "
                                                     f"{event.reason}", event.stamp))
        self.refresh()

    def _cancel_queued(self) -> None:
        problem = self.sender_.cancel(self.module, 0)
        if problem:
            self.show_problem(problem)

    def on_link(self, event: LinkEvent) -> None:
        if event.state == "down":
            self.link_down_at = time.monotonic() - event.since
            self.silent_before_cut = self.heard_at is None or \
                self.link_down_at - self.heard_at > ABSENT_S
        else:
            if self.link_down_at is not None and self.heard_at is not None \
                    and not self.silent_before_cut:
                # Silence while the link was down says nothing about the module: its age
                # counts again from the link's return (a status follows within a period).
                self.heard_at = max(self.heard_at, time.monotonic() - STALE_S)
            self.link_down_at = None
            self.silent_before_cut = False
        self.refresh()

    def show_problem(self, text: str) -> None:
        self.on_warning(WarningEvent(self.module, f"not sent: {text}", time.time()))

    # -- appearance ------------------------------------------------------------------------

    @property
    def age(self) -> Optional[float]:
        return None if self.heard_at is None else time.monotonic() - self.heard_at

    @property
    def presence(self) -> str:
        """running, stale, absent, or link_down (whatever the module last said: nothing
        it says now can cross)."""
        age = self.age
        if self.link_down_at is not None:
            return "link_down"
        if age is None or age > ABSENT_S:
            return "absent"
        return "stale" if age > STALE_S else "running"

    def tick(self) -> None:
        self.refresh()

    def refresh(self) -> None:
        presence = self.presence
        age = self.age
        running = presence != "absent" and self.state is not None and \
            lifecycle_of_status(self.state) == State.RUNNING
        colour = {"running": "#10a010" if running else "#d0a000", "stale": "#909090",
                  "absent": "#d00000", "link_down": LINK_DOWN_COLOUR}[presence]
        self.led.setStyleSheet(f"color: {colour}; font-size: 18px;")
        self.status_label.setStyleSheet(
            f"color: {LINK_DOWN_COLOUR}; font-weight: bold;" if presence == "link_down" else
            "color: #909090;" if presence != "running" else "")
        if presence == "link_down":
            down = time.monotonic() - self.link_down_at
            last = "never heard" if self.state is None else \
                f"silent since before the cut (last: {self.state})" if self.silent_before_cut \
                else f"last heard {self.state}"
            self.status_label.setText(f"link down for {age_text(down)}; module {last}")
        elif presence == "absent":
            self.status_label.setText(
                f"not launched on the robot (walkman-module {self.module} starts it)"
                if self.state is None else f"not running (last: {self.state})")
        else:      # the status itself (again, once the link is back: not "link down")
            self.status_label.setText(self.status_text)
        self.age_label.setText("" if age is None else f"{age:.1f} s ago")
        waiting = list(self.queued.values())
        self.queued_label.setText("queued for the link: " + ", ".join(f"`{t}`" for t in waiting)
                                  if waiting else "")
        self.cancel_button.setVisible(bool(waiting))
        self.body.setVisible(self.state is not None or self.advanced())
        known = None if presence == "absent" else self.state
        legal = set(legal_switches(known))
        for word, button in self.switch_buttons.items():
            button.setEnabled(self.advanced() or word in legal)
        self.refresh_commands(known)

    def refresh_commands(self, state: Optional[str]) -> None:
        """Task widgets enable their buttons here."""


def status_text(event: StatusEvent, catalogue: Optional[Catalogue] = None) -> str:
    """A status as the pilot reads it: its state, and its numbers named as the module's
    class declares (``tracking  neck yaw 0.36 rad, pitch 0.83 rad``)."""
    catalogue = catalogue or catalogue_of(event.module)
    whole = event.values and len(event.values) == len(event.data.split())
    data = catalogue.describe(event.state, event.values) if whole else event.data
    return event.state + (f"  {data}" if data else "")


class WheelOnlyWhenChosen:
    """A field the mouse wheel changes only once the pilot chose it (clicked or tabbed in):
    mixed into number fields, choice boxes and sliders.

    Qt's spin boxes and combo boxes take the wheel from under the pointer: a pilot
    scrolling a tab changed ``drc_drive``'s roll to -1.35 without seeing it.  Here the
    wheel over a field it does not have focus scrolls the page, as everywhere else.
    """

    #: How a pilot chooses a field; focus given by Qt itself (the first field of a window
    #: that became active) is not a choice.
    CHOSEN_BY = (Qt.MouseFocusReason, Qt.TabFocusReason, Qt.BacktabFocusReason,
                 Qt.ShortcutFocusReason)

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.setFocusPolicy(Qt.StrongFocus)     # the wheel alone never gives focus
        self.chosen = False

    def focusInEvent(self, event) -> None:  # noqa: N802 -- Qt's name
        self.chosen = event.reason() in self.CHOSEN_BY
        super().focusInEvent(event)

    def focusOutEvent(self, event) -> None:  # noqa: N802
        if event.reason() != Qt.PopupFocusReason:   # a combo's own list keeps it chosen
            self.chosen = False
        super().focusOutEvent(event)

    def wheelEvent(self, event) -> None:  # noqa: N802
        if self.chosen and self.hasFocus():
            super().wheelEvent(event)
        else:
            event.ignore()                      # to the scroll area around it


class NumberField(WheelOnlyWhenChosen, QDoubleSpinBox):
    """A command's number."""


class ChoiceBox(WheelOnlyWhenChosen, QComboBox):
    """A choice among commands."""


def number_field() -> QDoubleSpinBox:
    field = NumberField()
    field.setDecimals(3)
    # wide: the module checks its numbers (perception's set_resolution takes up to 1280 px;
    # at +-100 the field cut 640 to 100 without a word)
    field.setRange(-1e5, 1e5)
    field.setSingleStep(0.05)
    field.setAlignment(Qt.AlignRight)
    return field
