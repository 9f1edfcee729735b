"""``yarp-lite server``: a drop-in for ``yarpserver``.

The server is an ordinary yarp_lite port (named after the namespace,
``/root`` by default) whose reader applies :class:`NameService` to every
request, on any carrier: ``NAME_SERVER`` text, ``text``/``text_ack`` typing,
or binary tcp Bottles.  Around it:

* the registry and subscriptions in SQLite (``--portdb``, ``--subdb``);
  subscriptions default to a file, so persistent connections survive a
  restart (yarpserver keeps them in memory unless told otherwise);
* a connector thread that makes and breaks the persistent connections the
  service asks for, asking the source port through its admin interface;
* the ``yarp.conf`` handshake of ``BootstrapServer``: the address is written
  where every YARP program of this namespace will look for it.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Set, Tuple

from yarp_lite import network
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import Incoming, Payload
from yarp_lite.contact import Contact, safe_name
from yarp_lite.delivery import Source
from yarp_lite.errors import LocalProtocolError, YarpError
from yarp_lite.nameconfig import (DEFAULT_PORT, ServerAddress, config_file, data_home,
                                  namespace as current_namespace, read_server_address,
                                  write_server_address)
from yarp_lite.nameclient import local_ips
from yarp_lite.nameserver.registry import Registry
from yarp_lite.nameserver.service import NameService, Outcome
from yarp_lite.nameserver.subscriptions import Action, Subscriptions
from yarp_lite.port import Port

log = logging.getLogger("yarp_lite.nameserver")


def default_host() -> str:
    """``NameConfig::getHostName``: the shortest non-loopback IPv4 address, if any."""
    usable = [ip for ip in local_ips() if not ip.startswith("127.")]
    return min(usable, key=len) if usable else "127.0.0.1"


@dataclass
class ServerOptions:
    ip: str = ""
    socket: int = 0
    portdb: str = ":memory:"
    subdb: str = ""
    namespace: str = ""
    write: bool = False
    read: bool = False
    silent: bool = False


class _Requests:
    """The server's own port's delivery (:mod:`yarp_lite.delivery`): every data message is
    a name server request, answered in the input's thread."""

    latest_only = False

    def __init__(self, server: "NameServer") -> None:
        self._server = server
        self.envelope = ""

    def deliver(self, message: Incoming, source: Source) -> Optional[Payload]:
        return self._server.handle(message.bottle(), source.remote_host)

    def superseded(self, message: Incoming) -> None:
        """Never: every request is answered."""

    def pace(self) -> None:
        """No wait: the next request is read at once."""

    def close(self) -> None:
        """Nobody waits on it."""


class Connector:
    """Makes and breaks the persistent connections, off the request path."""

    RETRIES = 3

    def __init__(self, service: NameService) -> None:
        self.service = service
        self.queue: "queue.Queue[Optional[Tuple[Action, int]]]" = queue.Queue()
        self.pending: Set[Action] = set()
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, daemon=True, name="subscriptions")
        self.thread.start()

    def submit(self, action: Action) -> None:
        with self.lock:
            if action in self.pending:
                return
            self.pending.add(action)
        self.queue.put((action, 0))

    def stop(self) -> None:
        self.queue.put(None)

    def _resolve(self, name: str) -> Optional[Contact]:
        registration = self.service.registry.get(name)
        return registration.contact() if registration is not None else None

    def _run(self) -> None:
        while True:
            item = self.queue.get()
            if item is None:
                return
            action, attempt = item
            with self.lock:
                self.pending.discard(action)
            try:
                self._apply(action)
            except YarpError as exc:
                if attempt + 1 < self.RETRIES:
                    time.sleep(0.2 * (attempt + 1))
                    self.queue.put((action, attempt + 1))
                else:
                    log.info("persistent connection %s -> %s: %s", action.source,
                             action.target, exc)

    def _apply(self, action: Action) -> None:
        carrier = network.connection_carrier(action.source, action.target,
                                              resolve=self._resolve)
        if action.connect:
            wanted = Contact.parse(action.target).carrier or Contact.parse(action.source).carrier
            if carrier is not None and (not wanted or wanted == carrier):
                return
            outcome = network.connect(action.source, action.target, resolve=self._resolve)
            if not outcome.ok:
                raise YarpError(outcome.message)
            log.info("   (connected %s -> %s)", action.source, action.target)
        elif carrier is not None:
            network.disconnect(action.source, action.target, resolve=self._resolve)
            if self.service.subscriptions.wanted(action.source, action.target):
                # Decided when a port left, applied after it came back under the same name:
                # the connection broken may be the new one (or an output to the old process
                # the source still lists), so it is made again, to the port there now.
                outcome = network.connect(action.source, action.target, resolve=self._resolve)
                log.info("   (re-made %s -> %s: both ends are back)%s", action.source,
                         action.target, "" if outcome.ok else f": {outcome.message}")


