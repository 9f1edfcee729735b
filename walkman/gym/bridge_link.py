"""The robot bridge's word on the link, as a module hears it on ``/<module>/bridge:i``.

The runner opens the port and keeps it connected from :data:`ROBOT_BRIDGE_STATUS`
(:class:`nodekit.connections.ConnectionKeeper`: a bridge started after the module,
or restarted, is found within :data:`KEEP_PERIOD`).  In the lab no bridge runs:
the connection is never made, the link stays ``unknown`` and no link-loss policy
fires (:mod:`walkman.gym.link_loss`).  Statuses arrive in the port's thread and
go to a :class:`~nodekit.link_watch.LinkWatch`; the watchdog reads the state with
:meth:`BridgeLink.state`, which also lets the time pass (a bridge gone quiet).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Callable, Dict, Optional

from nodekit.connections import ConnectionKeeper
from nodekit.link_watch import DOWN, LinkState, LinkWatch, status_fields
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("walkman.gym")

#: Where the robot's bridge writes its status, every half second (:mod:`bridge.node`).
ROBOT_BRIDGE_STATUS = "/bridge/robot/status:o"
#: s between two attempts to connect it: in the lab each costs the name server a request.
KEEP_PERIOD = 1.0


class BridgeLink:
    """One module's view of the link: fed statuses, asked the state (thread-safe).
    ``clock`` dates what the port delivers (the runner's)."""

    def __init__(self, name: str, clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self._clock = clock
        self._watch = LinkWatch(direct=False, now=clock(), side="robot")
        self._lock = threading.Lock()
        self._port: Optional[Port] = None
        self._keeper: Optional[ConnectionKeeper] = None
        self._garbage_told = False

    def open(self, nameclient: NameClient, port_name: str) -> None:
        """Open ``port_name`` and keep it connected from the robot bridge's status."""
        self._port = Port(nameclient=nameclient, reader=self._on_bottle)
        self._port.open(port_name, wait=math.inf)
        self._keeper = ConnectionKeeper(period=KEEP_PERIOD)
        self._keeper.want(ROBOT_BRIDGE_STATUS, port_name, self._port, ours_is_source=False)
        self._keeper.start()

    def close(self) -> None:
        if self._keeper is not None:
            self._keeper.stop()
        if self._port is not None:
            self._port.close()

    def _on_bottle(self, bottle: Bottle) -> None:
        try:
            status = status_fields(bottle)
        except ValueError as exc:  # another program writing to our port: said once
            if not self._garbage_told:
                self._garbage_told = True
                log.warning("%s: ignored a message on %s (said once): %s", self.name,
                            self._port.name if self._port else "bridge:i", exc)
            return
        self.feed(status, self._clock())

    def feed(self, status: Dict[str, Any], now: float) -> None:
        """A status of the robot's bridge, at ``now``."""
        with self._lock:
            before = self._watch.state.state
            changed = self._watch.on_status(status, now)
        self._told(before, changed)

    def state(self, now: float) -> LinkState:
        """The link as it is ``now`` (a bridge that went quiet makes it down)."""
        with self._lock:
            before = self._watch.state.state
            changed = self._watch.tick(now)
            state = self._watch.state
        self._told(before, changed)
        return state

    def _told(self, before: str, changed: Optional[LinkState]) -> None:
        """Each change of the link in the module's log (the pilot hears of it from its own
        bridge; the module's warnings are for what the module does about it)."""
        if changed is None or changed.state == before:
            return
        if changed.state == DOWN:
            log.warning("%s: the link to the pilot is down (%s)", self.name, changed.reason)
        else:
            log.info("%s: the link to the pilot is %s", self.name, changed.state)
