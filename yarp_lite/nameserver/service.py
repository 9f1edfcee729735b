"""The name server's command language: one Bottle in, one reply out.

Theory of operation
-------------------
``NameService.apply`` reproduces yarpserver's ``ComposedNameService``: the
subscription commands (``subscribe``, ``unsubscribe``, ``announce``,
``topic``, ``untopic``, ``type``) are tried first, then the registry
commands of ``NameServiceOnTriples``.  Registry commands answer in two
styles:

* the classic "old" style, lines of text ending with ``*** end of message``
  (what ``yarp name list`` prints), returned as :class:`OldReply`;
* with a ``bot`` prefix, a Bottle (``bot query /x`` ->
  ``port (name /x) (ip ..) (port_number ..) (carrier tcp)``).

Applying a command also yields *events* (``[add] /port``, ``[del] /port``,
broadcast to whoever listens to the server port) and *actions*: connections
the server must make or break for persistent connections.  The service does
no I/O; :mod:`yarp_lite.nameserver.server` performs events and actions.

Commands come from any client, so :meth:`NameService.apply` answers any
Bottle (unknown commands get an empty reply, as from yarpserver) except one
whose text is not UTF-8 (a peer's raw bytes decoded with surrogate escapes):
the registry's SQLite tables cannot hold it, so that is a
:class:`RemoteProtocolError` and the server drops the connection.  A command
is bounded by the line or message limit of the connection that carried it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Union

from yarp_lite.bottle import Bottle, Vocab, iter_leaves
from yarp_lite.bottle_text import format_bottle, format_value, parse
from yarp_lite.carriers import Payload
from yarp_lite.errors import RemoteProtocolError
from yarp_lite.bursts import Burst
from yarp_lite.nameserver.registry import PropertyLimit, Registry, RegistryFull
from yarp_lite.nameserver.subscriptions import Action, Subscriptions, split_name

log = logging.getLogger("yarp_lite.nameserver")

HELP = ["+ help", "+ list [$prefix]", "+ register $portname",
        "+ register $portname $carrier $ipAddress $portNumber",
        "  (if you want a field set automatically, write '...')",
        "+ unregister $portname", "+ query $portname", "+ set $portname $property $value",
        "+ get $portname $property", "+ check $portname $property",
        "+ route $port1 $port2", "+ runners", "  (to get a list of the yarprun ports)"]


class OldReply(Payload):
    """Lines of the classic name server answer, terminated by ``*** end of message``.

    Like yarpserver, these go out as raw text lines whatever the carrier.
    """

    def __init__(self, lines: Sequence[str]) -> None:
        self.lines = list(lines) + ["*** end of message"]

    def text(self) -> str:
        return "\r\n".join(self.lines)

    def binary(self) -> list:
        return [("".join(line + "\r\n" for line in self.lines)).encode("utf-8",
                                                                      "surrogateescape")]

    def bottle(self) -> Bottle:
        return Bottle([line for line in self.lines])


Reply = Union[OldReply, Bottle]


@dataclass
class Outcome:
    reply: Reply
    events: List[Bottle] = field(default_factory=list)
    actions: List[Action] = field(default_factory=list)


def _word(command: Sequence, index: int) -> str:
    """``cmd.get(i).asString()`` (non-strings read as empty)."""
    if index < len(command):
        value = command[index]
        if isinstance(value, str):
            return str(value)
    return ""


def _text(command: Sequence, index: int) -> str:
    """``cmd.get(i).toString()``."""
    if index < len(command):
        value = command[index]
        return str(value) if isinstance(value, str) else format_value(value)
    return ""


class NameService:
    def __init__(self, registry: Registry, subscriptions: Subscriptions,
                 server_host: str, server_port: int, silent: bool = False) -> None:
        self.registry = registry
        self.subscriptions = subscriptions
        self._refused_sets = Burst()
        self.server_host = server_host
        self.server_port = server_port
        self.silent = silent
        self._last_register = ""

    # -- lookup used by subscriptions -------------------------------------------------

    def carrier_of(self, name: str) -> Optional[str]:
        registration = self.registry.get(name)
        if registration is not None:
            return registration.carrier
        if self.subscriptions.is_topic(name):
            return "topic"
        return None

    # -- entry point ---------------------------------------------------------------------

    def apply(self, command: Bottle, remote_host: str = "") -> Outcome:
        _check_text(command)
        self._log(command)
        key = _word(command, 0)
        handler = _SUBSCRIBER_COMMANDS.get(key)
        if handler is not None:
            outcome = handler(self, command)
            if outcome is not None:
                return outcome
        bottle_mode = False
        if command.find("format") == "json":
            bottle_mode = True
        if key == "NAME_SERVER":
            command = Bottle(command[1:])
            key = _word(command, 0)
        if key == "bot":
            bottle_mode = True
            command = Bottle(command[1:])
            key = _word(command, 0)
        handler = _REGISTRY_COMMANDS.get(key)
        if handler is None:
            return Outcome(OldReply([]))
        return handler(self, command, bottle_mode, remote_host)

    def _log(self, command: Bottle) -> None:
        if self.silent:
            return
        key = _word(command, 0)
        prefix = " * "
        if key == "register":
            self._last_register = _word(command, 1)
        elif key == "set" and _word(command, 1) == self._last_register:
            prefix = "   + "
        else:
            self._last_register = ""
        log.info("%s%s", prefix, format_bottle(command))

    # -- subscriber commands ---------------------------------------------------------------

    def _subscribe(self, command: Bottle) -> Optional[Outcome]:
        src, dest, mode = _word(command, 1), _word(command, 2), _word(command, 3)
        if dest:
            actions = self.subscriptions.add(src, dest, mode, self.carrier_of)
            return Outcome(Bottle([Vocab("ok")]), actions=actions)
        return Outcome(self.subscriptions.listing(src))

    def _unsubscribe(self, command: Bottle) -> Optional[Outcome]:
        ok = self.subscriptions.remove(_word(command, 1), _word(command, 2))
        return Outcome(Bottle([Vocab("ok" if ok else "fail")]))

    def _announce(self, command: Bottle) -> Optional[Outcome]:
        activity = 1
        if len(command) > 2 and isinstance(command[2], int) and not isinstance(command[2], Vocab):
            activity = 1 if command[2] else 0
        actions = self.subscriptions.welcome(_word(command, 1), activity, self.carrier_of)
        return Outcome(Bottle([Vocab("ok")]), actions=actions)

    def _topic(self, command: Bottle) -> Optional[Outcome]:
        if len(command) >= 2:
            actions = self.subscriptions.set_topic(_word(command, 1), _word(command, 2), True,
                                                   self.carrier_of)
            return Outcome(Bottle([Vocab("ok")]), actions=actions)
        return Outcome(Bottle(self.subscriptions.topics()))

    def _untopic(self, command: Bottle) -> Optional[Outcome]:
        self.subscriptions.set_topic(_word(command, 1), "", False, self.carrier_of)
        return Outcome(Bottle([Vocab("ok")]))

    def _type(self, command: Bottle) -> Optional[Outcome]:
        if len(command) == 4:
            ok = self.subscriptions.set_type(_word(command, 1), _word(command, 2),
                                             _word(command, 3))
            return Outcome(Bottle([Vocab("ok" if ok else "fail")]))
        if len(command) == 3:
            result = self.subscriptions.get_type(_word(command, 1), _word(command, 2))
            if not result:
                return Outcome(Bottle([Vocab("fail")]))
            return Outcome(Bottle([_word(command, 0), _word(command, 1), _word(command, 2),
                                   result]))
        return Outcome(Bottle([Vocab("fail")]))

    # -- registry commands -------------------------------------------------------------------

    def _query_entry(self, name: str, bottle_mode: bool) -> Optional[Bottle]:
        carrier, plain = split_name(name)
        network = ""
        if plain.startswith(("/net=", "/NET=")):
            end = plain.find("/", 5)
            if end >= 5:
                network, plain = plain[5:end], plain[end:]
        registration = self.registry.get(plain)
        if registration is None:
            if bottle_mode:
                return Bottle(["port", Bottle(["error", -2, "port not known"])])
            return None
        host = registration.host
        if network:
            for ip in self.registry.property(plain, "ips"):
                if ip.startswith(network):
                    host = ip
                    break
        if bottle_mode:
            return Bottle(["port", Bottle(["name", plain]), Bottle(["ip", host]),
                           Bottle(["port_number", registration.port]),
                           Bottle(["carrier", registration.carrier])])
        return Bottle(["registration", "name", plain, "ip", host, "port", registration.port,
                       "type", registration.carrier])

    def _query(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        entry = self._query_entry(_word(command, 1), bottle_mode)
        if bottle_mode:
            return Outcome(entry if entry is not None else Bottle())
        return Outcome(OldReply([_old_line(entry)] if entry is not None else []))

    def _register(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        name = _word(command, 1)
        outcome = Outcome(OldReply([]))
        if self.registry.get(name) is not None:
            outcome = self._unregister(Bottle(["unregister", name]), False, remote)
        carrier = _word(command, 2) or "..."
        if len(command) <= 2:
            carrier = "..."
        if carrier == "...":
            carrier = "tcp"
        machine = _word(command, 3) if len(command) > 3 else "..."
        if machine in ("...", ""):
            if carrier == "topic":
                machine = self.server_host
            elif carrier != "mcast":
                machine = remote if remote and remote != "..." else "localhost"
        port = -1
        if len(command) > 4:
            value = command[4]
            port = int(value) if isinstance(value, int) and not isinstance(value, Vocab) else 0
        elif carrier == "topic":
            port = self.server_port
        type_name = _word(command, 5) if len(command) > 5 else "*"
        try:
            registration = self.registry.register(name, carrier, machine, port, type_name)
        except RegistryFull as exc:
            log.error("cannot register %s: %s", name, exc)
            return Outcome(OldReply([]))
        events = outcome.events
        if carrier != "mcast":
            events.append(Bottle([Vocab("add"), registration.name]))
        entry = self._query_entry(registration.name, bottle_mode)
        reply: Reply = entry if bottle_mode and entry is not None else \
            OldReply([_old_line(entry)] if entry is not None else [])
        return Outcome(reply, events=events, actions=outcome.actions)

    def _unregister(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        name = _word(command, 1)
        actions = self.subscriptions.welcome(name, -1, self.carrier_of)
        removed = self.registry.unregister(name)
        events = []
        if removed is not None and removed.carrier != "mcast":
            events.append(Bottle([Vocab("del"), name]))
        return Outcome(OldReply([]), events=events, actions=actions)

    def _list(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        prefix = _word(command, 1)
        entries = []
        for name in self.registry.names():
            if prefix and not (name.startswith(prefix) and (
                    name == prefix or name[len(prefix):len(prefix) + 1] == "/"
                    or prefix.endswith("/"))):
                continue
            entry = self._query_entry(name, bottle_mode)
            if entry is not None:
                entries.append(entry)
        if bottle_mode:
            return Outcome(Bottle(["ports", *entries]))
        return Outcome(OldReply([_old_line(entry) for entry in entries]))

    def _runners(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        entries = [self._query_entry(name, bottle_mode) for name in self.registry.names()
                   if "true" in self.registry.property(name, "yarprun")]
        if bottle_mode:
            return Outcome(Bottle(["ports", *[e for e in entries if e is not None]]))
        return Outcome(OldReply([_old_line(e) for e in entries if e is not None]))

    def _set(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        name, key = _word(command, 1), _text(command, 2)
        values = [_text(command, index) for index in range(3, len(command))]
        try:
            stored = self.registry.set_property(name, key, values)
        except PropertyLimit as exc:
            if self._refused_sets.record():
                log.warning("refused set %s %s from %s: %s (%d refused in this burst)",
                            name, key, remote, exc, self._refused_sets.count)
            stored = False
        if not stored:
            return Outcome(Bottle() if bottle_mode else OldReply([]))
        return self._get(Bottle(["get", name, key]), bottle_mode, remote)

    def _get(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        name, key = _word(command, 1), _text(command, 2)
        if self.registry.get(name) is None:
            return Outcome(Bottle() if bottle_mode else OldReply([]))
        values = self.registry.property(name, key)
        if bottle_mode:
            result = Bottle()
            for value in values:
                parsed = parse(value)
                result.append(parsed[0] if len(parsed) == 1 else value)
            return Outcome(result)
        return Outcome(OldReply([" ".join(["port", name, "property", key, "=", *values])]))

    def _check(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        name, key, value = _word(command, 1), _text(command, 2), _text(command, 3)
        if self.registry.get(name) is None:
            return Outcome(OldReply([]))
        present = "true" if value in self.registry.property(name, key) else "false"
        return Outcome(OldReply([" ".join(["port", name, "property", key, "value", value,
                                           "present", present])]))

    def _route(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        first, second = _word(command, 1), _word(command, 2)
        return Outcome(OldReply([f"port {first} route {second} = tcp:/{second}"]))

    def _gc(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        return Outcome(OldReply(["garbage collection done."]))

    def _help(self, command: Bottle, bottle_mode: bool, remote: str) -> Outcome:
        if bottle_mode:
            return Outcome(Bottle(HELP))
        return Outcome(OldReply(["Here are some ways to use the name server:", *HELP]))


def _check_text(command: Bottle) -> None:
    """Refuse text SQLite cannot store: lone surrogates from a peer's non-UTF-8 bytes."""
    for leaf in iter_leaves(command):
        if isinstance(leaf, str):
            try:
                leaf.encode("utf-8")
            except UnicodeEncodeError:
                raise RemoteProtocolError(f"command text {leaf[:40]!r} is not UTF-8",
                                          "name server") from None


def _old_line(entry: Optional[Bottle]) -> str:
    """A registration as one "old" line: the Bottle's text without quotes."""
    return format_bottle(entry or []).replace('"', "")


_SUBSCRIBER_COMMANDS = {
    "subscribe": NameService._subscribe, "unsubscribe": NameService._unsubscribe,
    "announce": NameService._announce, "topic": NameService._topic,
    "untopic": NameService._untopic, "type": NameService._type,
}
_REGISTRY_COMMANDS = {
    "register": NameService._register, "unregister": NameService._unregister,
    "query": NameService._query, "list": NameService._list, "runners": NameService._runners,
    "set": NameService._set, "get": NameService._get, "check": NameService._check,
    "route": NameService._route, "gc": NameService._gc, "help": NameService._help,
}
