"""What a port answers when spoken to directly: port commands and the admin protocol.

Two interfaces reach the port itself rather than its owner:

* port commands (``doc/yarp_protocol.dox``): ``/dest`` (connect to dest),
  ``!/dest`` (drop that output), ``~/src`` (drop that input), ``*`` (describe),
  ``?`` (help), ``q`` (close this connection).  On text connections they
  answer in English lines; on binary ones silently.
* the admin protocol (``doc/port_admin.dox``, ``PortCore::adminBlock``): a
  Bottle such as ``[list] [out]`` or ``[add] /dest tcp`` answered with a
  Bottle.  This is what ``yarp connect``/``yarp disconnect`` and ``yarp admin
  rpc`` use.

This module decides the answers; :mod:`yarp_lite.port` performs the effects
through the small :class:`PortState` interface, so the rules are testable
without a network.  Answers reproduce YARP 3.5's text byte for byte.

Both take whatever a peer sent: :func:`admin` answers any Bottle and
:func:`port_command` any text (unknown commands get YARP's "not understood"
answers), never raising; the Bottle or line was already bounded by the
decoder that produced it.  What a peer may store in a port (``[prop] [set]``)
is bounded too: :data:`MAX_PROPERTY_BYTES` per port.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Protocol, Sequence, Tuple

from yarp_lite.bottle import Bottle, Dict as DictValue, Vocab, encode
from yarp_lite.contact import Contact


#: Encoded bytes of the properties one port keeps from ``[prop] [set]``; more is refused.
MAX_PROPERTY_BYTES = 64 * 1024


@dataclass(frozen=True)
class Route:
    """One connection as the port sees it."""

    source: str
    target: str
    carrier: str
    connectionless: bool = False


class PortState(Protocol):
    """What the admin logic needs from a live port."""

    name: str

    def address(self) -> Contact: ...

    def input_routes(self) -> List[Route]: ...

    def output_routes(self) -> List[Route]: ...

    def add_output(self, target: str) -> Tuple[bool, str]: ...

    def remove_output(self, target: str) -> bool: ...

    def remove_input(self, source: str) -> bool: ...

    def properties(self) -> Dict[str, object]: ...

    def admin_fallback(self, command: Bottle) -> Optional[Bottle]: ...


# --------------------------------------------------------------------------
# Port commands


HELP_LINES = [
    "This is a YARP port.  Here are the commands it responds to:",
    "*       Gives a description of this port",
    "d       Signals the beginning of input for the port's owner",
    'do      The same as "d" except replies should be suppressed ("data-only")',
    "q       Disconnects",
    "r       Reverse connection type to be a reader",
    "/port   Requests to send output to /port",
    "!/port  Requests to stop sending output to /port",
    "~/port  Requests to stop receiving input from /port",
    "a       Signals the beginning of an administrative message",
    "?       Gives this help",
]

NOT_UNDERSTOOD = [
    "Port command not understood.",
    "Type d to send data to the port's owner.",
    "Type ? for help.",
]


def describe(port: PortState) -> List[str]:
    """Answer to ``*`` (``PortCore::describe``)."""
    address = port.address()
    lines = [f"This is {port.name} at {address.uri()}"]
    outputs = port.output_routes()
    for route in outputs:
        lines.append(f"There is an output connection from {route.source} to {route.target} "
                     f"using {route.carrier}")
    if not outputs:
        lines.append("There are no outgoing connections")
    inputs = [route for route in port.input_routes() if route.carrier]
    for route in inputs:
        lines.append(f"There is an input connection from {route.source} to {route.target} "
                     f"using {route.carrier}")
    if not inputs:
        lines.append("There are no incoming connections")
    return lines


def add_output_text(port: PortState, target: str) -> Tuple[bool, str]:
    ok, message = port.add_output(target)
    return ok, message


def remove_output_text(port: PortState, target: str) -> str:
    if port.remove_output(target):
        return f"Removed connection from {port.name} to {target}"
    return f"Could not find an outgoing connection to {target}"


def remove_input_text(port: PortState, source: str) -> str:
    if port.remove_input(source):
        return f"Removing connection from {source} to {port.name}"
    return f"Could not find an incoming connection from {source}"


def port_command(port: PortState, text: str) -> List[str]:
    """Perform a port command; return the lines a text connection should see."""
    key = text[:1]
    if key == "/":
        return [add_output_text(port, text)[1]]
    if key == "!":
        return [remove_output_text(port, text[1:])]
    if key == "~":
        return [remove_input_text(port, text[1:])]
    if key == "*":
        return describe(port)
    if key in ("?", "h"):
        return list(HELP_LINES)
    return list(NOT_UNDERSTOOD)


# --------------------------------------------------------------------------
# Admin protocol


ADMIN_HELP = [
    "[help]                  # give this help",
    "[ver]                   # report protocol version information",
    "[add] $portname         # add an output connection",
    "[add] $portname $car    # add an output with a given protocol",
    "[del] $portname         # remove an input or output connection",
    "[list] [in]             # list input connections",
    "[list] [out]            # list output connections",
    "[list] [in]  $portname  # give details for input",
    "[list] [out] $portname  # give details for output",
    "[prop] [get]            # get all user-defined port properties",
    "[prop] [get] $prop      # get a user-defined port property (prop, val)",
    "[prop] [set] $prop $val # set a user-defined port property (prop, val)",
    "[prop] [get] $portname  # get Qos properties of a connection to/from a port",
    "[prop] [set] $portname  # set Qos properties of a connection to/from a port",
    "[prop] [get] $cur_port  # get information about current process (e.g., scheduling priority, pid)",
    "[prop] [set] $cur_port  # set properties of the current process (e.g., scheduling priority, pid)",
    "[atch] [out] $prop      # attach a portmonitor plug-in to the port's output",
    "[atch] [in]  $prop      # attach a portmonitor plug-in to the port's input",
    "[dtch] [out]            # detach portmonitor plug-in from the port's output",
    "[dtch] [in]             # detach portmonitor plug-in from the port's input",
]

_KNOWN = ("help", "ver", "pray", "add", "del", "atch", "dtch", "list", "set", "get", "prop")


def _command_name(value: object) -> str:
    if isinstance(value, Vocab):
        return str(value)
    if isinstance(value, str):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        code = (int(value) + (1 << 31)) % (1 << 32) - (1 << 31)  # asVocab32 truncates int64
        return str(Vocab(code))
    return ""


def _word(command: Sequence, index: int) -> str:
    """``cmd.get(i).asString()``: strings only, anything else reads as empty."""
    if index < len(command):
        value = command[index]
        if isinstance(value, str) and not isinstance(value, Vocab):
            return value
    return ""


def _direction(command: Sequence, index: int) -> str:
    """``[in]``/``[out]``, anything else meaning out (``parseConnectionDirection``)."""
    if index < len(command) and _command_name(command[index]) == "in":
        return "in"
    return "out"


def _describe_route(route: Route) -> Bottle:
    result = Bottle([Bottle(["from", route.source]), Bottle(["to", route.target]),
                     Bottle(["carrier", route.carrier])])
    if route.connectionless:
        result.append(Bottle(["connectionless", 1]))
    return result


def admin(port: PortState, command: Bottle) -> Bottle:
    """Answer one admin Bottle as ``PortCore::adminBlock`` does."""
    name = _command_name(command[0]) if command else ""
    if name not in _KNOWN:
        fallback = port.admin_fallback(command)
        if fallback is not None:
            return fallback
        return Bottle([Vocab("fail"), "send [help] for list of valid commands"])
    if name == "help":
        return Bottle([Vocab("many"), *ADMIN_HELP])
    if name == "ver":
        return Bottle([Vocab("ver"), 1, 2, 3])
    if name == "pray":
        return Bottle([f"You begin praying to {port.name.strip('/').split('/')[0]}.",
                       "You finish your prayer.",
                       f"You feel that {port.name.strip('/').split('/')[0]} is well-pleased."])
    if name == "add":
        target = _word(command, 1)
        carrier = _word(command, 2)
        if carrier:
            target = f"{carrier}:/{target}"
        ok, message = port.add_output(target)
        return Bottle([0 if ok else -1, message + "\r\n"])
    if name == "del":
        target = _word(command, 1)
        removed_out = port.remove_output(target)
        out_text = (f"Removed connection from {port.name} to {target}\r\n" if removed_out
                    else f"Could not find an outgoing connection to {target}\r\n")
        removed_in = port.remove_input(target)
        in_text = (f"Removing connection from {target} to {port.name}\r\n" if removed_in
                   else f"Could not find an incoming connection from {target}\r\n")
        ok = removed_out or removed_in
        if removed_out and not removed_in:
            text = out_text
        elif removed_in and not removed_out:
            text = in_text
        else:
            text = out_text + in_text
        return Bottle([0 if ok else -1, text])
    if name == "list":
        return _list(port, _direction(command, 1), _word(command, 2))
    if name in ("atch", "dtch"):
        return Bottle([Vocab("fail"), "port monitors are not supported by yarp_lite"])
    if name in ("set", "get"):
        target = _word(command, 2)
        if not target:
            return Bottle([-1, "target port is not specified.\r\n"])
        routes = port.input_routes() if _direction(command, 1) == "in" else \
            port.output_routes()
        match = [r for r in routes if (r.source if _direction(command, 1) == "in"
                                       else r.target) == target]
        if not match:
            kind = "from" if _direction(command, 1) == "in" else "to"
            return Bottle([-1, f"Could not find an incoming connection {kind} {target}\r\n"])
        if name == "get":
            return Bottle([DictValue()])
        return Bottle([0, f"Configured connection {'from' if _direction(command, 1) == 'in' else 'to'} {target}\r\n"])
    return _prop(port, command)


def _list(port: PortState, direction: str, target: str) -> Bottle:
    result = Bottle()
    if direction == "in":
        for route in port.input_routes():
            if not target:
                if route.source:
                    result.append(route.source)
            elif route.source == target:
                result.extend(_describe_route(route))
    else:
        for route in port.output_routes():
            if not target:
                result.append(route.target)
            elif route.target == target:
                result.extend(_describe_route(route))
    return result


def _prop(port: PortState, command: Bottle) -> Bottle:
    action = _command_name(command[1]) if len(command) > 1 else ""
    properties = port.properties()
    key = _word(command, 2)
    if action == "get":
        if not key:
            return Bottle([Bottle([k, v]) for k, v in properties.items()])
        if key.startswith("/"):
            return Bottle([Vocab("fail"), f"cannot find any connection to/from {key}"]) \
                if key != port.name else _port_info(port)
        value = properties.get(key)
        return Bottle([] if value is None else [value])
    if action == "set":
        if len(command) > 3:
            kept = {k: v for k, v in properties.items() if k != key}
            size = len(encode(Bottle([Bottle([k, v]) for k, v in kept.items()]
                                     + [Bottle([key, command[3]])])))
            if size > MAX_PROPERTY_BYTES:
                return Bottle([Vocab("fail"), f"properties would take {size} bytes "
                                              f"(limit {MAX_PROPERTY_BYTES})"])
            properties[key] = command[3]
        return Bottle([Vocab("ok")])
    return Bottle([Vocab("fail"), "property action not known"])


def _port_info(port: PortState) -> Bottle:
    import os

    return Bottle([
        Bottle(["process", DictValue.from_mapping({"pid": os.getpid(), "name": "python3"})]),
        Bottle(["platform", DictValue.from_mapping({"os": "Linux",
                                                    "hostname": port.address().host})]),
    ])
