"""yarp_lite ports on real sockets, against a ``yarp-lite server`` process."""

from __future__ import annotations

import socket
import struct
import threading
import time

import pytest

from harness import wait_until
from yarp_lite import network
from yarp_lite.bottle import Bottle, Int8, Vocab, encode
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.carriers import PROTOCOL_NOT_FOUND
from yarp_lite.errors import LocalProtocolError
from yarp_lite.framing import encode_message, encode_sender_name, yarp_number
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcClient, RpcServer

CARRIERS = ["tcp", "fast_tcp", "udp", "text", "text_ack"]


@pytest.fixture
def ports():
    opened = []

    def make(cls=Port, *args, **kwargs):
        port = cls(*args, **kwargs)
        opened.append(port)
        return port
    yield make
    for port in opened:
        port.close()


def test_open_registers_and_close_unregisters(lite_world, ports):
    port = ports(Port, "/test/a")
    client = NameClient()
    contact = client.query("/test/a")
    assert contact is not None and contact.port == port.address.port
    assert "/test/a" in [c.name for c in client.list()]
    assert client.get("/test/a", "accepts")  # described like a real YARP port
    port.close()
    assert client.query("/test/a") is None


def test_invalid_names_are_refused(lite_world):
    for name in ("noslash", "/ends/", "/has space", ""):
        with pytest.raises(LocalProtocolError, match="invalid port name"):
            Port(name)


@pytest.mark.parametrize("carrier", CARRIERS)
def test_write_read_on_every_carrier(lite_world, ports, carrier):
    received = []
    got = threading.Event()

    def reader(bottle):
        received.append(bottle)
        if len(received) == 3:
            got.set()

    ports(Port, "/in", reader=reader)
    out = ports(Port, "/out")
    outcome = network.connect("/out", "/in", carrier)
    assert outcome.ok, outcome.message
    assert network.connection_carrier("/out", "/in") == carrier
    bottles = [Bottle([1, "two", 3.5]), Bottle([Bottle([Int8(4)]), Vocab("ok"), b"\x00\x01"]),
               Bottle(["last"])]
    for bottle in bottles:
        assert out.write(bottle)
        if carrier == "udp":
            time.sleep(0.05)  # pacing, not synchronisation: udp drops what a reader misses
    assert got.wait(5), f"received only {received}"
    if carrier in ("text", "text_ack"):
        # Text loses the exact integer width, exactly as in YARP.
        assert [str(b) for b in received] == [str(b) for b in bottles]
    else:
        assert [encode(b) for b in received] == [encode(b) for b in bottles]


def test_rpc_with_handler_and_with_read_reply(lite_world, ports):
    ports(RpcServer, "/calc", handler=lambda b: Bottle([sum(b)]))
    client = ports(RpcClient, "/calc/client", "/calc")
    assert client.call(Bottle([1, 2, 3])) == [6]

    manual = ports(RpcServer, "/manual")

    def serve():
        request = manual.read(timeout=5)
        manual.reply(Bottle(["echo", *request]))
    threading.Thread(target=serve, daemon=True).start()
    client2 = ports(RpcClient, "/manual/client", "/manual")
    assert client2.call(["hi"], timeout=5) == ["echo", "hi"]


def test_rpc_to_a_port_that_never_replies_gets_an_empty_reply(lite_world, ports):
    ports(Port, "/silent", reader=lambda b: None)
    client = ports(RpcClient, "/silent/client", "/silent")
    assert client.call(["anyone?"], timeout=5) == []


def test_a_reader_that_raises_loses_one_message_not_the_connection(lite_world, ports):
    received = []

    def fragile(bottle):
        if bottle[0] == "boom":
            raise RuntimeError("owner bug")
        received.append(bottle[0])

    ports(Port, "/fragile", reader=fragile)
    out = ports(Port, "/fragile/out")
    assert network.connect("/fragile/out", "/fragile").ok
    for word in ("one", "boom", "two"):
        out.write([word])
    wait_until(lambda: received == ["one", "two"], message=f"both good messages (got {received})")
    assert network.is_connected("/fragile/out", "/fragile")


def test_rpc_port_accepts_one_output(lite_world, ports):
    ports(Port, "/x1", reader=lambda b: None)
    ports(Port, "/x2", reader=lambda b: None)
    client = ports(RpcClient, "/one", "/x1")
    assert not client.add_output("/x2")


