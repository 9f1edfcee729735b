"""Contacts (where a port lives) and YARP's port-name rules.

``Contact.parse`` follows ``Contact::fromString``: ``tcp://read`` names the
port ``/read`` reached with the tcp carrier, ``/read`` has no carrier
preference, and ``tcp://10.0.0.1:10002/`` is a raw socket address.  Port
names must start with ``/``, must not end with ``/`` and contain no spaces
(``NetworkBase::isValidPortName``).  Names given to ports are adjusted by
``YARP_RENAME_<safe name>`` and ``YARP_PORT_PREFIX`` exactly as YARP does, so
launch scripts written for YARP work unchanged.

``Contact.parse`` reads names and addresses that peers and the name server
send, so it is total: any text gives a Contact.  A socket number is at most
five ASCII digits; anything else after ``host:`` makes the text a name.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from typing import Mapping, Optional

from yarp_lite.errors import LocalProtocolError


@dataclass(frozen=True)
class Contact:
    """A port's registration: name, carrier, host and socket number."""

    name: str = ""
    carrier: str = ""
    host: str = ""
    port: int = -1

    @property
    def valid(self) -> bool:
        """True when the contact holds a socket address (``Contact::isValid``)."""
        return self.port >= 0

    @classmethod
    def parse(cls, text: str) -> "Contact":
        """``Contact::fromString``: ``[carrier:/]/name`` or ``carrier://host:port/``."""
        base = text.find("://")
        offset = 2
        if base < 0:
            base = text.find(":/")
            offset = 1
        if base < 0 and text.startswith("/"):
            base, offset = 0, 0
        carrier, host, port, start = "", "", -1, 0
        if base >= 0:
            carrier = text[:base]
            start = base + offset
            colon, mode, digits, index = -1, 0, 0, start + 1
            while index < len(text):
                ch = text[index]
                if ch == ":":
                    if mode == 0:
                        colon, mode = index, 1
                        index += 1
                        continue
                    mode = -1
                    break
                if ch == "/":
                    break
                if mode == 1:
                    if ch in "0123456789" and digits < 5:  # ASCII only; atoi's range
                        digits += 1
                        index += 1
                        continue
                    mode = -1
                    break
                index += 1
            if mode == 1 and digits >= 1:
                carrier = carrier or "tcp"
                host = text[start + 1:colon]
                port = int(text[colon + 1:colon + 1 + digits])
                start = index
        name = text[start:]
        return cls(name="" if name == "/" else name, carrier=carrier, host=host, port=port)

    def with_carrier(self, carrier: str) -> "Contact":
        return replace(self, carrier=carrier)

    def __str__(self) -> str:
        """``Contact::toString``: ``carrier:/`` + name, as YARP writes ``[add] tcp://r``."""
        return f"{self.carrier}:/{self.name}" if self.carrier else self.name

    def uri(self, with_carrier: bool = True) -> str:
        """``Contact::toURI``: ``tcp://10.0.0.1:10002/``."""
        head = f"{self.carrier}:/" if with_carrier and self.carrier else ""
        return f"{head}/{self.host}:{self.port}/" if self.host and self.port >= 0 else head


def is_valid_port_name(name: str) -> bool:
    """``NetworkBase::isValidPortName``."""
    if name == "...":
        return True
    return bool(name) and name.startswith("/") and not name.endswith("/") and " " not in name


def check_port_name(name: str) -> str:
    """Return ``name`` or raise a :class:`LocalProtocolError` saying what is wrong."""
    if is_valid_port_name(name):
        return name
    if not name:
        problem = "it is empty"
    elif not name.startswith("/"):
        problem = "it must start with '/'"
    elif name.endswith("/"):
        problem = "it must not end with '/'"
    else:
        problem = "it must not contain spaces"
    raise LocalProtocolError(f"invalid port name {name!r}: {problem}")


def safe_name(text: str) -> str:
    """``NameConfig::getSafeString``: every non-alphanumeric character becomes ``_``."""
    return re.sub(r"[^0-9A-Za-z]", "_", text)


def apply_environment(name: str, environ: Optional[Mapping[str, str]] = None) -> str:
    """The name a port really opens under: ``YARP_RENAME_*`` then ``YARP_PORT_PREFIX``."""
    env = os.environ if environ is None else environ
    renamed = env.get("YARP_RENAME" + safe_name(name), "")
    if renamed:
        name = renamed
    if name and name != "..." and not name.startswith("=") and not name.startswith("..."):
        prefix = env.get("YARP_PORT_PREFIX", "")
        if prefix:
            name = prefix + name
    return name
