"""The paper's QtTimedButton: a dangerous command counts down before it leaves.

The countdown itself runs in the pilot gateway (:mod:`rosnodes.timed`), so
every pilot sees the same one and a PI that crashes mid-countdown cannot leave
a command half-sent; the button shows the gateway's ``/M/countdown`` and a
second click while it waits cancels (the gateway receives the same command
again).  Between the click and the gateway's first word the button says so.
"""

from __future__ import annotations

from python_qt_binding.QtCore import Signal
from python_qt_binding.QtWidgets import QPushButton


IDLE_STYLE = ("QPushButton { color: #a05000; font-weight: bold; } "
              "QPushButton:disabled { color: #a0a0a0; font-weight: normal; }")


class TimedButton(QPushButton):
    """A button for one dangerous command; ``fire`` is emitted on every click."""

    fire = Signal()

    def __init__(self, label: str, parent=None) -> None:
        super().__init__(label, parent)
        self.label = label
        self.waiting = False
        self.setToolTip("dangerous: counts down 3 s before it is sent; click again to cancel")
        self.setStyleSheet(IDLE_STYLE)
        self.clicked.connect(self._clicked)

    def _clicked(self) -> None:
        if not self.waiting:
            self.setText(f"{self.label} (starting...)")
        self.fire.emit()

    def show_countdown(self, remaining: float, state: str) -> None:
        """The gateway's word on this command: waiting, sent or cancelled."""
        self.waiting = state == "waiting"
        if self.waiting:
            self.setText(f"{self.label}  {remaining:.1f} s - click to cancel")
            self.setStyleSheet("QPushButton { color: white; background: #c03030; "
                               "font-weight: bold; }")
        else:
            self.setText(self.label if state == "sent" else f"{self.label} (cancelled)")
            self.setStyleSheet(IDLE_STYLE)
