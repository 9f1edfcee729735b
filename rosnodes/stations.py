"""Pilot stations: several pilot gateways on one pilot YARP name server, told apart.

Theory of operation
-------------------
The DRC had three pilot PCs, each with a roscore and a gateway, all on the
pilot YARP name server.  Every gateway numbers the commands it sends, and a
GYM module drops a number it has already run (a resend).  Millisecond stamps
alone collide when two pilots click in the same millisecond, so each gateway
claims a *station* number ``1..MAX_STATIONS`` on the name server -- the first
``/pilot_gateway/<n>/sent:o`` that is free or whose owner no longer answers --
and its sequence numbers are ``stamp * STATION_SPAN + station``: two stations
never issue the same one, and each station's stamps strictly increase.

A claim is checked again a moment after the port is registered: if another
gateway registered the same name meanwhile (both saw it free), the one whose
registration did not survive moves to the next number.

The ``sent:o`` port also carries what the station sent (``station sender module
port text seq``), so every gateway republishes the others' commands on its own
``/pilot/sent_commands``: each pilot's log shows every command and who sent it.
"""

from __future__ import annotations

import random
import socket
import threading
import time
from typing import Callable, Optional, Tuple

from yarp_lite.contact import Contact
from yarp_lite.errors import YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

#: Sequence numbers are ``stamp * STATION_SPAN + station`` (int32: stamps wrap every 37 h).
STATION_SPAN = 16
MAX_STATIONS = STATION_SPAN - 1
_STAMP_MODULO = (1 << 31) // STATION_SPAN


class StationError(Exception):
    """No station number is free on the pilot name server."""


def sent_port_name(station: int) -> str:
    return f"/pilot_gateway/{station}/sent:o"


class SequenceNumbers:
    """This station's sequence numbers: unique across stations, increasing within one."""

    def __init__(self, station: int, clock: Callable[[], float] = time.time) -> None:
        if not 1 <= station <= MAX_STATIONS:
            raise ValueError(f"station {station} is outside 1..{MAX_STATIONS}")
        self.station = station
        self._clock = clock
        self._stamp = 0
        self._lock = threading.Lock()

    def next(self) -> int:
        with self._lock:
            stamp = int(self._clock() * 1000) % _STAMP_MODULO
            self._stamp = stamp if stamp > self._stamp else self._stamp + 1
            if self._stamp >= _STAMP_MODULO:   # the clock wrapped: start the cycle again
                self._stamp = 1
            return self._stamp * STATION_SPAN + self.station


def station_of(seq: int) -> int:
    return seq % STATION_SPAN


def _answers(contact: Contact) -> bool:
    try:
        socket.create_connection((contact.host, contact.port), timeout=1.0).close()
    except OSError:
        return False
    return True


def claim_station(nameclient: NameClient, open_port: Callable[[str], Port],
                  settle: Tuple[float, float] = (0.1, 0.3)) -> Tuple[int, Port]:
    """The first free station number and its open ``sent:o`` port."""
    for station in range(1, MAX_STATIONS + 1):
        name = sent_port_name(station)
        try:
            owner = nameclient.query(name)
        except YarpError:
            owner = None
        if owner is not None and _answers(owner):
            continue
        port = open_port(name)
        time.sleep(random.uniform(*settle))   # let a gateway starting with us register too
        registered = nameclient.query(name)
        if registered is not None and registered.port == port.address.port and \
                registered.host == port.address.host:
            return station, port
        port.close()                          # someone else's registration survived
    raise StationError(f"all {MAX_STATIONS} pilot stations on the name server are taken "
                       f"(/pilot_gateway/1..{MAX_STATIONS}/sent:o answer)")


def sent_bottle_fields(station: int, sender: str, module: str, port: str, text: str,
                       seq: int) -> list:
    return [station, sender, module, port, text, seq]


def parse_sent(bottle) -> Optional[Tuple[int, str, str, str, str, int]]:
    """A ``sent:o`` Bottle as its fields, or None when it is not one."""
    if len(bottle) != 6 or not all(isinstance(bottle[i], int) for i in (0, 5)):
        return None
    station, sender, module, port, text, seq = (bottle[i] for i in range(6))
    return int(station), str(sender), str(module), str(port), str(text), int(seq)
