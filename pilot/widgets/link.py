"""The link widget: the bridge as the pilot's PC sees it (``/bridge/pilot/status:o``).

Up or down and since when, the round trip (the kernel's smoothed RTT of the TCP
channel), commands queued for the robot, messages dropped or refused, and the
bit rate per 8-bit id computed from successive byte counters -- plus each
perception flow's mean completeness.  In the lab topology there is no bridge:
the widget says so.

Up or down comes from ``/bridge/link`` (:class:`pilot.link.LinkEvent`), the one source
every widget of the PI reads it from, not from the bridge's channel phase: that one
says "down" only once the TCP channel gave up, seconds after the other widgets.  While
the link is down there is no round trip to show, and none is shown.
"""

from __future__ import annotations

import time
from typing import Dict, Optional

from python_qt_binding.QtWidgets import (QHeaderView, QLabel, QTableWidget, QTableWidgetItem,
                                         QVBoxLayout, QWidget)

from pilot.link import BridgeEvent, LinkEvent
from pilot.link_cut import age_text

#: No status for this long: the bridge is not running (it sends one every second).
SILENT_S = 5.0


def bit_rates(before: Dict, after: Dict, seconds: float) -> Dict[str, float]:
    """bit/s per id between two ``bytes_by_id`` samples."""
    if seconds <= 0:
        return {}
    return {str(key): max(0, int(after[key]) - int(before.get(key, 0))) * 8 / seconds
            for key in after}


class LinkWidget(QWidget):
    def __init__(self, id_names: Optional[Dict[int, str]] = None, parent=None) -> None:
        super().__init__(parent)
        self.id_names = id_names or {}     # what each 8-bit id carries (the bridge config)
        self.setObjectName("link")
        layout = QVBoxLayout(self)
        self.summary = QLabel("")
        self.summary.setObjectName("link_summary")
        self.summary.setWordWrap(True)
        layout.addWidget(self.summary)
        self.rates = QTableWidget(0, 3)
        self.rates.setHorizontalHeaderLabels(["8-bit id", "carries", "bit/s"])
        self.rates.horizontalHeader().setSectionResizeMode(1, QHeaderView.Stretch)
        layout.addWidget(self.rates)
        self.flows = QLabel("")
        self.flows.setWordWrap(True)
        layout.addWidget(self.flows)
        self.last: Optional[BridgeEvent] = None
        self.heard = 0.0
        self.link: Optional[LinkEvent] = None
        self.link_at = 0.0                 # when it entered its state (time.monotonic)
        self._summarise()

    def on_link(self, event: LinkEvent) -> None:
        self.link, self.link_at = event, time.monotonic() - event.since
        self._summarise()

    def on_bridge(self, event: BridgeEvent) -> None:
        status = event.status
        tcp = status.get("tcp", {}) or {}
        before = self.last.status.get("tcp", {}).get("bytes_by_id", {}) if self.last else {}
        seconds = event.stamp - self.last.stamp if self.last else 0.0
        rates = bit_rates(before or {}, tcp.get("bytes_by_id", {}) or {}, seconds)
        self.last, self.heard = event, time.monotonic()
        self._summarise()
        if rates:
            self.rates.setRowCount(len(rates))
            for row, (ident, bits) in enumerate(sorted(rates.items(), key=lambda kv: int(kv[0]))):
                self.rates.setItem(row, 0, QTableWidgetItem(ident))
                self.rates.setItem(row, 1, QTableWidgetItem(self.id_names.get(int(ident), "")))
                self.rates.setItem(row, 2, QTableWidgetItem(f"{bits:,.0f}"))
        flows = (status.get("udp", {}) or {}).get("flows", {}) or {}
        self.flows.setText("perception: " + ", ".join(
            f"{name} {float(flow.get('mean_completeness', 0)):.0%} complete"
            for name, flow in flows.items()) if flows else "")

    def _summarise(self) -> None:
        """The link's state (``/bridge/link``), then the pilot bridge's own figures."""
        link = self.link
        state = None if link is None else link.state
        if state == "direct" or (link is None and self.last is None):
            self.summary.setText("no bridge: the lab topology has none (the pilot's programs "
                                 "reach the robot's ports directly)")
            self.summary.setStyleSheet("")
            return
        parts = ["link state not yet heard (/bridge/link)" if link is None else
                 f"link {state} for {age_text(time.monotonic() - self.link_at)}"]
        if self.last is not None:
            status = self.last.status
            dropped = status.get("dropped", {}) or {}
            round_trip = float(status.get("round_trip_ms", 0) or 0)
            parts += [f"round trip {round_trip:.1f} ms" if state == "up" and round_trip > 0
                      else "no round trip while down" if state == "down" else
                      "no round trip yet",
                      f"queued commands {status.get('queued_commands', 0)}",
                      f"refused {status.get('refused', 0)}",
                      f"dropped {sum(int(v) for v in dropped.values())}" +
                      (f" ({', '.join(f'{k} {v}' for k, v in dropped.items())})"
                       if dropped else "")]
        self.summary.setText(" | ".join(parts))
        self.summary.setStyleSheet("color: #10a010;" if state == "up" else
                                   "color: #d00000; font-weight: bold;")

    def tick(self) -> None:
        if self.link is not None or self.last is not None:
            self._summarise()
        if self.last is not None and time.monotonic() - self.heard > SILENT_S:
            self.summary.setText(f"the bridge is silent for {time.monotonic() - self.heard:.0f} s "
                                 f"(not running?)")
            self.summary.setStyleSheet("color: #d00000; font-weight: bold;")
