"""Talking to a name server (``yarpserver`` or ``yarp-lite server``).

Requests travel the way YARP 3.5's own ``NameClient`` sends them, so either
server understands them and each answers in its usual form:

* registration commands (``query``, ``register``, ``unregister``, ``set``,
  ``get``, ``list``, ``announce``...) as ``NAME_SERVER <command>`` text lines,
  answered in the "old" line format ending with ``*** end of message``;
* subscriptions and ``bot`` commands as binary Bottles over ``tcp``.

The server's address comes from ``yarp.conf`` (see :mod:`yarp_lite.nameconfig`)
and is re-read on every call, so a restarted server at a new address is found.
Every request authenticates first when an ``auth.conf`` holds a key
(:mod:`yarp_lite.auth`), looked up in the client's environment.
"""

from __future__ import annotations

import os
import socket
from typing import List, Mapping, Optional, Sequence

from yarp_lite import auth
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import BottlePayload, SUPPORTED
from yarp_lite.connection import OutgoingConnection, open_stream
from yarp_lite.contact import Contact
from yarp_lite.errors import NetworkError
from yarp_lite.nameconfig import ServerAddress, namespace, read_server_address

DEFAULT_TIMEOUT = 10.0


def parse_registration(line: str) -> Optional[Contact]:
    """``registration name /x ip 1.2.3.4 port 10002 type tcp`` -> Contact."""
    words = line.split()
    if len(words) >= 9 and words[0] == "registration":
        try:
            return Contact(name=words[2], carrier=words[8], host=words[4], port=int(words[6]))
        except ValueError:
            return None
    return None


def local_ips() -> List[str]:
    """IPv4 addresses of this machine's interfaces (YARP's ``getIpsAsBottle``)."""
    import fcntl
    import struct

    ips: List[str] = []
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _, name in socket.if_nameindex():
            try:
                request = struct.pack("256s", name.encode()[:15])
                raw = fcntl.ioctl(probe.fileno(), 0x8915, request)  # SIOCGIFADDR
            except OSError:
                continue  # interface without an IPv4 address
            address = socket.inet_ntoa(raw[20:24])
            if address not in ips:
                ips.append(address)
    finally:
        probe.close()
    return ips or ["127.0.0.1"]