def test_buffered_port_latest_only_and_strict(lite_world, ports):
    latest = ports(BufferedPort, "/latest")
    strict = ports(BufferedPort, "/strict", strict=True)
    sender = ports(Port, "/sender")
    assert network.connect("/sender", "/latest").ok
    assert network.connect("/sender", "/strict").ok
    for index in range(20):
        sender.write([index])
    wait_until(lambda: strict.pending == 20, message="20 strict messages")
    assert [strict.read()[0] for _ in range(20)] == list(range(20))
    assert latest.read(timeout=2) == [19]
    assert latest.dropped == 19 and latest.read(wait=False) is None


def test_buffered_port_callback_and_background_write(lite_world, ports):
    seen = []
    ports(BufferedPort, "/cb", on_read=seen.append, strict=True)
    writer = ports(BufferedPort, "/bw", strict=True)
    assert network.connect("/bw", "/cb").ok
    for index in range(50):
        writer.write([index])
    assert writer.wait_for_write(5)
    wait_until(lambda: len(seen) == 50)
    assert [b[0] for b in seen] == list(range(50))


def test_a_held_flood_of_silent_connections_cannot_lock_a_real_client_out(lite_world, ports,
                                                                         caplog):
    """More silent connections than the port takes inputs, all held open: the oldest that
    never said who they are are closed for newer ones, and a real sender gets through (a
    name server under such a flood beside two burners did not answer for 20 s)."""
    received = []
    target = ports(Port, "/flooded", reader=lambda b: received.append(b[0]))
    target.max_inputs = 100                     # the flood below is half as big again
    flood = []
    try:
        for _ in range(150):
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setblocking(False)
            flood.append(sock)
            try:
                sock.connect(("127.0.0.1", target.address.port))
            except BlockingIOError:
                pass
        said = lambda text: any(text in r.getMessage() for r in caplog.records)  # noqa: E731
        wait_until(lambda: said("had not said who they are") or said("connections refused"),
                   timeout=30, message="the port flooded")
        sender = ports(Port, "/real")
        wait_until(lambda: network.connect("/real", "/flooded").ok, timeout=30,
                   message="a real connection to the flooded port")
        sender.write([7])
        wait_until(lambda: received == [7], timeout=30, message="the real sender's message")
    finally:
        for sock in flood:
            sock.close()
    assert said("had not said who they are")


def test_a_reader_s_min_interval_skips_to_the_newest_and_can_be_changed_while_connected(
        lite_world, ports):
    """A module reads the robot slowly while idle and at its own rate once it controls
    (walkman.hal.robot.Robot.read_idle): the interval changes on a live connection."""
    seen = []
    reader = ports(BufferedPort, "/paced", on_read=lambda b: seen.append(b[0]),
                   min_interval=600.0)
    writer = ports(Port, "/pacer")
    assert network.connect("/pacer", "/paced", "fast_tcp").ok
    writer.write([0])
    wait_until(lambda: seen == [0], timeout=20, message="the first message")
    for index in range(1, 100):                 # they wait in the socket: 600 s to go
        writer.write([index])
    reader.min_interval = 0.0                   # the wait under way ends now
    wait_until(lambda: seen[-1:] == [99], timeout=20, message="the newest, 99")
    assert len(seen) <= 3, seen                 # the rest skipped, never decoded
    for index in range(100, 120):               # one by one: none can supersede another
        writer.write([index])
        wait_until(lambda: seen[-1] == index, timeout=20, message=f"message {index}")
    assert seen[-20:] == list(range(100, 120))
    with pytest.raises(ValueError, match="latest-only"):
        ports(BufferedPort, "/strictly", strict=True).min_interval = 0.5


def test_a_reader_asking_for_a_period_is_sent_fewer_messages_of_a_stream(lite_world, ports):
    """``+period.S``: the robot's 500 Hz state goes to a 10 Hz reader at about its rate
    (the writer skips the rest, never sends them); a reader without one gets every message,
    and a modifier the writer does not know is refused by name."""
    slow, every = [], []
    ports(BufferedPort, "/slow", on_read=lambda b: slow.append(b[0]))
    ports(BufferedPort, "/every", on_read=lambda b: every.append(b[0]), strict=True)
    writer = ports(Port, "/stream")
    assert network.connect("/stream", "/slow", "fast_tcp+period.600").ok
    assert network.connect("/stream", "/every", "fast_tcp").ok
    for index in range(50):
        writer.write([index], skip_busy=True)
    wait_until(lambda: every[-1:] == [49], message=f"every message (saw {every[-3:]})")
    assert every == list(range(50))
    assert slow == [0]                          # the next one is due in ten minutes
    writer.write([50])                          # a write that is not a stream's goes to all
    wait_until(lambda: slow[-1:] == [50], message=f"the plain write (saw {slow})")
    refused = network.connect("/stream", "/every", "fast_tcp+rate.5")
    assert not refused.ok and "unknown modifier 'rate.5'" in refused.message, refused


