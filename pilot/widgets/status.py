"""The status tab (paper, Figure 15): modules and warnings, temperatures and torques.

Per joint, the latest temperature and torque are bars (red above the warning
level); over time, the hottest joint and the largest torque are lines of the
last :data:`HISTORY_S` seconds.  The module table shows each module's state and
the age of its status, from the same events as the Generic Widgets.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Deque, Dict, Optional, Tuple

import numpy as np
from python_qt_binding.QtCore import QPointF, QRectF
from python_qt_binding.QtGui import QColor, QPainter, QPen
from python_qt_binding.QtWidgets import (QHBoxLayout, QTableWidget, QTableWidgetItem,
                                         QVBoxLayout, QWidget)

from pilot.link import JointsEvent, StatusEvent, TemperaturesEvent

HISTORY_S = 120.0
HOT_C = 70.0        # the temperature module's "hot" level (FACTS: boards shut down at 80)


class JointPlot(QWidget):
    """Bars of the latest value per joint, and the largest value over time."""

    def __init__(self, title: str, unit: str, warn: Optional[float], parent=None) -> None:
        super().__init__(parent)
        self.title, self.unit, self.warn = title, unit, warn
        self.names: Tuple[str, ...] = ()
        self.values = np.zeros(0)
        self.history: Deque[Tuple[float, float]] = deque()
        self.setMinimumSize(360, 200)

    def update_values(self, names, values: np.ndarray) -> None:
        self.names, self.values = tuple(names), np.asarray(values, float)
        now = time.monotonic()
        if self.values.size:
            self.history.append((now, float(np.nanmax(np.abs(self.values)))))
        while self.history and now - self.history[0][0] > HISTORY_S:
            self.history.popleft()
        self.update()

    def paintEvent(self, _event) -> None:  # noqa: N802 -- Qt's name
        painter = QPainter(self)
        painter.fillRect(self.rect(), QColor("#20242c"))
        painter.setPen(QColor("#e0e0e0"))
        w, h = self.width(), self.height()
        peak = float(np.nanmax(np.abs(self.values))) if self.values.size else 0.0
        painter.drawText(6, 14, f"{self.title}  (max {peak:.1f} {self.unit})")
        if not self.values.size:
            painter.drawText(6, 34, "no data yet")
            return
        top = max(peak, self.warn or 0.0, 1e-6) * 1.1
        bars_h = h * 0.55
        width = (w - 12) / len(self.values)
        for i, value in enumerate(np.abs(self.values)):
            bar = 0.0 if not np.isfinite(value) else value / top * (bars_h - 24)
            hot = self.warn is not None and value >= self.warn
            painter.fillRect(QRectF(6 + i * width, bars_h - bar, max(1.0, width - 1), bar),
                             QColor("#d03030" if hot else "#40a0e0"))
        painter.setPen(QPen(QColor("#f0c040"), 1.5))
        if len(self.history) > 1:
            t0 = self.history[-1][0] - HISTORY_S
            points = [QPointF(6 + (t - t0) / HISTORY_S * (w - 12),
                              h - 6 - v / top * (h - bars_h - 16)) for t, v in self.history]
            for a, b in zip(points, points[1:]):
                painter.drawLine(a, b)
        painter.setPen(QColor("#a0a0a0"))
        painter.drawText(6, int(bars_h + 12), f"largest over the last {HISTORY_S:.0f} s")


class StatusTab(QWidget):
    def __init__(self, modules, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("status")
        layout = QVBoxLayout(self)
        self.table = QTableWidget(len(modules), 3)
        self.table.setHorizontalHeaderLabels(["module", "state", "heard"])
        self.rows: Dict[str, int] = {}
        self.heard: Dict[str, float] = {}
        for row, module in enumerate(modules):
            self.rows[module] = row
            self.table.setItem(row, 0, QTableWidgetItem(module))
            self.table.setItem(row, 1, QTableWidgetItem("not running"))
            self.table.setItem(row, 2, QTableWidgetItem("never"))
        layout.addWidget(self.table)
        plots = QHBoxLayout()
        self.temperatures = JointPlot("temperatures", "\u00b0C", HOT_C)
        self.torques = JointPlot("torques", "N\u00b7m", None)
        plots.addWidget(self.temperatures)
        plots.addWidget(self.torques)
        layout.addLayout(plots)

    def on_status(self, event: StatusEvent) -> None:
        row = self.rows.get(event.module)
        if row is not None:
            self.table.item(row, 1).setText(event.state)
            self.heard[event.module] = time.monotonic() - max(0.0, time.time() - event.stamp)

    def on_joints(self, event: JointsEvent) -> None:
        self.torques.update_values(event.names, event.effort)

    def on_temperatures(self, event: TemperaturesEvent) -> None:
        self.temperatures.update_values(event.names, event.celsius)

    def tick(self) -> None:
        now = time.monotonic()
        for module, row in self.rows.items():
            heard = self.heard.get(module)
            self.table.item(row, 2).setText("never" if heard is None else f"{now - heard:.1f} s ago")


