"""UDP channel: reassembly by message number, gathering time, FEC, and bad datagrams."""

from __future__ import annotations

import random
import socket
import time

import numpy as np
import pytest

from bridge.endpoints.yarp import BottleUdpCodec
from bridge.flows import Carriage, FlowKey, Form, Route
from bridge.transport.drops import Reason
from bridge.transport.udp_channel import (Reassembler, UdpChannel, UdpRoute, UdpStats,
                                          message_datagrams, slice_message)
from bridge.wire import datagrams, tiles
from bridge.wire.link import DatagramSealer
from harness import free_port, wait_until
from yarp_lite.bottle import Bottle


class RasterCodec:
    """Tiles of a plain numpy image, for tests without ROS."""

    tiled = True

    def encode(self, image):
        return tiles.split(image, tiles.header_for(image, tiles.PNG), b"frame")

    def decode(self, canvas, completeness):
        return canvas


def udp_route(key, label, codec, fec=0.0, adaptive=False) -> UdpRoute:
    return UdpRoute.of(Route(FlowKey(*key), label, Carriage.DATAGRAMS, Form.BOTTLE, fec=fec,
                             fec_auto=adaptive), codec)


IMAGE = np.random.default_rng(0).integers(0, 256, (120, 160, 3), dtype=np.uint8)
CAMERA = udp_route((30, 0), "camera", RasterCodec())
CAMERA_FEC = udp_route((31, 0), "camera_fec", RasterCodec(), fec=0.5)
BLOB = udp_route((9, 0), "blob", BottleUdpCodec())
ROUTES = {r.key: r for r in (CAMERA, CAMERA_FEC, BLOB)}
A_TO_B, B_TO_A = b"a" * 32, b"b" * 32


def keyed_pair(a: UdpChannel, b: UdpChannel) -> None:
    """What a TCP handshake gives both ends: each one's sending and receiving key."""
    a.set_keys("installed", A_TO_B, B_TO_A)
    b.set_keys("installed", B_TO_A, A_TO_B)


def test_a_complete_message_is_published_at_once():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    wire = message_datagrams(CAMERA, 1000, RasterCodec().encode(IMAGE))
    out = []
    for raw in wire:
        out += reassembler.feed(raw, now=0.0)
    assert len(out) == 1 and out[0][1].completeness == 1.0
    assert np.array_equal(out[0][1].pixels, IMAGE)
    assert all(len(raw) <= datagrams.MAX_INNER for raw in wire)


def test_a_partial_image_is_published_after_the_gathering_time():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    wire = message_datagrams(CAMERA, 1000, RasterCodec().encode(IMAGE))
    kept = wire[:-3]
    for raw in kept:
        assert reassembler.feed(raw, now=0.0) == []
    assert reassembler.expire(now=0.39) == []
    (key, canvas), = reassembler.expire(now=0.41)
    assert 0.5 < canvas.completeness < 1.0
    assert np.array_equal(canvas.pixels[canvas.covered], IMAGE[canvas.covered])
    assert stats.flows["camera"].partial == 1
    # Stragglers and replays of a published message are stale.
    assert reassembler.feed(wire[-1], now=0.5) == [] and reassembler.drops.get(Reason.STALE) == 1
    assert reassembler.feed(wire[0], now=0.5) == [] and reassembler.drops.get(Reason.STALE) == 2


def test_the_canvas_knows_the_tiles_sent_and_which_of_them_were_lost():
    reassembler = Reassembler(ROUTES, 0.4, UdpStats())
    bodies = RasterCodec().encode(IMAGE)
    wire = message_datagrams(CAMERA, 1000, bodies)
    dropped = {1, len(wire) - 1}
    for index, raw in enumerate(wire):
        if index not in dropped:
            reassembler.feed(raw, now=0.0)
    (_, canvas), = reassembler.expire(now=1.0)
    arrival = canvas.arrival()
    assert (arrival.tiles, arrival.tiles_arrived) == (len(bodies), len(bodies) - 2)
    lost = np.zeros(IMAGE.shape[:2], bool)
    for index in dropped:
        tile = tiles.decode_tile(bodies[index])[0]
        lost[tile.y:tile.y + tile.height, tile.x:tile.x + tile.width] = True
    shown = np.zeros_like(lost)
    for region in arrival.missing:
        shown[region.y:region.y + region.height, region.x:region.x + region.width] = True
    assert np.array_equal(shown, lost) and arrival.fraction == pytest.approx(1 - lost.mean())


