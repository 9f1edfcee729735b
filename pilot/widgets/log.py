"""The pilot's log: every command any pilot sent (and who), status changes, warnings.

Commands come from ``/pilot/sent_commands``, which each gateway fills with its
own and the other stations' commands, so every PI shows every pilot's; a
command from another PI is marked as such.  Warnings are red (paper, 2.3).  The link
going down and coming back (``/bridge/link``) is said too, with what it held.
"""

from __future__ import annotations

import html
import time
from typing import Dict, Optional

from python_qt_binding.QtWidgets import QTextEdit

from pilot.link import (BatteryEvent, CommandStateEvent, LinkEvent, SentEvent, StatusEvent,
                        WarningEvent)
from walkman.hal.battery import WARNING_LEVELS as BATTERY_LEVELS

MAX_LINES = 2000


class LogView(QTextEdit):
    def __init__(self, me: str, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("log")
        self.setReadOnly(True)
        self.me = me
        self.states: Dict[str, str] = {}
        self.link_state = ""
        self.battery_level: Optional[float] = None   # the lowest level the charge is under
        self.lines = 0

    def _line(self, stamp: float, text: str, colour: str = "") -> None:
        when = time.strftime("%H:%M:%S", time.localtime(stamp))
        body = html.escape(text)
        self.append(f'<span style="color:{colour or "#000000"}">{when} {body}</span>')
        self.lines += 1
        if self.lines > MAX_LINES:
            self.clear()
            self.lines = 0

    def note(self, text: str, colour: str = "#8a5a00") -> None:
        """A line of the PI's own (its 3-D view restarting), now."""
        self._line(time.time(), text, colour)

    def on_sent(self, event: SentEvent) -> None:
        mine = event.sender == self.me
        who = "me" if mine else f"{event.sender} (station {event.station})"
        self._line(event.stamp, f"{who} -> /{event.module}/{event.port}: {event.text}",
                   "" if mine else "#2060c0")

    def on_status(self, event: StatusEvent) -> None:
        if self.states.get(event.module) != event.state:
            self.states[event.module] = event.state
            self._line(time.time(), f"/{event.module}: {event.state}", "#606060")

    def on_warning(self, event: WarningEvent) -> None:
        self._line(event.stamp, f"/{event.module} WARNING: {event.text}", "#d00000")

    def on_battery(self, event: BatteryEvent) -> None:
        """A line when the charge falls below a level (the HAL warns on the robot too)."""
        below = [level for level in BATTERY_LEVELS if event.percent < level]
        lowest = min(below, default=None)
        if lowest is not None and (self.battery_level is None or lowest < self.battery_level):
            self._line(event.stamp, f"BATTERY below {lowest:g} %: {event.percent:.1f} %, "
                                    f"{event.voltage:.1f} V", "#d00000")
        self.battery_level = lowest

    def on_link(self, event: LinkEvent) -> None:
        before, self.link_state = self.link_state, event.state
        if event.state == before:
            if event.state == "down" and event.queued:
                self._line(time.time(), f"link down: {event.queued} command(s) wait for it",
                           "#2f6fd0")
            return
        if event.state == "down":
            held = f"; {event.queued} command(s) wait for it" if event.queued else ""
            self._line(time.time() - event.since,
                       f"LINK DOWN ({event.reason}): commands wait for it, and expire if "
                       f"they wait past their validity{held}", "#2f6fd0")
        elif event.state == "up" and before == "down":
            self._line(time.time(), "link up again", "#2f6fd0")
        elif event.state == "up":
            self._line(time.time(), "link to the robot up", "#606060")

    #: The states of a command worth a line: what the pilot must know happened to it.
    TOLD = {"queued": "#2f6fd0", "refused": "#d00000", "expired": "#d00000",
            "interrupted": "#d00000", "cancelled": "#606060"}

    def on_command_state(self, event: CommandStateEvent) -> None:
        colour = self.TOLD.get(event.state)
        if colour is None:
            return
        why = f": {event.reason}" if event.reason else ""
        who = "" if event.sender == self.me else f" (from {event.sender})"
        self._line(event.stamp, f"/{event.module}/{event.port} `{event.text}` "
                                f"{event.state}{why}{who}", colour)
