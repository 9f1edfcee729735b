"""Network-wide operations: connect, disconnect, query, write to a port by name.

These are YARP's ``NetworkBase`` functions.  A connection is made by asking
the *source* port, over its admin interface, to add an output
(``[add] tcp://dest``) -- so they work the same whether the ports are
yarp_lite or real YARP.  Persistent connections are asked of the name server
instead (``subscribe src dest``).  Every function reports failure the way the
``yarp`` tool prints it (``Failure: ...``) through :class:`Outcome`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.carriers import BottlePayload
from yarp_lite.connection import REFUSED_RETRY, OutgoingConnection
from yarp_lite.contact import Contact, is_valid_port_name
from yarp_lite.errors import AuthenticationError, NetworkError, YarpError
from yarp_lite.nameclient import NameClient

Resolver = Callable[[str], Optional[Contact]]


@dataclass(frozen=True)
class Outcome:
    ok: bool
    message: str = ""

    def __bool__(self) -> bool:
        return self.ok


def _resolver(client: Optional[NameClient], resolve: Optional[Resolver]) -> Resolver:
    if resolve is not None:
        return resolve
    chosen = client or NameClient()

    def query(name: str) -> Optional[Contact]:
        try:
            return chosen.query(name)
        except NetworkError:
            return None
    return query


def request(target: Contact, command: Sequence, admin: bool = False, carrier: str = "",
            sender: str = "admin", timeout: float = 10.0,
            retry_refused: float = REFUSED_RETRY) -> Bottle:
    """Send one Bottle to a port and return its reply (``NetworkBase::write``).

    Admin requests use ``text_ack`` by default, as YARP's tools do, so they
    also work against ports that only speak text.  A refused connection is
    retried for ``retry_refused`` seconds (a port registers before it listens).
    """
    chosen = carrier or ("text_ack" if admin else target.carrier or "tcp")
    connection = OutgoingConnection.open(target, sender, chosen, timeout=timeout,
                                         retry_refused=retry_refused)
    try:
        reply = connection.send("a" if admin else "d", BottlePayload(Bottle(command)),
                                want_reply=True, timeout=timeout)
    finally:
        connection.close()
    return reply if reply is not None else Bottle()


def connect(source: str, target: str, carrier: str = "", *, client: Optional[NameClient] = None,
            resolve: Optional[Resolver] = None, persist: bool = False,
            mode: str = "") -> Outcome:
    """Connect ``source``'s output to ``target`` (``yarp connect``)."""
    if carrier:
        target = f"{carrier}:/{Contact.parse(target).name or target}"
    if persist:
        chosen = client or NameClient()
        try:
            ok = chosen.subscribe(source, target, mode)
        except YarpError as exc:
            return Outcome(False, f"Failure: {exc}")
        return Outcome(ok, "Success: port-to-port persistent connection added." if ok
                       else "Persistent connection operation failed.")
    wanted_source, wanted_target = Contact.parse(source), Contact.parse(target)
    for role, contact in (("source", wanted_source), ("destination", wanted_target)):
        if not is_valid_port_name(contact.name):
            return Outcome(False, f"Failure: no way to make connection, invalid {role} "
                                  f"'{contact.name}'")
    lookup = _resolver(client, resolve)
    found_source = lookup(wanted_source.name)
    if found_source is None:
        return Outcome(False, f"Failure: could not find source port {source}")
    found_target = lookup(wanted_target.name)
    if found_target is None:
        return Outcome(False, f"Failure: could not find destination port {target}")
    chosen = wanted_source.carrier or wanted_target.carrier or found_target.carrier or "tcp"
    spec = str(Contact(wanted_target.name, chosen))
    try:
        reply = request(found_source, [Vocab("add"), spec], admin=True)
    except YarpError as exc:
        return Outcome(False, f"Failure: {exc}")
    return _admin_outcome(reply, "connect")


