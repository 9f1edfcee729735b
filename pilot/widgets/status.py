"""The status tab (paper, Figure 15): modules and their warnings, temperatures and torques,
the battery.

Per joint, the latest temperature and torque are bars (red above the warning
level); over time, the hottest joint and the largest torque are lines of the
last :data:`HISTORY_S` seconds.  The module table shows each module's state and
the age of its status, from the same events as the Generic Widgets.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Deque, Dict, List, Optional, Tuple

import numpy as np
from python_qt_binding.QtCore import QPointF, QRectF, Qt
from python_qt_binding.QtGui import QColor, QFont, QPainter, QPen
from python_qt_binding.QtWidgets import (QHBoxLayout, QHeaderView, QLabel, QLineEdit,
                                         QListWidget, QListWidgetItem, QTableWidget,
                                         QTableWidgetItem, QToolTip, QVBoxLayout, QWidget)

from pilot.link import BatteryEvent, JointsEvent, StatusEvent, TemperaturesEvent, WarningEvent
from pilot.link_cut import LinkCut, age_text
from pilot.widgets.generic import LINK_DOWN_COLOUR, ChoiceBox, status_text

HISTORY_S = 120.0
HOT_C = 70.0        # the temperature module's "hot" level (FACTS: boards shut down at 80)


class JointPlot(QWidget):
    """Bars of the latest value per joint, named, on a scale with units; below, the largest
    value over time.  Hovering a bar names its joint and value."""

    AXIS_W = 44          # px left of the bars for the scale
    NAMES_H = 86         # px under the bars for the joint names (turned upright)

    def __init__(self, title: str, unit: str, warn: Optional[float], parent=None) -> None:
        super().__init__(parent)
        self.title, self.unit, self.warn = title, unit, warn
        self.names: Tuple[str, ...] = ()
        self.values = np.zeros(0)
        self.history: Deque[Tuple[float, float]] = deque()
        self.setMinimumSize(360, 350)
        self.setMouseTracking(True)

    def update_values(self, names, values: np.ndarray) -> None:
        self.names, self.values = tuple(names), np.asarray(values, float)
        now = time.monotonic()
        if self.values.size:
            self.history.append((now, float(np.nanmax(np.abs(self.values)))))
        while self.history and now - self.history[0][0] > HISTORY_S:
            self.history.popleft()
        self.update()

    # -- geometry, shared by painting and hovering ---------------------------------------

    def _bar_width(self) -> float:
        return (self.width() - self.AXIS_W - 6) / max(1, len(self.values))

    def _bars_bottom(self) -> float:
        return self.height() * 0.58

    def joint_at(self, x: float) -> Optional[int]:
        """The index of the bar under ``x``, if any."""
        if not self.values.size or x < self.AXIS_W:
            return None
        index = int((x - self.AXIS_W) // self._bar_width())
        return index if 0 <= index < len(self.values) else None

    def peak(self) -> Tuple[float, str]:
        """The largest magnitude now and whose it is."""
        if not self.values.size or not np.isfinite(self.values).any():
            return 0.0, ""
        index = int(np.nanargmax(np.abs(self.values)))
        name = self.names[index] if index < len(self.names) else f"#{index}"
        return float(abs(self.values[index])), name

    def mouseMoveEvent(self, event) -> None:  # noqa: N802 -- Qt's name
        index = self.joint_at(event.pos().x())
        if index is None:
            QToolTip.hideText()
            return
        name = self.names[index] if index < len(self.names) else f"#{index}"
        QToolTip.showText(event.globalPos(), f"{name}: {self.values[index]:.1f} {self.unit}",
                          self)

    # -- painting ------------------------------------------------------------------------

    def paintEvent(self, _event) -> None:  # noqa: N802 -- Qt's name
        painter = QPainter(self)
        painter.fillRect(self.rect(), QColor("#20242c"))
        painter.setPen(QColor("#e0e0e0"))
        w, h = self.width(), self.height()
        peak, whose = self.peak()
        painter.drawText(6, 14, f"{self.title} ({self.unit})" + (
            f"   max {peak:.1f} {self.unit} at {whose}" if whose else ""))
        if not self.values.size:
            painter.drawText(6, 34, "no data yet")
            return
        top = max(peak, self.warn or 0.0, 1e-6) * 1.1
        left, bottom, ceiling = self.AXIS_W, self._bars_bottom(), 24.0
        scale = (bottom - ceiling) / top
        small = QFont(painter.font())
        small.setPointSizeF(max(6.0, small.pointSizeF() * 0.8))
        painter.setFont(small)
        # The scale: three ticks with their values, and the warning level.
        for fraction in (0.0, 0.5, 1.0):
            value = top / 1.1 * fraction
            y = bottom - value * scale
            painter.setPen(QColor("#505860"))
            painter.drawLine(QPointF(left, y), QPointF(w - 6, y))
            painter.setPen(QColor("#a0a0a0"))
            painter.drawText(QRectF(0, y - 8, left - 4, 16), Qt.AlignRight | Qt.AlignVCenter,
                             f"{value:.0f}")
        if self.warn is not None:
            y = bottom - self.warn * scale
            painter.setPen(QPen(QColor("#d03030"), 1, Qt.DashLine))
            painter.drawLine(QPointF(left, y), QPointF(w - 6, y))
        width = self._bar_width()
        for i, value in enumerate(np.abs(self.values)):
            bar = 0.0 if not np.isfinite(value) else value * scale
            hot = self.warn is not None and value >= self.warn
            painter.fillRect(QRectF(left + i * width, bottom - bar, max(1.0, width - 1), bar),
                             QColor("#d03030" if hot else "#40a0e0"))
        # Each bar's joint, written upward under it.
        painter.setPen(QColor("#c0c0c0"))
        for i, name in enumerate(self.names[:len(self.values)]):
            painter.save()
            painter.translate(left + (i + 0.5) * width + 4, bottom + 3)
            painter.rotate(-90)
            painter.drawText(QRectF(-self.NAMES_H, -8, self.NAMES_H, 12),
                             Qt.AlignRight | Qt.AlignVCenter, name)
            painter.restore()
        # Over time: the largest value of each sample.
        graph_top, graph_bottom = bottom + self.NAMES_H + 18, h - 6.0
        # Its own scale: the largest of the window (a past peak above today's bars).
        ceiling_history = max([v for _, v in self.history] + [top / 1.1, 1e-6])
        painter.setPen(QColor("#a0a0a0"))
        painter.drawText(6, int(graph_top - 4),
                         f"largest over the last {HISTORY_S:.0f} s ({self.unit}, "
                         f"0 to {ceiling_history:.0f})")
        painter.setPen(QPen(QColor("#f0c040"), 1.5))
        if len(self.history) > 1 and graph_bottom > graph_top:
            t0 = self.history[-1][0] - HISTORY_S
            points = [QPointF(left + (t - t0) / HISTORY_S * (w - left - 6),
                              graph_bottom - v / ceiling_history * (graph_bottom - graph_top))
                      for t, v in self.history]
            for a, b in zip(points, points[1:]):
                painter.drawLine(a, b)


def body_layout() -> Tuple[Dict[str, Tuple[float, float]], List[Tuple[str, str]]]:
    """Each joint seen from the front (lateral, up; metres, the pelvis at 0) with the robot
    standing straight, and the bones between joints: what a silhouette is drawn from."""
    from walkman.model.description import walkman

    robot = walkman()
    link_at: Dict[str, Tuple[float, float, float]] = {"pelvis": (0.0, 0.0, 0.0)}
    places: Dict[str, Tuple[float, float]] = {}
    joint_of_link: Dict[str, str] = {}
    bones: List[Tuple[str, str]] = []
    for joint in robot.joints:                   # parents come before their children
        x, y, z = link_at[joint.parent]
        ox, oy, oz = joint.origin
        link_at[joint.child] = (x + ox, y + oy, z + oz)
        places[joint.name] = (y + oy, z + oz)
        if joint.parent in joint_of_link:
            bones.append((joint_of_link[joint.parent], joint.name))
        joint_of_link[joint.child] = joint.name
    return places, bones


def heat_colour(share: float) -> QColor:
    """Blue (cool, small) through green and yellow to red (hot, large)."""
    share = min(max(share, 0.0), 1.0)
    return QColor.fromHsvF((1.0 - share) * 0.66, 0.9, 0.95)


class BodyView(QWidget):
    """Fig. 15 (B): a figure of the robot whose joints are coloured by their value."""

    def __init__(self, title: str, unit: str, parent=None) -> None:
        super().__init__(parent)
        self.title, self.unit = title, unit
        self.places, self.bones = body_layout()
        self.values: Dict[str, float] = {}
        self.setMinimumSize(220, 260)
        self.setMouseTracking(True)

    def update_values(self, names, values) -> None:
        self.values = {name: float(value) for name, value in zip(names, values)
                       if name in self.places and np.isfinite(value)}
        self.update()

    def _points(self) -> Dict[str, QPointF]:
        ys = [p[0] for p in self.places.values()]
        zs = [p[1] for p in self.places.values()]
        span = max(max(ys) - min(ys), max(zs) - min(zs), 1e-6)
        scale = min(self.width() - 20, self.height() - 44) / span
        middle_y, top = (max(ys) + min(ys)) / 2, max(zs)
        return {name: QPointF(self.width() / 2 - (y - middle_y) * scale,   # it faces us
                              28 + (top - z) * scale) for name, (y, z) in self.places.items()}

    def joint_at(self, x: float, y: float) -> Optional[str]:
        """The joint drawn nearest ``(x, y)``, within 10 px."""
        distance, name = min((abs(p.x() - x) + abs(p.y() - y), name)
                             for name, p in self._points().items())
        return name if distance <= 10 else None

    def mouseMoveEvent(self, event) -> None:  # noqa: N802 -- Qt's name
        name = self.joint_at(event.pos().x(), event.pos().y())
        if name is None:
            QToolTip.hideText()
            return
        value = self.values.get(name)
        QToolTip.showText(event.globalPos(), f"{name}: " + (
            "no data" if value is None else f"{value:.1f} {self.unit}"), self)

    def paintEvent(self, _event) -> None:  # noqa: N802 -- Qt's name
        painter = QPainter(self)
        painter.setRenderHint(QPainter.Antialiasing)
        painter.fillRect(self.rect(), QColor("#20242c"))
        magnitudes = [abs(v) for v in self.values.values()]
        low, high = (min(magnitudes), max(magnitudes)) if magnitudes else (0.0, 1.0)
        painter.setPen(QColor("#e0e0e0"))
        painter.drawText(6, 14, f"{self.title}: {low:.0f} (blue) to {high:.0f} (red) {self.unit}"
                         if magnitudes else f"{self.title}: no data yet")
        points = self._points()
        painter.setPen(QPen(QColor("#707880"), 3))
        for a, b in self.bones:
            painter.drawLine(points[a], points[b])
        painter.setPen(Qt.NoPen)
        for name, point in points.items():
            value = self.values.get(name)
            colour = QColor("#505860") if value is None else \
                heat_colour((abs(value) - low) / max(high - low, 1e-6))
            painter.setBrush(colour)
            painter.drawEllipse(point, 5.5, 5.5)


class BatteryGauge(QWidget):
    """Figure 15's horizontal bar: the charge, its voltage and current, coloured by level."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.reading: Optional[BatteryEvent] = None
        self.setMinimumHeight(34)

    def on_battery(self, event: BatteryEvent) -> None:
        self.reading = event
        self.update()

    def colour(self) -> str:
        if self.reading is None:
            return "#606060"
        return "#d03030" if self.reading.percent < 10 else \
            "#e0a020" if self.reading.percent < 20 else "#30a040"

    def text(self) -> str:
        if self.reading is None:
            return "battery: no reading yet"
        r = self.reading
        return f"battery {r.percent:.0f} %   {r.voltage:.1f} V   {r.current:.1f} A"

    def paintEvent(self, _event) -> None:  # noqa: N802 -- Qt's name
        painter = QPainter(self)
        rect = QRectF(self.rect()).adjusted(1, 1, -1, -1)
        painter.fillRect(rect, QColor("#20242c"))
        if self.reading is not None:
            share = min(max(self.reading.percent / 100.0, 0.0), 1.0)
            painter.fillRect(QRectF(rect.x(), rect.y(), rect.width() * share, rect.height()),
                             QColor(self.colour()))
        painter.setPen(QColor("#f0f0f0"))
        painter.drawText(rect, Qt.AlignCenter, self.text())