def test_a_latest_only_reader_that_fell_behind_skips_to_the_newest(lite_world, ports):
    """As YARP's non-strict BufferedPort: a callback still busy when messages pile up
    sees the newest next, not the backlog (a 500 Hz state stream read by a slow module
    was up to a second old)."""
    seen = []

    def slow(bottle):
        seen.append(bottle[0])
        if len(seen) == 1:
            time.sleep(0.3)                 # the backlog piles up in the connection

    reader = ports(BufferedPort, "/behind", on_read=slow)
    writer = ports(Port, "/fast")
    assert network.connect("/fast", "/behind", "fast_tcp").ok      # no acks: the writer goes on
    for index in range(200):
        writer.write([index])
    wait_until(lambda: seen and seen[-1] == 199, message=f"the newest message (saw {seen[-5:]})")
    assert len(seen) < 50, seen
    assert seen == sorted(seen) and reader.dropped == 200 - len(seen)


def test_admin_interface(lite_world, ports):
    ports(Port, "/adm/in", reader=lambda b: None)
    out = ports(Port, "/adm/out")
    contact = NameClient().query("/adm/out")
    assert network.request(contact, [Vocab("ver")], admin=True) == [Vocab("ver"), 1, 2, 3]
    reply = network.request(contact, [Vocab("add"), "/adm/in"], admin=True)
    assert reply == [0, "Added connection from /adm/out to /adm/in\r\n"]
    assert network.request(contact, [Vocab("list"), Vocab("out")], admin=True) == ["/adm/in"]
    details = network.request(contact, [Vocab("list"), Vocab("out"), "/adm/in"], admin=True)
    assert details.find("carrier") == "tcp"
    help_reply = network.request(contact, [Vocab("help")], admin=True)
    assert help_reply[0] == Vocab("many") and len(help_reply) > 10
    assert network.request(contact, [Vocab("del"), "/adm/in"], admin=True)[0] == 0
    assert out.output_count == 0
    assert network.request(contact, ["bogus"], admin=True)[0] == Vocab("fail")


def test_a_reader_that_vanished_is_not_listed_as_an_output(lite_world, lite, ports):
    """No write needed: ``[list] [out]`` is what a name server asks before it
    reconnects a persistent connection, so a dead reader must not be named."""
    reader = lite_world.tool(lite, "read", "/gone/in")
    reader.wait_for("Port /gone/in active")
    writer = ports(Port, "/gone/out")
    assert network.connect("/gone/out", "/gone/in").ok
    reader.wait_for("Receiving input from /gone/out")
    contact = NameClient().query("/gone/out")
    assert network.request(contact, [Vocab("list"), Vocab("out")], admin=True) == ["/gone/in"]
    reader.kill()  # SIGKILL: the sockets close, nobody says goodbye or unregisters
    wait_until(lambda: network.request(contact, [Vocab("list"), Vocab("out")],
                                       admin=True) == [], message="dead output removed")
    assert writer.output_count == 0


def test_describe_lists_connections(lite_world, ports):
    ports(Port, "/d/in", reader=lambda b: None)
    ports(Port, "/d/out")
    assert network.connect("/d/out", "/d/in").ok
    lines = network.describe("/d/out")
    assert lines[0].startswith("This is /d/out at tcp://")
    assert "There is an output connection from /d/out to /d/in using tcp" in lines


def test_port_prefix_and_rename(lite_world, ports, monkeypatch):
    monkeypatch.setenv("YARP_PORT_PREFIX", "/robot")
    assert ports(Port, "/arm").name == "/robot/arm"
    monkeypatch.delenv("YARP_PORT_PREFIX")
    monkeypatch.setenv("YARP_RENAME_leg", "/left_leg")
    assert ports(Port, "/leg").name == "/left_leg"


# -- persistent connections ------------------------------------------------------------------


