"""The YARP connections a node needs, made when both ends exist and remade when lost.

Theory of operation
-------------------
A node (the bridge, the pilot gateway, perception, the Pilot Interface) opens its
own ports and declares, with :meth:`ConnectionKeeper.want`, which connections it
needs to ports of other processes.  Every ``period`` a thread checks each one
and makes the missing ones, so modules may start in any order and come back
after a crash; "waiting for ..." is logged once per outage, not every period.

Trying a missing connection costs a name-server request (a new TCP connection,
as in YARP) even when the other port is not there.  With more than
:data:`LIST_ABOVE` missing, one ``list`` first tells which other ports are
registered and only those are tried: a bridge configured for 256 modules with
their status ports alone running made 765 requests every half second, which
kept its name server busy and slowed every port opening on the PC.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import Dict, List, Optional, Set, Tuple

from yarp_lite import network
from yarp_lite.errors import YarpError
from yarp_lite.port import Port

log = logging.getLogger("nodekit.connections")

#: With more connections than this missing, a ``list`` tells which are worth trying.
LIST_ABOVE = 8


@dataclass
class _Wanted:
    source: str
    target: str
    carrier: str
    port: Port
    ours_is_source: bool
    announced: bool = False

    @property
    def other_end(self) -> str:
        """The other process's port, the one that must be registered to connect (unless
        it is a raw address, ``tcp://host:port``)."""
        return self.target if self.ours_is_source else self.source


class ConnectionKeeper:
    """Keeps the connections between the bridge's ports and the modules' ports alive."""

    def __init__(self, period: float = 0.5) -> None:
        self.period = period
        self._wanted: List[_Wanted] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None

    def want(self, source: str, target: str, port: Port, ours_is_source: bool,
             carrier: str = "tcp") -> _Wanted:
        """Keep ``source -> target`` connected; the handle answers :meth:`connected`."""
        wanted = _Wanted(source, target, carrier, port, ours_is_source)
        with self._lock:
            self._wanted.append(wanted)
        return wanted

    def forget(self, port: Port) -> None:
        with self._lock:
            self._wanted = [w for w in self._wanted if w.port is not port]

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="yarp connections",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=3)

    def connected(self, wanted: _Wanted) -> bool:
        """Is that connection up now (its other end alive)?"""
        if wanted.ours_is_source:
            return any(r.target == wanted.target for r in wanted.port.output_routes())
        return any(r.source == wanted.source for r in wanted.port.input_routes())

    def check_now(self) -> None:
        with self._lock:
            wanted = list(self._wanted)
        missing = [item for item in wanted if item.port.is_open and not self.connected(item)]
        registered = self._registered(missing) if len(missing) > LIST_ABOVE else None
        for item in missing:
            if registered is not None and item.other_end.startswith("/") and \
                    item.other_end not in registered[id(item.port.nameclient)]:
                ok = False
            else:
                ok = self._connect(item)
            if ok:
                log.info("connected %s -> %s", item.source, item.target)
                item.announced = False
            elif not item.announced:
                log.info("waiting for %s (to connect %s -> %s)", item.other_end,
                         item.source, item.target)
                item.announced = True

    @staticmethod
    def _registered(missing: List[_Wanted]) -> Optional[Dict[int, Set[str]]]:
        """The names registered with each name server of ``missing``'s ports, by ``id`` of
        their name client: one ``list`` per server; None if one cannot be listed (then
        every connection is tried, as before)."""
        by_server: Dict[Tuple[str, int], Set[str]] = {}
        by_client: Dict[int, Set[str]] = {}
        for item in missing:
            client = item.port.nameclient
            if id(client) in by_client:
                continue
            try:
                address = client.server_address()
                where = (address.host, address.port)
                if where not in by_server:
                    by_server[where] = {contact.name for contact in client.list()}
            except YarpError:
                return None
            by_client[id(client)] = by_server[where]
        return by_client

    @staticmethod
    def _connect(item: _Wanted) -> bool:
        try:
            if item.ours_is_source:
                return bool(item.port.add_output(item.target, item.carrier, quiet=True))
            return bool(network.connect(item.source, item.target, item.carrier,
                                        client=item.port.nameclient))
        except YarpError:
            return False

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            try:
                self.check_now()
            except Exception:  # noqa: BLE001 -- keep keeping
                log.exception("connection keeper")
