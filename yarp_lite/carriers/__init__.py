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


def make_carrier(name: str) -> Carrier:
    """A fresh carrier for one connection; unknown names are a local error."""
    base = carrier_base_name(name or "tcp")
    cls = CARRIERS.get(base)
    if cls is None:
        raise LocalProtocolError(
            f"unknown carrier {base!r}; yarp_lite supports {', '.join(SUPPORTED)}")
    if base != name:
        raise LocalProtocolError(f"carrier modifiers are not supported: {name!r}")
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
           "carrier_base_name", "BottlePayload", "RawPayload", "Payload", "Incoming",
           "MessageSource", "DatagramStream", "PROTOCOL_NOT_FOUND"]