class NameServer:
    """A running name server; :meth:`start` returns once it answers requests."""

    def __init__(self, options: ServerOptions) -> None:
        self.options = options
        self.namespace = options.namespace or current_namespace()
        self.lock = threading.Lock()
        self.port: Optional[Port] = None
        self.service: Optional[NameService] = None
        self.connector: Optional[Connector] = None
        self.address: Optional[ServerAddress] = None

    def _choose_address(self) -> ServerAddress:
        options = self.options
        previous = read_server_address(self.namespace)
        if options.read and previous is None:
            raise LocalProtocolError(f"could not read configuration file "
                                     f"{config_file(self.namespace)}")
        host = options.ip or (previous.host if previous else "") or default_host()
        port = options.socket or (previous.port if previous else 0) or DEFAULT_PORT
        chosen = ServerAddress(host, port)
        changed = previous is not None and (previous.host, previous.port) != (host, port)
        if changed and not options.write:
            raise LocalProtocolError(
                f"need to change settings in {config_file(self.namespace)}: it says "
                f"{previous.host}:{previous.port}, this server would be {host}:{port}. "
                "Pass --write to overwrite it, --read to use it, or delete the file.")
        if changed or previous is None:
            path = write_server_address(chosen, self.namespace)
            log.info("Wrote %s:%d to %s", host, port, path)
        return chosen

    def start(self) -> "NameServer":
        options = self.options
        self.address = self._choose_address()
        subdb = options.subdb or str(data_home() / (
            f"subscriptions{safe_name(self.namespace)}_{self.address.port}.db"))
        if subdb != ":memory:":
            Path(subdb).parent.mkdir(parents=True, exist_ok=True)
        reset = bool(options.ip or options.socket) and options.portdb != ":memory:"
        log.info("Using port database: %s", options.portdb)
        log.info("Using subscription database: %s", subdb)
        log.info("IP address: %s", self.address.host)
        log.info("Port number: %d", self.address.port)
        registry = Registry(options.portdb, self.address.port, reset=reset)
        subscriptions = Subscriptions(subdb)
        self.service = NameService(registry, subscriptions, self.address.host,
                                   self.address.port, silent=options.silent)
        self.connector = Connector(self.service)
        self.port = Port(register=False, delivery=_Requests(self))
        bind_host = "" if self.address.host not in ("127.0.0.1", "localhost") else "127.0.0.1"
        self.port.open(self.namespace, host=bind_host, socket_number=self.address.port)
        self.port.address = Contact(self.namespace, "tcp", self.address.host, self.address.port)
        log.info("Registering name server with itself")
        self.handle(Bottle(["register", self.namespace, "tcp", self.address.host,
                            self.address.port]), self.address.host)
        self.handle(Bottle(["set", self.namespace, "nameserver", "true"]), self.address.host)
        self.handle(Bottle(["announce", self.namespace]), self.address.host)
        log.info("Ok. Ready!")
        return self

    def handle(self, command: Bottle, remote: str) -> Payload:
        """Apply one request; perform its events and actions; return the reply."""
        from yarp_lite.carriers import BottlePayload

        assert self.service is not None and self.connector is not None
        with self.lock:
            outcome: Outcome = self.service.apply(command, remote)
        for action in outcome.actions:
            self.connector.submit(action)
        if outcome.events and self.port is not None:
            self.port.drop_closed_outputs()      # a gone listener's socket is not kept
            for event in outcome.events:
                self.port.write(event)
        reply = outcome.reply
        return reply if isinstance(reply, Payload) else BottlePayload(reply)

    def stop(self) -> None:
        if self.connector is not None:
            self.connector.stop()
        if self.port is not None:
            self.port.close()
        if self.service is not None:
            self.service.registry.close()
            self.service.subscriptions.close()

    def serve_forever(self) -> None:
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            log.info("closing yarp-lite server")
        finally:
            self.stop()
