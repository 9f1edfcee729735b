"""The YARP connections a node needs, made when both ends exist and remade when lost.

Theory of operation
-------------------
A node (the bridge, the pilot gateway, perception, the Pilot Interface) opens its
own ports and declares, with :meth:`ConnectionKeeper.want`, which connections it
needs to ports of other processes.  Every ``period`` a thread checks each one
and makes the missing ones, so modules may start in any order and come back
after a crash; "waiting for ..." is logged once per outage, not every period.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import List, Optional

from yarp_lite import network
from yarp_lite.errors import YarpError
from yarp_lite.port import Port

log = logging.getLogger("nodekit.connections")


@dataclass
class _Wanted:
    source: str
    target: str
    carrier: str
    port: Port
    ours_is_source: bool
    announced: bool = False


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
        for item in wanted:
            if not item.port.is_open or self.connected(item):
                continue
            try:
                if item.ours_is_source:
                    ok = item.port.add_output(item.target, item.carrier, quiet=True)
                else:
                    ok = bool(network.connect(item.source, item.target, item.carrier,
                                              client=item.port.nameclient))
            except YarpError:
                ok = False
            if ok:
                log.info("connected %s -> %s", item.source, item.target)
                item.announced = False
            elif not item.announced:
                log.info("waiting for %s (to connect %s -> %s)",
                         item.target if item.ours_is_source else item.source,
                         item.source, item.target)
                item.announced = True

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            try:
                self.check_now()
            except Exception:  # noqa: BLE001 -- keep keeping
                log.exception("connection keeper")
