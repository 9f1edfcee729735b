"""The ``tcp`` carrier (acknowledged) and ``fast_tcp`` (the same, unacknowledged).

Magic ``YA e4 1e 00 00 RP`` (tcp) or ``YA 64 1e 00 00 RP`` (fast_tcp); the
receiver answers the header with its socket number and every message is
index + payload; tcp's receiver acknowledges each message with ``YA 0 RP``.
"""

from __future__ import annotations

from yarp_lite.carriers.binary import BinaryCarrier, read_binary_ack
from yarp_lite.framing import ACK, yarp_number
from yarp_lite.stream import Stream

_SPECIFIER_BASE = 7777
TCP_CODE = 3


class TcpCarrier(BinaryCarrier):
    name = "tcp"
    header = yarp_number(_SPECIFIER_BASE + TCP_CODE + 128)
    requires_ack = True

    def read_ack(self, stream: Stream) -> None:
        read_binary_ack(stream)

    def ack_chunk(self) -> bytes:
        return ACK


class FastTcpCarrier(BinaryCarrier):
    name = "fast_tcp"
    header = yarp_number(_SPECIFIER_BASE + TCP_CODE)