def test_persistent_connection_before_ports_exist_and_after_restart(lite_world, ports):
    assert network.connect("/p/out", "/p/in", persist=True).ok
    received = []
    receiver = ports(Port, "/p/in", reader=received.append)
    sender = ports(Port, "/p/out")
    wait_until(lambda: sender.output_count == 1, message="persistent connection made")
    sender.write(["first"])
    wait_until(lambda: received == [["first"]])
    receiver.close()
    wait_until(lambda: sender.output_count == 0 or not sender.write(["lost"]), timeout=5)
    ports(Port, "/p/in", reader=received.append)
    wait_until(lambda: sender.output_count == 1, message="connection restored")
    sender.write(["second"])
    wait_until(lambda: ["second"] in received)
    listing = NameClient().subscriptions()
    assert listing[0] == "subscriptions" and len(listing) == 2


def test_subscriptions_and_registrations_survive_a_server_restart(lite_world, ports):
    from yarp_lite.registration import RegistrationKeeper

    received = []
    ports(Port, "/s/in", reader=received.append)
    sender = ports(Port, "/s/out")
    assert network.connect("/s/out", "/s/in", persist=True).ok
    wait_until(lambda: sender.output_count == 1)
    lite_world.stop_server()
    lite_world.start_server()
    RegistrationKeeper.instance().check_now()
    wait_until(lambda: NameClient().query("/s/out") is not None, timeout=10,
               message="ports registered again")
    assert NameClient().subscriptions()[1:] != []
    sender.remove_output("/s/in")
    # The restored server remakes the persistent connection when the ports announce.
    RegistrationKeeper.instance().check_now()
    assert network.connect("/s/out", "/s/in", persist=True).ok
    wait_until(lambda: sender.output_count == 1, timeout=10)


def test_noticing_a_restart_costs_one_query_per_name_server_not_a_list_per_port(
        lite_world, ports, monkeypatch):
    from yarp_lite.registration import RegistrationKeeper

    for index in range(6):
        ports(Port, f"/keep/p{index}", reader=lambda bottle: None)
    asked = {"query": [], "list": 0}
    query, listing = NameClient.query, NameClient.list

    def counted_query(client, name):
        asked["query"].append(name)
        return query(client, name)

    def counted_list(client):
        asked["list"] += 1
        return listing(client)

    keeper = RegistrationKeeper.instance()
    with keeper.held():   # the keeper's own rounds would be counted too (a flake: 2 lists)
        monkeypatch.setattr(NameClient, "query", counted_query)
        monkeypatch.setattr(NameClient, "list", counted_list)
        keeper.check_all()
        keeper.check_all()
        assert len(asked["query"]) == 2 and asked["list"] == 0, asked
        assert asked["query"][0] != asked["query"][1]  # each port's turn comes
        lite_world.stop_server()
        lite_world.start_server()
        keeper.check_all()
        assert asked["list"] == 1  # the one asked about was lost: find the others
    for index in range(6):
        assert query(NameClient(), f"/keep/p{index}") is not None


# -- bad input -----------------------------------------------------------------------------


def _raw(port: Port) -> socket.socket:
    return socket.create_connection(("127.0.0.1", port.address.port), timeout=5)


def _still_works(ports, target: Port, received: list) -> None:
    sender = ports(Port, "...")  # anonymous: the server names it /tmp/port/N
    assert sender.name.startswith("/tmp/port/")
    assert network.connect(sender.name, target.name).ok
    sender.write(["alive"])
    wait_until(lambda: ["alive"] in received, message="port still serving")


def test_unknown_protocol_gets_yarps_explanation(lite_world, ports):
    received = []
    port = ports(Port, "/bad/a", reader=received.append)
    with _raw(port) as sock:
        sock.sendall(b"GET / HTTP/1.0\r\n\r\n")
        reply = b""
        while chunk := sock.recv(4096):
            reply += chunk
    assert reply == PROTOCOL_NOT_FOUND
    _still_works(ports, port, received)


