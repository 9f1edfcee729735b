"""Presence kept in step: tell the peer which modules are here, open the peer's as stand-ins.

Theory of operation
-------------------
The rules are :mod:`bridge.gym.presence`'s (which flows a side watches, which of its
endpoints stand in for the peer's programs, the remembered word); this is the
thread that applies them, every :data:`PRESENCE_PERIOD` or at once when woken:

* *here*: the watched flows whose program's port is connected now.  When it
  changes, the TCP channel is kicked so the peer hears it in the next frame
  (:meth:`StandIns.here` is what the channel sends; None until the bridge has
  connected to the modules already running, so a restarted bridge never tells
  the peer, for a moment, that every module has gone);
* *the peer's word*: the stand-ins it names are opened, the others closed -- a
  closing one only once it has written what the journal holds for it (at most
  :data:`bridge.gym.presence.READER_GRACE`), so a module's last warning reaches the
  pilot.  The word is remembered on disk for a restart during an outage.

The stand-ins are also sources of the link's messages: :meth:`StandIns.source`
gives the open one of a flow to the delivery path, under the lock that
:meth:`StandIns.close` takes, so nothing is opened after the bridge stopped.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional

from bridge.config import ROBOT, BridgeConfig, Channel
from bridge.flows import FlowKey
from bridge.gym import presence as rules
from bridge.gym.presence import READER_GRACE, Presence, PresenceMemory
from bridge.transport.journal import Journal
from yarp_lite.errors import YarpError

log = logging.getLogger("bridge")

#: How often a bridge looks whether its modules' ports are connected, and its stand-ins in step.
PRESENCE_PERIOD = 0.2


class StandIns:
    """One side's presence: its watched module ends, and the peer's modules stood in for."""

    def __init__(self, config: BridgeConfig, side: str, state_dir: Path, journal: Journal,
                 open_endpoint: Callable[[Channel], Any],
                 on_here_changed: Callable[[], None], on_opened: Callable[[], None],
                 on_closed: Callable[[FlowKey], None]) -> None:
        self.config = config
        self.side = side
        self.keys = rules.stand_ins(config, side)
        self.watched = rules.watched(config, side)
        self.journal = journal
        self._open_endpoint = open_endpoint
        self._on_here_changed = on_here_changed     # the TCP channel: say it in a frame
        self._on_opened = on_opened                 # the delivery: what waited for them
        self._on_closed = on_closed                 # first-status memory: forget the flow
        self.internal_errors = 0
        self._module_ends: Dict[FlowKey, Any] = {}  # endpoints whose program's port is watched
        self._open: Dict[FlowKey, Any] = {}         # stand-ins open now
        self._leaving: Dict[FlowKey, float] = {}    # said gone, still writing the journal's
        self._lock = threading.Lock()               # open/close vs delivery and close()
        self._closed = False
        self._wake = threading.Event()
        self._memory = PresenceMemory(state_dir, config)
        self.remembered: Presence = self._memory.load()
        self.peer: Presence = self.remembered       # the peer's last word
        self._here: Optional[Presence] = None

    # -- what the TCP channel and the delivery path ask --------------------------------

    def here(self) -> Optional[Presence]:
        """The watched flows whose program's port is connected here, as last looked at;
        None until :meth:`keep` runs."""
        return self._here

    def on_peer(self, flows: Presence) -> None:
        """The peer's word (from a frame): followed at once."""
        self.peer = flows
        self._wake.set()

    def watch(self, key: FlowKey, endpoint: Any) -> None:
        """``endpoint`` connects to a program whose presence the peer is told."""
        self._module_ends[key] = endpoint

    def source(self, key: FlowKey) -> Optional[Any]:
        """The open stand-in that delivers ``key``'s messages to local programs, if any."""
        with self._lock:
            endpoint = self._open.get(key)
        if endpoint is None or self.config.channel(key).destination != self.side:
            return None
        return endpoint

    def shown(self) -> Presence:
        """The flows whose stand-ins are open now."""
        with self._lock:
            return frozenset(self._open)

    def endpoints(self) -> List[Any]:
        with self._lock:
            return list(self._open.values())

    # -- the thread ----------------------------------------------------------------------

    def keep(self, stopping: threading.Event) -> None:
        """Tell the peer at once when a module's ports come or go here; open and close the
        stand-ins as the peer's word says.  Never ends before ``stopping``: a name server
        gone in the middle is tried again, a bug is logged and counted."""
        kept = self.remembered
        failing = False
        while not stopping.is_set():
            try:
                here = frozenset(key for key, endpoint in list(self._module_ends.items())
                                 if endpoint.linked)
                if here != self._here:
                    self._here = here
                    self._on_here_changed()
                peer = self.peer
                if peer != kept:
                    kept = peer
                    self._memory.save(peer)
                self.follow(peer & self.keys)
                failing = False
            except YarpError as exc:
                if not failing:
                    log.warning("presence: cannot open or close stand-ins now (%s); trying "
                                "again", exc)
                failing = True
            except Exception:  # noqa: BLE001 -- our bug: seen, counted, and tried again
                if stopping.is_set():
                    return  # the journal closed under us: stopping, not a bug
                self.internal_errors += 1
                log.exception("presence: following the peer failed (a bug); trying again")
            self._wake.wait(PRESENCE_PERIOD)
            self._wake.clear()

    def wake(self) -> None:
        self._wake.set()

    def follow(self, wanted: Presence) -> None:
        """Open the stand-ins ``wanted`` names, close the others -- once a closing one has
        written what the journal holds for it (a module's last warning reaches the pilot)."""
        opened: Dict[str, List[str]] = {}
        closed: Dict[str, List[str]] = {}
        pending: Optional[set] = None   # read from the journal only when one is closing
        now = time.monotonic()
        for key in sorted(self.keys):
            if self._closed:
                return
            channel = self.config.channel(key)
            if key in wanted and key not in self._open:
                endpoint = self._open_endpoint(channel)
                with self._lock:   # close() closes what is listed, or we do
                    if self._closed:
                        endpoint.close()
                        return
                    self._open[key] = endpoint
                opened.setdefault(channel.module, []).append(endpoint.port.name)
            elif key not in wanted and key in self._open:
                leaving = self._leaving.setdefault(key, now)
                if pending is None:
                    pending = {FlowKey(message.id, message.kind)
                               for message in self.journal.undelivered()}
                if key in pending and now - leaving < READER_GRACE:
                    continue   # what the journal holds for it first, for a while
                self._leaving.pop(key, None)
                with self._lock:
                    endpoint = self._open.pop(key)
                self._on_closed(key)
                endpoint.close()
                closed.setdefault(channel.module, []).append(endpoint.port.name)
            else:
                self._leaving.pop(key, None)
        peer = "pilot" if self.side == ROBOT else "robot"
        for module, names in opened.items():
            log.info("%s is on the %s: opened %s", module, peer, ", ".join(names))
        for module, names in closed.items():
            log.info("%s left the %s: closed %s", module, peer, ", ".join(names))
        if opened:
            self._on_opened()

    def close(self) -> List[Any]:
        """No stand-in opens from now on; returns the open ones, for the caller to close
        with the bridge's other endpoints."""
        with self._lock:
            self._closed = True
            endpoints, self._open = list(self._open.values()), {}
        self._wake.set()
        return endpoints