def test_repair_datagrams_rebuild_lost_tiles():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    wire = message_datagrams(CAMERA_FEC, 7, RasterCodec().encode(IMAGE))
    data_parts = [raw for raw in wire if not datagrams.decode(raw).is_repair]
    lost = set(random.Random(1).sample(range(len(wire)), len(data_parts) // 3))
    out = []
    for index, raw in enumerate(wire):
        if index not in lost:
            out += reassembler.feed(raw, now=0.0)
    out += reassembler.expire(now=1.0)
    (_, canvas), = out
    assert canvas.completeness == 1.0 and stats.flows["camera_fec"].repaired > 0


def test_a_sliced_message_is_whole_or_lost():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    bottle = Bottle([bytes(5000), "tail"])
    wire = message_datagrams(BLOB, 5, slice_message(BottleUdpCodec().encode(bottle)))
    assert len(wire) == 4
    for raw in wire[1:]:
        reassembler.feed(raw, now=0.0)
    assert reassembler.expire(now=1.0) == [] and stats.flows["blob"].lost == 1
    out = []
    for raw in message_datagrams(BLOB, 6, slice_message(BottleUdpCodec().encode(bottle))):
        out += reassembler.feed(raw, now=2.0)
    assert out == [(FlowKey(9, 0), bottle)]


def test_newer_messages_supersede_older_ones_and_numbers_wrap():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    near_wrap = (1 << 32) - 1
    for number in (near_wrap, 0, 1):  # 0 and 1 come after the wrap
        out = []
        for raw in message_datagrams(BLOB, number, slice_message(b"\x01\x00\x02")):
            out += reassembler.feed(raw, now=0.0)
        assert len(out) == 1
    for raw in message_datagrams(BLOB, near_wrap, slice_message(b"\x01\x00\x02")):
        assert reassembler.feed(raw, now=0.0) == []
    assert reassembler.drops.get(Reason.STALE) == 1


def test_garbage_and_unknown_ids_are_counted_not_fatal():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    assert reassembler.feed(b"\x00" * 40, now=0.0) == []
    assert reassembler.feed(datagrams.encode(datagrams.Datagram(99, 0, 1, 1, 1, 0, b"x")),
                            now=0.0) == []
    corrupt_tile = datagrams.encode(datagrams.Datagram(30, 0, 1, 1, 1, 0, b"\x05" * 30))
    assert reassembler.feed(corrupt_tile, now=0.0) == []
    counts = reassembler.drops
    assert (counts.get(Reason.MALFORMED), counts.get(Reason.UNKNOWN_ID)) == (2, 1)
    assert "tile" in counts.last_error
    assert stats.flows["camera"].lost == 1


def test_channels_on_sockets_deliver_and_refuse_strangers():
    port_a, port_b = free_port(), free_port()
    received = []
    a = UdpChannel(peer="127.0.0.1", port=port_a, peer_port=port_b, routes=[BLOB], gather=0.4,
                   on_message=lambda k, v: None, rate=2e6)
    b = UdpChannel(peer="127.0.0.1", port=port_b, peer_port=port_a, routes=[BLOB], gather=0.4,
                   on_message=lambda k, v: received.append(v))
    a.start()
    b.start()
    try:
        a.post(BLOB.key, Bottle(["before any key", 2]))
        time.sleep(0.5)  # nothing may leave before the link's handshake gives keys
        assert a.stats.datagrams_out == 0
        keyed_pair(a, b)
        a.post(BLOB.key, Bottle(["hello", bytes(3000)]))
        wait_until(lambda: any(v[0] == "hello" for v in received), 5, message="the message")
        count = len(received)
        raw = message_datagrams(BLOB, int(time.time() * 1000) & 0xFFFFFFFF,
                                slice_message(b"\x01\x09\x03bad"))
        stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        stranger.bind(("127.0.0.2", 0))
        stranger.sendto(DatagramSealer(A_TO_B).seal(raw[0]), ("127.0.0.1", port_b))
        stranger.close()
        wait_until(lambda: b.drops.get(Reason.STRANGER) == 1, 5, message="stranger counted")
        # From the peer's own address: a forged tag, then a replay of a genuine datagram.
        spoof = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        spoof.sendto(DatagramSealer(b"x" * 32).seal(raw[0]), ("127.0.0.1", port_b))
        wait_until(lambda: b.drops.get(Reason.FORGED) == 1, 5, message="forgery counted")
        genuine = DatagramSealer(A_TO_B)
        spoof.sendto(genuine.seal(raw[0]), ("127.0.0.1", port_b))  # counter 0: seen already
        wait_until(lambda: b.drops.get(Reason.REPLAYED) == 1, 5, message="replay counted")
        spoof.close()
        assert len(received) == count
    finally:
        a.stop()
        b.stop()


def test_pacing_holds_the_configured_rate():
    port_a, port_b = free_port(), free_port()
    a = UdpChannel(peer="127.0.0.1", port=port_a, peer_port=port_b, routes=[BLOB], gather=0.4,
                   on_message=lambda k, v: None, rate=400e3)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", port_b))
    a.set_keys("installed", A_TO_B, B_TO_A)
    a.start()
    try:
        started = time.monotonic()
        a.post(BLOB.key, Bottle([bytes(50_000)]))  # 400 kbit of payload and headers
        wait_until(lambda: a.stats.datagrams_out >= 35, 10, message="all datagrams")
        elapsed = time.monotonic() - started
        bits = (a.stats.bytes_out + 28 * a.stats.datagrams_out) * 8
        assert bits / elapsed <= 400e3 * 1.25
    finally:
        a.stop()
        sink.close()


STOP = UdpRoute.of(Route(FlowKey(250, 0), "stop_all", Carriage.URGENT, Form.BOTTLE),
                   BottleUdpCodec())


def test_a_full_radio_takes_one_copy_of_a_stop_and_no_copies_of_the_rest():
    """Issue 66: behind a full radio, copies only delay the next stop.  The stop (or its
    acknowledgement) goes as one datagram, a resending of it and a command's copies not at
    all; with room, every copy goes; paced data waits for room."""
    from bridge.transport.link_budget import LinkBudget

    port_a, port_b = free_port(), free_port()
    budget = LinkBudget(9600)
    a = UdpChannel(peer="127.0.0.1", port=port_a, peer_port=port_b, routes=[BLOB, STOP],
                   gather=0.4, on_message=lambda k, v: None, budget=budget)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", port_b))
    a.set_keys("installed", A_TO_B, B_TO_A)
    try:
        assert a.send_now(STOP.key, Bottle(["stop_all", 7]), 3) == 3      # room: every copy
        budget.spend(600, time.monotonic())       # telemetry already in the radio's queue
        assert budget.full(time.monotonic())
        assert a.send_now(STOP.key, Bottle(["stop_all", 8]), 3) == 1      # full: one
        assert a.send_now(STOP.key, Bottle(["stop_all", 8]), 3, again=True) == 0
        assert a.send_now(BLOB.key, Bottle(["command"]), 2) == 0
        assert a.drops.get(Reason.COPY_SKIPPED) == 2 + 3 + 2
        spent = budget.spent
        a.start()
        a.post(BLOB.key, Bottle(["telemetry", bytes(100)]))
        time.sleep(0.1)
        assert budget.spent == spent          # paced data waits while the radio is full
        wait_until(lambda: budget.spent > spent, 5, message="the telemetry once there is room")
    finally:
        a.stop()
        sink.close()


def test_a_stop_goes_in_as_many_copies_as_the_loss_coming_in_needs():
    """At 30 % loss three copies of a stop all fail 2.7 % of the time.  A stop's copies
    tell the peer nothing of the loss (a lost one is never missed), so the loss this end
    measures on the way in sizes them: six."""
    from bridge.wire.datagrams import Report

    port_a, port_b = free_port(), free_port()
    a = UdpChannel(peer="127.0.0.1", port=port_a, peer_port=port_b, routes=[BLOB, STOP],
                   gather=0.4, on_message=lambda k, v: None)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", port_b))
    a.set_keys("installed", A_TO_B, B_TO_A)
    try:
        a.loss_in.on_report(Report(received=7000, expected=10000), time.monotonic())
        assert a.send_now(STOP.key, Bottle(["stop_all", 7]), 3) == 6
        assert a.send_now(BLOB.key, Bottle(["command"]), 2) == 2     # copies as configured
    finally:
        a.stop()
        sink.close()


def test_a_tile_whose_metadata_has_the_wrong_shape_is_dropped_not_raised():
    """Found by fuzzing: a valid compact Bottle of the wrong shape as an image's metadata
    raised ValueError out of the receive loop (a peer holding the key could stop it)."""
    from bridge.endpoints.ros import ImageCodec

    image = udp_route((30, 0), "image", ImageCodec(80))
    body = bytes.fromhex(
        "02020100500003010002000002020389504e470d0a1a0a0000000d49484452000000020000000208"
        "0000000057dd52f80000000b494441540899636000010000060001e687fe7f0000000049454e44ae"
        "426082")
    reassembler = Reassembler({image.key: image}, 0.4, UdpStats())
    assert reassembler.feed(datagrams.encode(datagrams.Datagram(30, 0, 1, 1, 1, 0, body)),
                            now=0.0) == []
    assert reassembler.drops.get(Reason.MALFORMED) == 1
    assert "image metadata" in reassembler.drops.last_error
    assert reassembler.stats.flows["image"].lost == 1


# -- adaptive FEC ---------------------------------------------------------------------------

CAMERA_AUTO = udp_route((32, 0), "camera_auto", RasterCodec(), adaptive=True)


def test_the_loss_meter_counts_data_off_the_wire_and_stragglers():
    stats = UdpStats()
    reassembler = Reassembler(ROUTES, 0.4, stats)
    wire = message_datagrams(CAMERA_FEC, 7, RasterCodec().encode(IMAGE))
    data = [i for i, raw in enumerate(wire) if not datagrams.decode(raw).is_repair]
    lost = set(data[:3])
    for index, raw in enumerate(wire):
        if index not in lost:
            reassembler.feed(raw, now=0.0)
    # Repairs rebuilt the three lost parts, but the meter saw them missing from the wire.
    assert stats.flows["camera_fec"].repaired == 3
    assert (reassembler.loss.received, reassembler.loss.expected) == (len(data) - 3, len(data))
    # A message given up at the gathering time, whose last part arrives after all.
    wire = message_datagrams(CAMERA, 8, RasterCodec().encode(IMAGE))
    for raw in wire[:-1]:
        reassembler.feed(raw, now=1.0)
    reassembler.expire(now=2.0)
    reassembler.feed(wire[-1], now=2.1)
    assert reassembler.loss.expected - reassembler.loss.received == 3


class LossySocket:
    """The channel's socket, losing each datagram it sends with probability ``loss``."""

    def __init__(self, sock: socket.socket, loss: float, seed: int) -> None:
        self._sock, self._loss, self._rng = sock, loss, random.Random(seed)

    def sendto(self, data: bytes, address) -> int:
        if self._rng.random() < self._loss:
            return len(data)
        return self._sock.sendto(data, address)

    def __getattr__(self, name: str):
        return getattr(self._sock, name)


#: s a frame's datagrams are gathered for in the repair test: long, so that only the repairs
#: decide a frame's completeness.  At 0.4 s the adaptive route's mean fell to 0.92 and 0.89 in
#: two suite runs (fc68, fc72) but never in 32 runs alone, beside two CPU burners or beside
#: two real-time busy loops (2026-11-29); what held a frame's datagrams back in the suite is
#: not known, so a failure prints both sides' counts.
REPAIR_GATHER = 2.0


@pytest.mark.parametrize("route, least", [(CAMERA_AUTO, 0.98), (CAMERA_FEC, 0.0)])
def test_adaptive_repairs_follow_the_loss_the_receiver_reports(route, least):
    port_a, port_b = free_port(), free_port()
    received = []
    a = UdpChannel(peer="127.0.0.1", port=port_a, peer_port=port_b, routes=[route],
                   gather=REPAIR_GATHER, on_message=lambda k, v: None)
    b = UdpChannel(peer="127.0.0.1", port=port_b, peer_port=port_a, routes=[route],
                   gather=REPAIR_GATHER,
                   on_message=lambda k, v: received.append((v.completeness, time.monotonic())))
    a._sock = LossySocket(a._sock, 0.3, seed=11)
    keyed_pair(a, b)
    a.start()
    b.start()
    try:
        posted = []
        for frame in range(40):
            count = len(received)
            posted.append(time.monotonic())
            a.post(route.key, IMAGE)
            wait_until(lambda: len(received) > count, 10, message=f"frame {frame}")
            time.sleep(0.05)
        flow = a.stats.flows[route.label]
        later = [completeness for completeness, _ in received[10:]]   # the first reports
        mean = sum(later) / len(later)                                # come with the first frames
        told = (f"completeness and delivery (s after posting): "
                f"{[(round(c, 3), round(t - p, 3)) for (c, t), p in zip(received, posted)]}; "
                f"sender {a.stats}; receiver {b.stats}")
        if route.fec_auto:
            assert 0.25 < a.stats.peer_loss < 0.35 and a.stats.fec_loss_bound > 0.25, told
            assert flow.repairs_sent > 0.6 * len(RasterCodec().encode(IMAGE)) * flow.sent, told
            assert mean >= least, told
        else:   # a fixed 0.5 is not enough at 30 % for groups of 32: the test can fail
            assert mean < 0.98, told
    finally:
        a.stop()
        b.stop()
