"""Datagram copies of commands and statuses: the codec, which status copy is written, and a
command that crosses while its TCP frame is stuck (bridge.transport.copies)."""

from __future__ import annotations

import dataclasses
import select
import socket
import threading
from typing import Iterator, List

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError
from bridge.transport.copies import (OVERTAKEN, FirstStatus, ReliableCopy, ReliableCopyCodec,
                                     decode_copy, encode_copy)
from bridge.transport.drops import Reason
from bridge.transport.udp_channel import UdpChannel, UdpRoute
from bridge.wire import compact
from codec_helpers import FUZZ
from harness import free_port, wait_until
from harness import ManualClock as Clock
from test_tcp_channel import COMMAND, ROUTES, End
from walkman.gym.validity import split
from yarp_lite.bottle import Bottle

# -- the codec ----------------------------------------------------------------------------


def test_a_copy_round_trips_and_every_cut_of_it_is_refused_by_name():
    copy = ReliableCopy(0x1234_5678_9ABC_DEF0, 77, compact.encode(Bottle(["go", 1.5])), 12345)
    data = encode_copy(copy)
    assert decode_copy(data) == copy
    for end in range(17):                             # the head, byte by byte, and nothing
        with pytest.raises(BridgeProtocolError, match="16-byte head and a payload"):
            decode_copy(data[:end])
    with pytest.raises(BridgeProtocolError, match="neither may be 0"):
        decode_copy(bytes(8) + data[8:])
    with pytest.raises(BridgeProtocolError, match="clock 4294967295 exceeds"):
        decode_copy(data[:12] + b"\xff" * 4 + data[16:])
    with pytest.raises(ValueError, match="number > 0"):
        encode_copy(ReliableCopy(1, 0, b"x"))


@FUZZ
@given(st.binary(max_size=64))
def test_any_bytes_are_a_copy_or_the_peers_error(data):
    try:
        copy = ReliableCopyCodec().decode(data, 1.0)
    except BridgeProtocolError:
        return
    assert encode_copy(copy) == data


# -- which status copy is written -----------------------------------------------------------


def test_the_first_status_copy_is_written_and_a_late_older_one_never():
    clock = Clock()
    first = FirstStatus(clock)
    start = clock.now
    assert first.first("valve", Bottle([5, "reached"]))
    assert not first.first("valve", Bottle([5, "reached"]))      # the other copy
    assert first.first("valve", Bottle([6, "grasped"]))          # by datagram, ahead of TCP
    clock.now = start + 0.3
    assert not first.first("valve", Bottle([5, "reached"]))      # TCP's late one: overtaken
    assert first.first("door", Bottle([5, "reached"]))           # flows are apart
    assert (first.repeats, first.overtaken) == (1, 1)


def test_a_module_restarted_counts_again_after_a_while_or_once_it_left():
    clock = Clock()
    first = FirstStatus(clock)
    first.first("valve", Bottle([900, "idle"]))
    clock.now += OVERTAKEN + 0.1          # restarted later than a late copy can come
    assert first.first("valve", Bottle([1, "initializing"]))
    first.forget("valve")                # its stand-in closed: it left
    assert first.first("valve", Bottle([1, "initializing"]))


# -- a command whose frame is stuck crosses as a datagram --------------------------------------


class Relay:
    """A TCP forwarder between the pilot and the robot whose pilot->robot way can stop:
    a TCP stream stalled behind a lost segment, while datagrams still pass."""

    def __init__(self, target: int) -> None:
        self.target = target
        self.flowing = threading.Event()
        self.flowing.set()
        self.closed = threading.Event()
        self.holding = False     # some bytes were held since it stopped
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.2)
        self.port = self.listener.getsockname()[1]
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.closed.is_set():
            try:
                inbound, _ = self.listener.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            threading.Thread(target=self._pump, args=(inbound,), daemon=True).start()

    def _pump(self, inbound: socket.socket) -> None:
        try:
            outbound = socket.create_connection(("127.0.0.1", self.target))
        except OSError:
            inbound.close()
            return
        held = bytearray()      # pilot->robot bytes read while stopped: sent on resume
        with inbound, outbound:
            while not self.closed.is_set():
                readable, _, _ = select.select([inbound, outbound], [], [], 0.05)
                try:
                    if held and self.flowing.is_set():
                        outbound.sendall(held)
                        held.clear()
                    for source in readable:
                        data = source.recv(65536)
                        if not data:
                            return
                        if source is outbound:
                            inbound.sendall(data)
                        elif self.flowing.is_set() and not held:
                            outbound.sendall(data)
                        else:
                            held += data
                            self.holding = True
                except OSError:
                    return

    def close(self) -> None:
        self.closed.set()
        self.listener.close()
        self.thread.join(timeout=3)