class WarningsPanel(QWidget):
    """Every module's warnings, newest first, filtered by module and by words (Fig. 15 (A))."""

    ALL = "all modules"
    LIMIT = 500          # the oldest go beyond this many

    def __init__(self, modules, parent=None) -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        filters = QHBoxLayout()
        self.module_filter = ChoiceBox()
        self.module_filter.setObjectName("warning_module")
        self.module_filter.addItems([self.ALL, *modules])
        self.text_filter = QLineEdit()
        self.text_filter.setObjectName("warning_text")
        self.text_filter.setPlaceholderText("only warnings with these words")
        filters.addWidget(QLabel("warnings of"))
        filters.addWidget(self.module_filter)
        filters.addWidget(self.text_filter, 1)
        layout.addLayout(filters)
        self.list = QListWidget()
        self.list.setObjectName("warnings")
        self.list.setMaximumHeight(120)
        layout.addWidget(self.list)
        self.warnings: List[WarningEvent] = []
        self.module_filter.currentTextChanged.connect(lambda _: self.refresh())
        self.text_filter.textChanged.connect(lambda _: self.refresh())

    def on_warning(self, event: WarningEvent) -> None:
        self.warnings.append(event)
        del self.warnings[:-self.LIMIT]
        self.refresh()

    def shown(self) -> List[WarningEvent]:
        module = self.module_filter.currentText()
        words = self.text_filter.text().lower().split()
        return [w for w in reversed(self.warnings)
                if module in (self.ALL, w.module) and all(word in w.text.lower() for word in words)]

    def refresh(self) -> None:
        self.list.clear()
        for event in self.shown():
            stamp = time.strftime("%H:%M:%S", time.localtime(event.stamp))
            item = QListWidgetItem(f"{stamp}  /{event.module}  {event.text}")
            item.setForeground(QColor("#c00000"))
            self.list.addItem(item)


