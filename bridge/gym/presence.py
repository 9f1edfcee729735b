"""Presence: a module's stand-in ports exist on one side only while the module exists on the other.

Theory of operation
-------------------
A bridged YARP flow has a *module end* where the bridge connects to a program's
port: the sending side when it reads a program's output (the robot's bridge
reads ``/M/status:o``), else the receiving side when it writes a program's input
(the robot's bridge writes ``/M/switch:i``).  The other side's endpoint is a
*stand-in*: it opens that program port's own name (``/M/status:o``,
``/M/switch:i`` on the pilot's name server) for local programs.  A side watches
its module ends -- is the connection to the program up? -- and tells the peer,
on every new connection and whenever it changes (the ``presence`` of a TCP
frame, :mod:`bridge.wire.frames`); the peer opens a stand-in while its flow is
present and closes it otherwise, so its programs see the module come and go as
they would on one name server: a pilot's tools can tell a running module from
an absent one, and a command to an absent module is refused at the pilot as in
the lab.

While the link is down the peer's last word stands: the stand-ins stay, and a
command to them waits in the journal for the link, as before.  That word is kept
in the state directory (:class:`PresenceMemory`), so a bridge restarted during an
outage shows what it showed before it stopped.  The endpoint that watches a
program is always open (a custom module's ``port_to_open``, the robot's
``/bridge/robot/M/...``), and so are the robot state's ports and ROS topics, which
have no module end here.  A stand-in closes only once it has written what the
journal holds for it, so a module's last warning still reaches the pilot.

This module is pure: which endpoints are stand-ins, which flows a side watches,
and the remembered word; :class:`bridge.gym.stand_ins.StandIns` opens and closes ports.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path
from typing import Optional

from bridge.config import BridgeConfig, Channel
from bridge.wire.frames import Presence

log = logging.getLogger("bridge.gym.presence")

#: Seconds a reliable message waits for a reader of a stand-in local programs read (the
#: pilot's ``/M/warning:o``, just opened) before it is written with nobody reading, as
#: YARP would -- a gateway connects within a second -- and a stand-in said gone stays
#: open for what the journal still holds for it.  Nothing waits for ever.
READER_GRACE = 10.0


def module_end(channel: Channel) -> Optional[str]:
    """The side that watches the program ``channel`` connects to, if any."""
    if channel.middleware != "yarp":
        return None
    if channel.feed_port:
        return channel.source
    if channel.deliver_port is not None:
        return channel.destination
    return None


def watched(config: BridgeConfig, side: str) -> Presence:
    """The flows whose module end is on ``side``: what it tells the peer about."""
    return frozenset(c.key for c in config.channels if module_end(c) == side)


def stand_ins(config: BridgeConfig, side: str) -> Presence:
    """The flows whose endpoint on ``side`` stands in for a program on the peer's side."""
    return frozenset(c.key for c in config.channels
                     if module_end(c) not in (None, side))


class PresenceMemory:
    """The peer's last word on presence, in ``<state_dir>/presence.json``, by flow label.

    Labels (``gaze_control/status``), not ids, so an edited configuration cannot
    make a remembered id mean another module.  A missing or unreadable file is
    an empty memory (said once in the log): the link brings the truth.
    """

    def __init__(self, state_dir: Path, config: BridgeConfig) -> None:
        self.path = Path(state_dir) / "presence.json"
        self._labels = {c.key: c.label for c in config.channels}
        self._keys = {label: key for key, label in self._labels.items()}

    def load(self) -> Presence:
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return frozenset()
        except OSError as exc:
            log.warning("presence: cannot read %s (%s); no module shown until the link says",
                        self.path, exc)
            return frozenset()
        try:
            labels = json.loads(text)["present"]
            if not isinstance(labels, list):
                raise TypeError("'present' is not a list")
        except (ValueError, KeyError, TypeError) as exc:
            log.warning("presence: %s is not a presence file (%s); no module shown until the "
                        "link says", self.path, exc)
            return frozenset()
        return frozenset(self._keys[label] for label in labels if label in self._keys)

    def save(self, presence: Presence) -> None:
        labels = sorted(self._labels[key] for key in presence if key in self._labels)
        temporary = self.path.with_suffix(".tmp")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            temporary.write_text(json.dumps({"present": labels}) + "\n")
            os.replace(temporary, self.path)
        except OSError as exc:
            log.warning("presence: cannot keep the peer's word in %s: %s", self.path, exc)