COPIED_ROUTES = [dataclasses.replace(route, copies=2) if route.key == COMMAND else route
                 for route in ROUTES]


@pytest.fixture
def relayed(tmp_path) -> Iterator[tuple]:
    """A robot and a pilot end, TCP through a :class:`Relay`, their copies on UDP."""
    robot_tcp, robot_udp, pilot_udp = free_port(), free_port(), free_port()
    relay = Relay(robot_tcp)
    copied = [UdpRoute.of(route, ReliableCopyCodec()) for route in COPIED_ROUTES if route.copies]
    robot_copies = UdpChannel(peer="127.0.0.1", port=robot_udp, peer_port=pilot_udp,
                              routes=copied, gather=0.1,
                              on_message=lambda key, copy: robot.channel.accept_copy(key, copy))
    pilot_copies = UdpChannel(peer="127.0.0.1", port=pilot_udp, peer_port=robot_udp,
                              routes=copied, gather=0.1, on_message=lambda key, value: None)
    sent: List[ReliableCopy] = []

    def send_copies(copies) -> None:
        for key, copy in copies:
            sent.append(copy)
            pilot_copies.send_now(key, copy, 2)

    robot = End("robot", robot_tcp, tmp_path / "robot", listen=True, routes=COPIED_ROUTES,
                on_keys=robot_copies.set_keys)
    pilot = End("pilot", relay.port, tmp_path / "pilot", listen=False, routes=COPIED_ROUTES,
                on_keys=pilot_copies.set_keys, on_copies=send_copies)
    for part in (robot_copies, pilot_copies, robot, pilot):
        part.start()
    try:
        wait_until(lambda: robot.channel.connected and pilot.channel.connected, 10,
                   message="link up")
        yield robot, pilot, relay, sent
    finally:
        relay.flowing.set()
        for part in (pilot, robot, pilot_copies, robot_copies):
            part.stop()
        relay.close()


def test_a_command_whose_frame_is_stuck_runs_once_by_its_copy(relayed):
    robot, pilot, relay, sent = relayed
    pilot.channel.send_reliable(COMMAND, Bottle([Bottle(["look_at", 1.0]), 1]))
    wait_until(lambda: len(robot.reliable) == 1 and pilot.journal.waiting() == 0, 10,
               message="the first command, both ways open")
    relay.flowing.clear()                       # the pilot's TCP stream stops here
    pilot.channel.send_reliable(COMMAND, Bottle([Bottle(["look_at", 2.0]), 2]))
    wait_until(lambda: len(robot.reliable) == 2, 10,
               message="the second command, by its datagram copy alone")
    assert robot.channel.stats.reliable_by_copy >= 1
    relay.flowing.set()                         # the frame follows: a repeat, not a drop
    wait_until(lambda: pilot.journal.waiting() == 0, 15, message="the robot's acknowledgement")
    assert [split(message)[0][0][1] for message in robot.reliable] == [1.0, 2.0]
    assert robot.channel.drops.get(Reason.DUPLICATE) == 0
    assert [copy.seq for copy in sent][:2] == [1, 2]


def test_copies_of_a_message_count_once_for_the_loss_and_are_no_drop():
    """Three copies of each message (the stop-all's way, and commands'): the receiver's loss
    report never says more arrived than was sent (it used to, and the report's encoder
    refused it in the sending thread), and the repeats are no drop."""
    from bridge.flows import Carriage, Form, Route
    from bridge.transport.udp_channel import Reassembler, UdpStats, message_datagrams
    from bridge.wire import datagrams

    route = UdpRoute.of(Route(COMMAND, "gaze_control/command", Carriage.RELIABLE, Form.BOTTLE,
                              copies=3), ReliableCopyCodec())
    stats = UdpStats()
    reassembler = Reassembler({COMMAND: route}, 0.4, stats)
    published = []
    for seq in range(1, 6):
        (wire,) = message_datagrams(route, 1000 + seq,
                                    [encode_copy(ReliableCopy(9, seq, b"\x01go"))])
        for _ in range(3):
            published += reassembler.feed(wire, now=seq * 0.01)
    assert [copy.seq for _, copy in published] == [1, 2, 3, 4, 5]
    assert (reassembler.loss.received, reassembler.loss.expected) == (5, 5)
    datagrams.encode_report(reassembler.loss.report())      # a report it can send
    assert stats.flows["gaze_control/command"].repeats == 10
    assert reassembler.drops.get(Reason.STALE) == 0