class StatusTab(QWidget):
    def __init__(self, modules, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("status")
        layout = QVBoxLayout(self)
        #: While the link is down: how old the states, charts and battery below are.
        self.cut = LinkCut()
        self.link_banner = QLabel("")
        self.link_banner.setObjectName("status_link")
        self.link_banner.setWordWrap(True)
        self.link_banner.setStyleSheet(f"color: {LINK_DOWN_COLOUR}; font-weight: bold;")
        self.link_banner.setVisible(False)
        layout.addWidget(self.link_banner)
        self.charts_at: Optional[float] = None   # when the newest joints or temperatures came
        self.table = QTableWidget(len(modules), 3)
        self.table.setHorizontalHeaderLabels(["module", "state", "heard"])
        self.rows: Dict[str, int] = {}
        self.heard: Dict[str, float] = {}
        for row, module in enumerate(modules):
            self.rows[module] = row
            self.table.setItem(row, 0, QTableWidgetItem(module))
            self.table.setItem(row, 1, QTableWidgetItem("not running"))
            self.table.setItem(row, 2, QTableWidgetItem("never"))
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeToContents)
        header.setSectionResizeMode(1, QHeaderView.Stretch)   # the state and its numbers
        header.setSectionResizeMode(2, QHeaderView.ResizeToContents)
        self.table.setMaximumHeight(36 + 30 * max(1, len(modules)))
        self.table.setMinimumHeight(min(36 + 30 * max(1, len(modules)), 160))
        layout.addWidget(self.table)
        self.warnings = WarningsPanel(list(modules))
        layout.addWidget(self.warnings)
        plots = QHBoxLayout()
        self.temperatures = JointPlot("temperatures", "\u00b0C", HOT_C)
        self.torques = JointPlot("torques", "N\u00b7m", None)
        plots.addWidget(self.temperatures)
        plots.addWidget(self.torques)
        layout.addLayout(plots)
        bodies = QHBoxLayout()
        self.temperature_body = BodyView("temperatures", "\u00b0C")
        self.torque_body = BodyView("torques", "N\u00b7m")
        bodies.addWidget(self.temperature_body)
        bodies.addWidget(self.torque_body)
        layout.addLayout(bodies)
        self.battery = BatteryGauge()
        layout.addWidget(self.battery)

    def on_status(self, event: StatusEvent) -> None:
        row = self.rows.get(event.module)
        if row is not None:
            self.table.item(row, 1).setText(status_text(event))
            self.heard[event.module] = time.monotonic() - max(0.0, time.time() - event.stamp)

    def on_link(self, event) -> None:
        self.cut.on_link(event)
        self.tick()

    def on_joints(self, event: JointsEvent) -> None:
        self.charts_at = self.cut.clock()
        self.torques.update_values(event.names, event.effort)
        self.torque_body.update_values(event.names, event.effort)

    def on_battery(self, event: BatteryEvent) -> None:
        self.battery.on_battery(event)

    def on_warning(self, event: WarningEvent) -> None:
        self.warnings.on_warning(event)

    def on_temperatures(self, event: TemperaturesEvent) -> None:
        self.charts_at = self.cut.clock()
        self.temperatures.update_values(event.names, event.celsius)
        self.temperature_body.update_values(event.names, event.celsius)

    def tick(self) -> None:
        now = time.monotonic()
        down = self.cut.down_for
        for module, row in self.rows.items():
            heard = self.heard.get(module)
            text = "never" if heard is None else f"{now - heard:.1f} s ago"
            self.table.item(row, 2).setText(text if down is None else
                                            f"{text} (link down {age_text(down)})")
            if heard is None:           # "not running" is more than a cut link can tell
                self.table.item(row, 1).setText("not running" if down is None else
                                                "unknown: never heard, link down")
        banner = self.cut.banner("the states, charts and battery below", self.charts_at)
        self.link_banner.setText(banner)
        self.link_banner.setVisible(bool(banner))


