"""Keeping ports registered: a name server that restarts learns them again.

See :class:`RegistrationKeeper`.
"""

from __future__ import annotations

import contextlib
import logging
import threading
from typing import Dict, Iterator, List, Optional, Protocol

from yarp_lite.contact import Contact
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient

log = logging.getLogger("yarp_lite.port")


class Kept(Protocol):
    """What the keeper needs of a port (:class:`yarp_lite.port.Port`)."""

    name: str
    address: Contact
    nameclient: NameClient

    @property
    def is_open(self) -> bool: ...


class RegistrationKeeper:
    """Re-registers open ports when the name server comes back.

    Real YARP ports stay unregistered after a name server restart; ours notice
    and register again at the same address, so persistent connections and
    lookups work without restarting the modules.  Noticing costs one ``query``
    per name server (not per port) every few seconds, for one of this process's
    ports in turn
    (a restarted server has lost them all, so one tells); only when that port is
    missing does a ``list`` find the others.  A ``list`` every period cost what
    the server holds: 53 kbit/s over the robot link for one pilot process in
    the direct topology (``bench/bench_bridge.py`` 1), and megabytes with 10 000
    ports.

    One keeper serves every port a process opens (:meth:`instance`); a port may be given
    its own instead.  Its thread runs while it keeps a port, and ends soon after the last
    one closes.
    """

    _instance: Optional["RegistrationKeeper"] = None
    _instance_lock = threading.Lock()
    PERIOD = 2.0

    def __init__(self) -> None:
        self._ports: List[Kept] = []
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._turn = 0  # which port the next check asks about
        self._round = threading.Lock()   # the background round vs held()
        self._holding = 0

    @classmethod
    def instance(cls) -> "RegistrationKeeper":
        with cls._instance_lock:
            if cls._instance is None:
                cls._instance = cls()
            return cls._instance

    def add(self, port: Kept) -> None:
        with self._lock:
            self._ports.append(port)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, daemon=True,
                                                name="yarp_lite registration keeper")
                self._thread.start()

    def remove(self, port: Kept) -> None:
        """Stop keeping ``port``; the thread ends soon after the last port goes."""
        with self._lock:
            if port in self._ports:
                self._ports.remove(port)
            if not self._ports:
                self._wake.set()

    def check_now(self) -> None:
        """Run one check soon (tests and tools use this instead of sleeping)."""
        self._wake.set()

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """No background round meanwhile (one under way ends first): for a caller that
        runs :meth:`check_all` itself and counts what one round asks."""
        with self._round:
            self._holding += 1
        try:
            yield
        finally:
            with self._round:
                self._holding -= 1

    def _run(self) -> None:
        while True:
            self._wake.wait(self.PERIOD)
            self._wake.clear()
            with self._lock:
                if not self._ports:       # the last port closed: the keeper's work is done
                    self._thread = None
                    return
            with self._round:
                if not self._holding:
                    self.check_all()

    def check_all(self) -> None:
        """One round: ask each name server about one of our ports; re-register if lost."""
        with self._lock:
            ports = [port for port in self._ports if port.is_open]
        by_server: Dict[object, List[Kept]] = {}
        for port in ports:  # each port has its own client: one check per server
            by_server.setdefault(self._server_of(port), []).append(port)
        for group in by_server.values():
            self._check(group)

    @staticmethod
    def _server_of(port: Kept) -> object:
        try:
            address = port.nameclient.server_address()
        except YarpError:
            return id(port.nameclient)  # none configured now: its own group, skipped
        return (address.host, address.port)

    def _check(self, ports: List[Kept]) -> None:
        client = ports[0].nameclient
        self._turn += 1
        sentinel = ports[self._turn % len(ports)]
        try:
            found = client.query(sentinel.name)
            if found is not None and found.port == sentinel.address.port:
                return  # the server still knows us
            known = {contact.name: contact for contact in client.list()}
        except YarpError:
            return  # server down: try again next period
        for port in ports:
            current = known.get(port.name)
            if current is not None and current.port == port.address.port:
                continue
            if not port.is_open:
                continue
            try:
                client.register(port.name, "tcp", port.address.host, port.address.port)
                client.describe_port(port.name)
                client.announce(port.name)
                log.info("%s: registered again with the name server", port.name)
            except YarpError as exc:
                log.debug("%s: re-registration failed: %s", port.name, exc)