def disconnect(source: str, target: str, *, client: Optional[NameClient] = None,
               resolve: Optional[Resolver] = None, persist: bool = False) -> Outcome:
    """Remove the connection ``source -> target`` (``yarp disconnect``)."""
    if persist:
        chosen = client or NameClient()
        try:
            ok = chosen.unsubscribe(source, target)
        except YarpError as exc:
            return Outcome(False, f"Failure: {exc}")
        return Outcome(ok, "" if ok else "Unsubscription failed.")
    found_source = _resolver(client, resolve)(Contact.parse(source).name)
    if found_source is None:
        return Outcome(False, f"Failure: could not find source port {source}")
    try:
        reply = request(found_source, [Vocab("del"), Contact.parse(target).name or target],
                        admin=True)
    except YarpError as exc:
        return Outcome(False, f"Failure: {exc}")
    outcome = _admin_outcome(reply, "disconnect")
    return outcome if outcome.ok else Outcome(False, "Failure: no such connection")


def _admin_outcome(reply: Bottle, action: str) -> Outcome:
    if reply and isinstance(reply[0], int) and not isinstance(reply[0], Vocab):
        ok = reply[0] == 0
        message = str(reply[1]) if len(reply) > 1 else ""
    else:
        message = str(reply[0]) if reply else ""
        ok = message[:1] in ("A", "R")
    return Outcome(ok, ("Success: " if ok else "Failure: ") + message)


def connection_carrier(source: str, target: str, *, client: Optional[NameClient] = None,
                       resolve: Optional[Resolver] = None) -> Optional[str]:
    """The carrier of the connection ``source -> target``, or None if there is none."""
    found_source = _resolver(client, resolve)(Contact.parse(source).name)
    if found_source is None:
        return None
    try:
        reply = request(found_source, [Vocab("list"), Vocab("out"),
                                       Contact.parse(target).name or target],
                        admin=True, timeout=5.0)
    except AuthenticationError:
        raise  # not "no connection": nobody can tell until the keys match
    except YarpError:
        return None
    carrier = reply.find("carrier")
    return str(carrier) if carrier is not None else None


def is_connected(source: str, target: str, **kwargs) -> bool:
    return connection_carrier(source, target, **kwargs) is not None


def exists(name: str, *, client: Optional[NameClient] = None, timeout: float = 5.0,
           check_version: bool = True) -> bool:
    """Is ``name`` registered and answering now (``NetworkBase::exists``)?

    A refusal is not retried: this asks about the present (callers that
    wait, like :func:`wait_for_port`, poll).  A port that refuses our key
    raises :class:`AuthenticationError` instead of answering no.
    """
    contact = _resolver(client, None)(name)
    if contact is None:
        return False
    if not check_version:
        try:
            OutgoingConnection.open(contact, "admin", "text", timeout=timeout,
                                    retry_refused=0.0).abort()
            return True
        except AuthenticationError:
            raise  # something answers, but not to us: say so rather than "no"
        except YarpError:
            return False
    try:
        reply = request(contact, [Vocab("ver")], admin=True, timeout=timeout, retry_refused=0.0)
    except AuthenticationError:
        raise
    except YarpError:
        return False
    return bool(reply) and str(reply[0]) in ("ver", "dict")


def wait_for_port(name: str, timeout: Optional[float] = None,
                  client: Optional[NameClient] = None, poll: float = 0.1) -> bool:
    deadline = None if timeout is None else time.monotonic() + timeout
    while not exists(name, client=client, timeout=2.0, check_version=False):
        if deadline is not None and time.monotonic() > deadline:
            return False
        time.sleep(poll)
    return True


def wait_for_connection(source: str, target: str, timeout: Optional[float] = None,
                        client: Optional[NameClient] = None, poll: float = 0.1) -> bool:
    deadline = None if timeout is None else time.monotonic() + timeout
    while not is_connected(source, target, client=client):
        if deadline is not None and time.monotonic() > deadline:
            return False
        time.sleep(poll)
    return True


def describe(name: str, client: Optional[NameClient] = None, timeout: float = 5.0) -> list:
    """The ``*`` description a port gives of itself (``yarp ping``)."""
    contact = _resolver(client, None)(name)
    if contact is None:
        raise NetworkError(f"could not find port {name}")
    connection = OutgoingConnection.open(contact, "<ping>", "text_ack", timeout=timeout)
    try:
        lines = connection.send_text_command("*", timeout=timeout)
    finally:
        connection.abort()
    return [line for line in lines if line != "<ACK>"][:64]
