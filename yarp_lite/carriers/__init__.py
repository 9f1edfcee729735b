"""Carriers, chosen by name (``tcp``, ``udp://read``) or by a connection's first 8 bytes.

=========== ============================ ====== ======= ========
carrier     magic                        acks   replies  mode
=========== ============================ ====== ======= ========
tcp         ``YA e4 1e 00 00 RP``        yes    yes     binary
fast_tcp    ``YA 64 1e 00 00 RP``        no     yes     binary
udp         ``YA 61 1e 00 00 RP``        no     no      datagrams
text        ``CONNECT ``                 no     no      text
text_ack    ``CONNACK ``                 yes    yes     text
name_ser    ``NAME_SER``                 no     yes     text, name server only
=========== ============================ ====== ======= ========

One modifier is understood, as YARP writes modifiers (``carrier+key.value``):
``+period.S`` asks the writer for about one message every ``S`` seconds on this connection
(see :func:`send_period`); any other modifier is refused by name.
"""

from __future__ import annotations

from typing import Dict, Optional, Type

from yarp_lite.carriers.base import (BottlePayload, Carrier, Incoming, MessageSource, Payload,
                                     RawPayload)
from yarp_lite.carriers.name_ser import NameSerCarrier
from yarp_lite.carriers.tcp import FastTcpCarrier, TcpCarrier
from yarp_lite.carriers.text import TextAckCarrier, TextCarrier
from yarp_lite.carriers.udp import DatagramStream, UdpCarrier
from yarp_lite.errors import LocalProtocolError
from yarp_lite.framing import parse_yarp_number

CARRIERS: Dict[str, Type[Carrier]] = {
    cls.name: cls for cls in (TcpCarrier, FastTcpCarrier, UdpCarrier, TextCarrier,
                              TextAckCarrier, NameSerCarrier)
}
#: Carriers a yarp_lite port accepts and offers (what it tells the name server).
SUPPORTED = ("tcp", "fast_tcp", "udp", "text", "text_ack", "name_ser")
_SPECIFIER_BASE = 7777


def carrier_base_name(name: str) -> str:
    """``tcp+send.portmonitor`` -> ``tcp``: the carrier without its modifiers."""
    return name.split("+", 1)[0]


#: Longest ``+period.S`` a reader may ask for (s): a stream slower than this is a mistake.
MAX_SEND_PERIOD = 3600.0


def send_period(name: str) -> float:
    """``fast_tcp+period.0.004`` -> 0.004: how often the reader of a stream wants a message
    (0: every one).  A writer's streams where only the newest matters (``skip_busy``) send
    such a connection about one message per period and skip the rest, so a 10 Hz reader of a
    500 Hz robot state costs the writer 10 sends a second, not 500 (on 2 cores the robot's
    own process spent most of a core sending states its readers dropped unread).  Other
    modifiers, and a period that is not a positive number of seconds, are local errors."""
    period = 0.0
    for modifier in (name or "").split("+")[1:]:
        key, _, value = modifier.partition(".")
        if key != "period":
            raise LocalProtocolError(f"carrier {name!r}: unknown modifier {modifier!r} "
                                     f"(yarp_lite understands only +period.SECONDS)")
        try:
            period = float(value)
        except ValueError:
            period = -1.0
        if not 0.0 < period <= MAX_SEND_PERIOD:
            raise LocalProtocolError(f"carrier {name!r}: +period wants seconds in "
                                     f"(0, {MAX_SEND_PERIOD:g}], got {value!r}")
    return period


def with_send_period(carrier: str, seconds: float) -> str:
    """``carrier`` asking for one message every ``seconds`` (unchanged for 0: every one)."""
    return f"{carrier}+period.{seconds:g}" if seconds > 0 else carrier


def make_carrier(name: str) -> Carrier:
    """A fresh carrier for one connection; unknown names and modifiers are local errors."""
    base = carrier_base_name(name or "tcp")
    cls = CARRIERS.get(base)
    if cls is None:
        raise LocalProtocolError(
            f"unknown carrier {base!r}; yarp_lite supports {', '.join(SUPPORTED)}")
    send_period(name)
    return cls()


def carrier_for_header(header: bytes) -> Optional[Carrier]:
    """The carrier a connection's first 8 bytes announce, or None if unknown."""
    for cls in (TextCarrier, TextAckCarrier, NameSerCarrier):
        if header == cls.header:
            return cls()
    number = parse_yarp_number(header)
    if number is None or number < _SPECIFIER_BASE:
        return None
    specifier = number - _SPECIFIER_BASE
    kind = specifier % 16
    if kind == 3:
        return TcpCarrier() if specifier & 128 else FastTcpCarrier()
    if kind == 0:
        return UdpCarrier()
    return None


#: YARP's answer to a connection that starts with unknown bytes.
PROTOCOL_NOT_FOUND = (
    b"* Error. Protocol not found.\r\n"
    b"* Hello. You appear to be trying to communicate with a YARP Port.\r\n"
    b"* The first 8 bytes sent to a YARP Port are critical for identifying the\r\n"
    b"* protocol you wish to speak.\r\n"
    b"* The first 8 bytes you sent were not associated with any particular protocol.\r\n"
    b"* If you are a human, try typing \"CONNECT foo\" followed by a <RETURN>.\r\n"
    b"* The 8 bytes \"CONNECT \" correspond to a simple text-mode protocol.\r\n"
    b"* Goodbye.\r\n")

__all__ = ["Carrier", "CARRIERS", "SUPPORTED", "make_carrier", "carrier_for_header",
           "carrier_base_name", "send_period", "with_send_period", "BottlePayload", "RawPayload", "Payload", "Incoming",
           "MessageSource", "DatagramStream", "PROTOCOL_NOT_FOUND"]