class NameClient:
    """Client of one namespace's name server."""

    def __init__(self, space: Optional[str] = None, address: Optional[ServerAddress] = None,
                 timeout: float = DEFAULT_TIMEOUT,
                 environ: Optional[Mapping[str, str]] = None) -> None:
        self._space = space
        self._address = address
        self.timeout = timeout
        self.environ = environ

    # -- where ---------------------------------------------------------------

    @property
    def namespace(self) -> str:
        return self._space or namespace(self.environ)

    def server_address(self) -> ServerAddress:
        address = self._address or read_server_address(self.namespace, self.environ)
        if address is None:
            raise NetworkError(
                f"no name server configured for namespace {self.namespace} "
                f"(run 'yarp-lite server', or 'yarp-lite conf HOST PORT')")
        return address

    # -- transports ----------------------------------------------------------

    def text(self, command: str, multi: bool = True) -> List[str]:
        """Send ``NAME_SERVER <command>``; return the answer lines.

        With ``multi`` the answer ends at a line starting with ``*`` or ``[``
        (as YARP's client reads it) or when the server hangs up.
        """
        address = self.server_address()
        credentials = self.credentials()
        stream = open_stream(address.host, address.port, timeout=self.timeout,
                             credentials=credentials,
                             where=f"name server {address.host}:{address.port}")
        try:
            stream.set_timeout(self.timeout)
            stream.write(f"NAME_SERVER {command}\n".encode("utf-8", "surrogateescape"))
            first = stream.read_some()
            if not auth.is_text(first):
                raise auth.unexpected_answer(
                    credentials, stream.where,
                    f"the name server answered {len(first)} bytes that are not text")
            stream.unread(first)
            lines: List[str] = []
            while True:
                try:
                    line = stream.read_line()
                except NetworkError:
                    if lines:
                        break
                    raise
                lines.append(line)
                if not multi or (len(line) > 1 and line[0] in "*["):
                    break
            return lines
        finally:
            stream.close()

    def credentials(self) -> auth.AuthConfig:
        """The key for talking to the server (``auth.conf`` in this client's environment)."""
        return auth.load(self.environ)

    def bottle(self, command: Sequence, timeout: Optional[float] = None) -> Bottle:
        """Send a Bottle over tcp and return the server's Bottle reply."""
        address = self.server_address()
        contact = Contact(self.namespace, "tcp", address.host, address.port)
        connection = OutgoingConnection.open(contact, "admin", "tcp",
                                             timeout=timeout or self.timeout, retry_refused=0.0,
                                             credentials=self.credentials())
        try:
            reply = connection.send("d", BottlePayload(Bottle(command)), want_reply=True,
                                    timeout=timeout or self.timeout)
        finally:
            connection.close()
        return reply if reply is not None else Bottle()

    # -- registrations -------------------------------------------------------

    def query(self, name: str) -> Optional[Contact]:
        """Where ``name`` is registered, or None."""
        for line in self.text(f"query {name}"):
            contact = parse_registration(line)
            if contact is not None:
                return contact
        return None

    def register(self, name: str, carrier: str = "...", host: str = "...",
                 port: Optional[int] = None) -> Contact:
        """Register ``name`` (``...`` lets the server pick); return the registration."""
        words = ["register", name]
        if carrier != "..." or host != "..." or port is not None:
            words += [carrier, host, str(port) if port is not None else "..."]
        for line in self.text(" ".join(words)):
            contact = parse_registration(line)
            if contact is not None:
                return contact
        raise NetworkError(f"name server refused to register {name}")

    def describe_port(self, name: str, carriers: Sequence[str] = SUPPORTED) -> None:
        """The properties real YARP ports set right after registering."""
        offered = " ".join(carriers)
        self.set(name, "offers", offered.split())
        self.set(name, "accepts", offered.split())
        self.set(name, "ips", local_ips())
        self.set(name, "process", [str(os.getpid())])

    def unregister(self, name: str) -> None:
        self.text(f"unregister {name}")

    def announce(self, name: str, activity: int = 1) -> None:
        self.text(f"announce {name} {activity}" if activity != 1 else f"announce {name}")

    def set(self, name: str, key: str, values: Sequence[str]) -> List[str]:
        return self.text(" ".join(["set", name, key, *map(str, values)]))

    def get(self, name: str, key: str) -> List[str]:
        """Values of a port property (``port /x property key = v1 v2``)."""
        for line in self.text(f"get {name} {key}"):
            words = line.split()
            if len(words) >= 5 and words[0] == "port" and words[4] == "=":
                return words[5:]
        return []

    def list(self) -> List[Contact]:
        return [contact for contact in map(parse_registration, self.text("list"))
                if contact is not None]

    def list_lines(self, prefix: str = "") -> List[str]:
        return self.text(f"list {prefix}".strip())

    # -- persistent connections ----------------------------------------------

    def subscribe(self, source: str, target: str, mode: str = "") -> bool:
        command = ["subscribe", source, target] + ([mode] if mode else [])
        reply = self.bottle(command)
        return bool(reply) and str(reply[0]) == "ok"

    def unsubscribe(self, source: str, target: str) -> bool:
        reply = self.bottle(["unsubscribe", source, target])
        return bool(reply) and str(reply[0]) == "ok"

    def subscriptions(self, port: str = "") -> Bottle:
        return self.bottle(["subscribe", port] if port else ["subscribe"])

    def ping(self) -> bool:
        try:
            self.text("help", multi=False)
            return True
        except NetworkError:
            return False