@pytest.mark.parametrize("after_header", [
    yarp_number(10) + bytes([1, 1]) + b"\xff" * 8 + struct.pack("<ii", 0x7FFFFFF0, 0),  # 2 GB
    b"XXXXXXXXXXXXXXXXXXXXXXXXXXXX",                                                    # garbage
    b"".join(encode_message("D", [b"\x00\x01\x00\x00\x05\x00\x00\x00"])),               # truncated bottle
    b"".join(encode_message("D", [b"abc"]))[:25],                                       # dies mid-message
])
def test_malformed_messages_drop_only_that_connection(lite_world, ports, after_header):
    received = []
    port = ports(Port, "/bad/b", reader=received.append)
    with _raw(port) as sock:
        sock.sendall(yarp_number(7777 + 3 + 128) + encode_sender_name("/evil"))
        assert sock.recv(8).startswith(b"YA")
        sock.sendall(after_header)
        time.sleep(0.2)  # let the port chew on the bad bytes before we hang up (either way,
        # the assertions below must hold: nothing delivered, the port still serving)
    _still_works(ports, port, received)
    assert received == [["alive"]]


def test_a_flood_of_registrations_and_connections(lite_world, ports):
    client = NameClient()
    errors = []

    def register(index):
        try:
            client.register(f"/flood/{index}")
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(exc)
    threads = [threading.Thread(target=register, args=(i,)) for i in range(100)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    names = [c.name for c in client.list()]
    assert sum(name.startswith("/flood/") for name in names) == 100
    numbers = [c.port for c in client.list() if c.name.startswith("/flood/")]
    assert len(set(numbers)) == 100  # every registration got its own socket number
    received = []
    port = ports(Port, "/bad/c", reader=received.append)
    idle = [_raw(port) for _ in range(50)]  # connections that never say anything
    try:
        _still_works(ports, port, received)
    finally:
        for sock in idle:
            sock.close()


def test_an_idle_input_survives_a_process_wide_socket_timeout(lite_world, ports):
    """rospy sets socket.setdefaulttimeout(60) when a subscriber connects: our sockets must
    not inherit it (an idle warning port was dropped after a minute of silence)."""
    received = []
    previous = socket.getdefaulttimeout()
    socket.setdefaulttimeout(0.3)
    try:
        port = ports(Port, "/idle/in", reader=received.append)
        out = ports(Port, "/idle/out")
        assert out.add_output("/idle/in")
        out.write(Bottle(["before"]))
        wait_until(lambda: received == [["before"]], 5, message="the first message")
        time.sleep(1.0)  # the thing under test: silence longer than the default timeout
        out.write(Bottle(["after"]))
        wait_until(lambda: received == [["before"], ["after"]], 5,
                   message="a message after the silence")
        assert port.input_count == 1
    finally:
        socket.setdefaulttimeout(previous)


# -- holding messages for readers that connect later (yarp_lite.held) ------------------------


def test_a_plain_port_drops_what_it_writes_with_no_reader_as_yarp(lite_world, ports):
    out = ports(Port, "/plain/out")
    assert out.write(["nobody listens"])
    received = []
    ports(Port, "/plain/in", reader=received.append)
    assert network.connect("/plain/out", "/plain/in").ok
    assert out.write(["now"])
    wait_until(lambda: received == [["now"]], timeout=5)


def test_a_holding_port_hands_a_late_reader_what_it_wrote_before(lite_world, ports):
    out = ports(Port)
    out.hold_for_late_readers(count=8, max_age=30.0)
    out.open("/held/out")
    out.write(["7", "expired", "too old"])
    out.write(["8", "accepted"])
    received = []
    ports(Port, "/held/in", reader=received.append)
    assert network.connect("/held/out", "/held/in").ok
    out.write(["9", "accepted"])
    wait_until(lambda: len(received) == 3, timeout=5, message=f"got {received}")
    assert received == [["7", "expired", "too old"], ["8", "accepted"], ["9", "accepted"]]
    assert out.held.handed_over == 2


def test_a_reader_back_under_its_name_gets_only_what_it_missed(lite_world, ports):
    out = ports(Port)
    out.hold_for_late_readers(count=8, max_age=30.0)
    out.open("/again/out")
    first = []
    reader = ports(Port, "/again/in", reader=first.append)
    assert network.connect("/again/out", "/again/in").ok
    out.write(["taken"])
    wait_until(lambda: first == [["taken"]], timeout=5)
    reader.close()                                     # a restarting process
    wait_until(lambda: out.output_count == 0, timeout=5, message="the reader gone")
    out.write(["missed"])
    second = []
    ports(Port, "/again/in", reader=second.append)
    assert network.connect("/again/out", "/again/in").ok
    wait_until(lambda: second == [["missed"]], timeout=5, message=f"got {second}")
    # a reader that was never there gets the recent history, as a latched topic
    other = []
    ports(Port, "/again/look", reader=other.append)
    assert network.connect("/again/out", "/again/look").ok
    wait_until(lambda: other == [["taken"], ["missed"]], timeout=5, message=f"got {other}")
    assert second == [["missed"]]


def test_what_is_written_while_a_reader_is_handed_the_backlog_comes_after_it(lite_world,
                                                                               ports):
    out = ports(Port)
    out.hold_for_late_readers(count=100, max_age=30.0)
    out.open("/order/out")
    for number in range(20):
        out.write([number])
    received = []

    def slow_reader(bottle):
        time.sleep(0.005)          # the hand-over takes a while: writes come meanwhile
        received.append(bottle[0])

    ports(Port, "/order/in", reader=slow_reader)
    connecting = threading.Thread(target=network.connect, args=("/order/out", "/order/in"))
    connecting.start()
    for number in range(20, 60):
        out.write([number])
        time.sleep(0.001)
    connecting.join()
    wait_until(lambda: len(received) >= 60 and out.output_count == 1, timeout=10,
               message=f"got {len(received)}")
    time.sleep(0.1)
    assert received == list(range(60))     # each once, in the order written


# -- the port's parts: registration, delivery, outputs (issue 67) -------------------------


def test_a_registration_keeper_given_to_ports_keeps_them_and_its_thread_ends_with_the_last(
        lite_world, ports):
    """Whoever opens ports may give them a keeper of its own; its thread runs while it
    keeps a port, ends soon after the last one closes, and starts again with the next."""
    from yarp_lite.registration import RegistrationKeeper

    keeper = RegistrationKeeper()
    first = ports(Port, "/keeper/a", keeper=keeper)
    second = ports(Port, "/keeper/b", keeper=keeper)
    thread = keeper._thread
    assert thread is not None and thread.is_alive()
    lite_world.stop_server()
    lite_world.start_server()
    keeper.check_now()
    wait_until(lambda: NameClient().query("/keeper/b") is not None, timeout=10,
               message="the keeper registered its ports again")
    first.close()
    assert thread.is_alive()                 # one port left to keep
    second.close()
    thread.join(timeout=5.0)
    assert not thread.is_alive()
    ports(Port, "/keeper/c", keeper=keeper)
    assert keeper._thread is not None and keeper._thread.is_alive()


def test_a_delivery_of_the_owners_own_gets_every_message_with_its_source(lite_world, ports):
    """A port's delivery strategy (yarp_lite.delivery) replaces the callback and the
    blocking read: it hears each data message with where it came from, and its reply goes
    back to a sender that asked for one."""

    class Recorder:
        latest_only = False

        def __init__(self) -> None:
            self.envelope = ""
            self.seen = []

        def deliver(self, message, source):
            self.seen.append((message.bottle().to_text(), source.route.source,
                              source.remote_host))
            return Bottle(["got", len(self.seen)])

        def superseded(self, message) -> None:
            raise AssertionError("a delivery that is not latest-only skips nothing")

        def pace(self) -> None:
            pass

        def close(self) -> None:
            pass

    recorder = Recorder()
    ports(Port, "/delivery/in", delivery=recorder)
    client = ports(RpcClient, "/delivery/client", "/delivery/in")
    assert client.call(["hello", 1]).to_text() == "got 1"
    writer = ports(Port, "/delivery/out")
    assert writer.add_output("/delivery/in")
    writer.write(Bottle(["again"]))
    wait_until(lambda: len(recorder.seen) == 2)
    assert recorder.seen == [("hello 1", "/delivery/client", "127.0.0.1"),
                             ("again", "/delivery/out", "127.0.0.1")]
    with pytest.raises(ValueError, match="a reader or a delivery, not both"):
        Port(reader=print, delivery=recorder)


def test_asking_for_a_ports_outputs_changes_nothing_the_next_write_drops_a_dead_one(
        lite_world, ports):
    """``output_routes``/``output_count`` leave out an output whose reader has gone but
    do not drop it; the next write does."""
    reader = ports(Port, "/query/in", reader=lambda bottle: None)
    writer = ports(Port, "/query/out")
    assert writer.add_output("/query/in")
    assert writer.output_count == 1
    reader.close()
    wait_until(lambda: writer.output_count == 0)
    assert writer.has_outputs                 # still there: a query dropped nothing
    assert writer.output_count == 0 and writer.output_routes() == []
    wait_until(lambda: not writer.write(Bottle(["anyone?"])) or not writer.has_outputs)
    assert not writer.has_outputs
