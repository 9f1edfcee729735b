"""The udp carrier's receiving side: what a broken message costs, and who hears about it.

Real datagram sockets on loopback, no port and no name server: the sender's
bytes go straight into a :class:`DatagramMessageSource`.
"""

from __future__ import annotations

import logging
import socket
from typing import Iterator, List

import pytest

from yarp_lite.bottle import Bottle, decode, encode
from yarp_lite.carriers.datagram import pack_message
from yarp_lite.carriers.udp import DatagramMessageSource, DatagramStream, InputCounters
from yarp_lite.framing import encode_message

SENDER = "/robot/state:o"


def data_message(values: list) -> bytes:
    """Index and payload of one data message, as a udp sender cuts into datagrams."""
    return b"".join(encode_message("D", [encode(Bottle(values))]))


@pytest.fixture
def link() -> Iterator["Link"]:
    receiver = DatagramStream.bind("127.0.0.1", SENDER)
    receiver.sock.settimeout(5)  # a missing datagram fails the test instead of hanging it
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield Link(receiver, sender)
    sender.close()
    receiver.close()


class Link:
    def __init__(self, receiver: DatagramStream, sender: socket.socket) -> None:
        self.receiver, self.sender = receiver, sender
        self.source = DatagramMessageSource(receiver, receiver.where, 1 << 20)

    def send_message(self, body: bytes) -> None:
        """One message, cut into datagrams as a udp sender does."""
        for datagram in pack_message([body]):
            self.sender.sendto(datagram, self.receiver.local_address)

    def send_bottle(self, values: list) -> None:
        self.send_message(data_message(values))

    def receive(self) -> Bottle:
        return decode(self.source.next().binary)


def udp_warnings(caplog) -> List[logging.LogRecord]:
    return [r for r in caplog.records if r.name == "yarp_lite.carriers.udp"]


def test_a_malformed_message_costs_itself_is_counted_and_names_its_sender(link, caplog):
    link.send_bottle(["first"])
    link.send_message(b"YA\x0b\x00\x00\x00RP" + bytes(20))  # index header announcing 11 bytes
    link.send_bottle(["after"])
    assert link.receive() == ["first"]
    assert link.receive() == ["after"]
    assert link.source.counters == InputCounters(messages=2, malformed=1)
    [record] = udp_warnings(caplog)
    text = record.getMessage()
    assert record.levelno == logging.WARNING
    assert SENDER in text and "index header announces 11 bytes" in text
    assert f"datagram from 127.0.0.1:{link.sender.getsockname()[1]}" in text


def test_a_burst_of_malformed_messages_is_logged_at_1_10_100(link, caplog):
    for _ in range(120):
        link.send_message(b"garbage, not an index" + bytes(10))
    link.send_bottle(["survivor"])
    assert link.receive() == ["survivor"]
    assert link.source.malformed == 120
    lines = [r.getMessage() for r in udp_warnings(caplog)]
    assert [line.split("dropped, ")[1].split(" in this burst")[0] for line in lines] == \
        ["1", "10", "100"]


def test_a_bug_in_decoding_is_logged_with_its_traceback_counted_and_survived(link, caplog,
                                                                            monkeypatch):
    real = link.source.decoder.next_message
    calls = []

    def broken_once():
        calls.append(1)
        if len(calls) == 1:
            raise ZeroDivisionError("a bug, not the peer's fault")
        return real()

    monkeypatch.setattr(link.source.decoder, "next_message", broken_once)
    link.send_bottle(["lost to the bug"])
    link.send_bottle(["next"])
    assert link.receive() == ["next"]
    assert link.source.counters == InputCounters(messages=1, failures=1)
    [record] = udp_warnings(caplog)
    assert record.levelno == logging.ERROR and SENDER in record.getMessage()
    assert record.exc_info is not None and record.exc_info[0] is ZeroDivisionError


def test_lost_and_corrupt_datagrams_are_counted_as_dropped(link):
    datagrams = pack_message([data_message(["x" * 100_000])])
    assert len(datagrams) == 2
    link.sender.sendto(datagrams[1], link.receiver.local_address)  # its first half was lost
    link.send_bottle(["whole"])
    assert link.receive() == ["whole"]
    assert link.source.counters == InputCounters(messages=1, dropped_datagrams=1)
