"""The TCP channel in-process on loopback: batching, exactly-once, reconnects, bad peers.

The link protocol and the frame session are tested without sockets in test_link.py and
test_frame_session.py, the phase table in test_channel_phase.py; here the channel's
threads and sockets around them: who may connect, who may replace whom.
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from typing import Any, Callable, List, Tuple

import pytest

from bridge.flows import Carriage, FlowKey, Form, Route
from bridge.gym.expiry import aged_payload
from bridge.transport.drops import Reason
from bridge.transport.journal import Journal
from bridge.transport.tcp_channel import TcpChannel, TcpListener, TcpSettings
from bridge.wire import compact, frames
from bridge.wire.link import LinkKey
from harness import free_port, wait_until
from system.processes import WaitTimeout
from yarp_lite.bottle import Bottle

SWITCH, COMMAND, STATUS = FlowKey(7, 0), FlowKey(7, 1), FlowKey(7, 2)
KEY = LinkKey(bytes(range(32)), source="test key")
ROUTES = [Route(SWITCH, "gaze_control/switch", Carriage.RELIABLE, Form.BOTTLE),
          Route(COMMAND, "gaze_control/command", Carriage.RELIABLE, Form.BOTTLE, expiring=True),
          Route(STATUS, "gaze_control/status", Carriage.LATEST, Form.BOTTLE,
                status_events=True)]


class Heard(TcpListener):
    """What the channel tells an :class:`End`, put where the tests read it."""

    def __init__(self, end: "End") -> None:
        self.end = end

    def message(self, key, value) -> None:
        self.end.streams.append((key, value))

    def reliable(self) -> None:
        self.end._drain()

    def presence(self) -> Any:
        return self.end.here

    def peer_presence(self, flows) -> None:
        self.end.on_presence(flows)

    def keys(self, event: str, send_key: bytes, receive_key: bytes) -> None:
        self.end.on_keys(event, send_key, receive_key)

    def copies(self, copies) -> None:
        self.end.on_copies(copies)

    def age(self, payload: bytes, seconds: float) -> bytes:
        return aged_payload(payload, seconds)


class End:
    """One side: a channel, its journal, and what it received; ``on_keys``, ``on_copies``:
    where the link's datagram keys and copies go."""

    def __init__(self, side: str, port: int, state_dir, listen: bool, peer: str = "127.0.0.1",
                 config_text: str = "config", period: float = 0.2,
                 key: LinkKey = KEY, routes: List[Route] = ROUTES,
                 on_keys: Callable[[str, bytes, bytes], None] = lambda *keys: None,
                 on_copies: Callable[[list], None] = lambda copies: None) -> None:
        self.state_dir = state_dir
        self.journal = Journal(state_dir)
        self.streams: List[Tuple[Any, Any]] = []
        self.reliable: List[Bottle] = []
        self.held_for: List[float] = []   # seconds since each came off the link, as journalled
        self.lock = threading.Lock()
        self.here: Any = frozenset()      # the presence this side tells (None: not known)
        self.heard: List[Any] = []        # the peer's presences, as they came
        self.on_presence: Callable[[Any], None] = self.heard.append
        self.on_keys, self.on_copies = on_keys, on_copies
        settings = TcpSettings(side, peer, port, listen, config_text, period, link_timeout=2.0,
                               key=key)
        self.channel = TcpChannel(settings, self.journal, routes, Heard(self))

    def _drain(self) -> None:
        from bridge.wire import compact

        with self.lock:
            for message in self.journal.undelivered():
                row, payload = message.row, message.payload
                self.reliable.append(compact.decode(payload))
                self.held_for.append(time.time() - message.received)
                self.journal.delivered(row)

    def start(self) -> "End":
        self.channel.start()
        return self

    def stop(self) -> None:
        self.channel.stop()
        self.journal.close()


@pytest.fixture
def pair(tmp_path):
    port = free_port()
    ends = []

    def make(**kwargs):
        robot = End("robot", port, tmp_path / "robot", listen=True, **kwargs).start()
        pilot = End("pilot", port, tmp_path / "pilot", listen=False, **kwargs).start()
        ends.extend([robot, pilot])
        wait_until(lambda: robot.channel.connected and pilot.channel.connected, 10,
                   message="link up")
        return robot, pilot

    make.port, make.tmp = port, tmp_path
    make.ends = ends
    yield make
    for end in ends:
        end.stop()


def test_commands_arrive_once_in_order_and_at_once(pair):
    robot, pilot = pair(period=5.0)  # a long period: commands must not wait for it
    started = time.monotonic()
    for index in range(20):
        pilot.channel.send_reliable(SWITCH, Bottle(["start", index + 2]))
    wait_until(lambda: len(robot.reliable) == 20, 5, message="commands")
    assert time.monotonic() - started < 2.0
    assert [b[1] for b in robot.reliable] == list(range(2, 22))
    wait_until(lambda: pilot.journal.waiting() == 0, 5, message="acks")


def test_streams_keep_only_the_latest_value_per_period(pair):
    robot, pilot = pair(period=0.3)
    for index in range(100):
        robot.channel.post(STATUS, Bottle([index + 2, "a"]))
    wait_until(lambda: pilot.streams, 3, message="status")
    time.sleep(0.5)  # the thing under test: more than a period passes and nothing older comes
    assert [value[0] for _, value in pilot.streams] == [101]
    robot.channel.post(STATUS, Bottle([102, "b"]))
    wait_until(lambda: len(pilot.streams) == 2, 3, message="second status")
    assert pilot.streams[-1][1] == Bottle([102, "b"])
    assert robot.channel.stats.payload_out < 20  # the second one went as a 3-byte delta


def test_a_status_event_leaves_at_once_and_a_flood_of_them_is_coalesced(pair):
    robot, pilot = pair(period=30.0)  # no periodic frame within this test
    robot.channel.post(STATUS, Bottle([2, "a", 0.5]))  # data changed only: waits for T
    robot.channel.post(STATUS, Bottle([3, "b", 0.5]), event=True)
    wait_until(lambda: pilot.streams, 3, message="the event")
    assert [value for _, value in pilot.streams] == [Bottle([3, "b", 0.5])]
    for seq in range(4, 104):
        robot.channel.post(STATUS, Bottle([seq, "c", 0.5]), event=True)
    wait_until(lambda: pilot.streams[-1][1][0] == 103, 3, message="the newest event")
    # 100 events posted within a few EVENT_MIN_GAPs: a few sends, never 100.
    assert len(pilot.streams) <= 6, [value[0] for _, value in pilot.streams]
    robot.channel.post(STATUS, Bottle([103, "c", 0.75]))  # not an event
    time.sleep(0.5)  # the thing under test: many gaps pass and it still waits for T
    assert pilot.streams[-1][1] == Bottle([103, "c", 0.5])


def test_bytes_queued_for_a_slow_reader_are_not_taken_for_a_loss():
    from bridge.transport.tcp_channel import _only_unacknowledged, _unsent_bytes

    listener = socket.create_server(("127.0.0.1", 0))
    sender = socket.create_connection(listener.getsockname())
    receiver, _ = listener.accept()
    try:
        sender.sendall(b"x" * 1000)
        wait_until(lambda: _unsent_bytes(sender) == 0, 5, message="acknowledged")
        assert not _only_unacknowledged(sender)        # all acknowledged: nothing lost
        sender.setblocking(False)
        try:                                            # the reader reads nothing: fill the
            while True:                                 # window and our queue behind it
                sender.send(b"x" * 65536)
        except BlockingIOError:
            pass
        assert _unsent_bytes(sender) > 0
        assert not _only_unacknowledged(sender)        # queued, not lost: no nudge
    finally:
        for sock in (sender, receiver, listener):
            sock.close()
    assert not _only_unacknowledged(sender)            # closed: nothing


def wait_for_nudges(end: "End", count: int, what: str) -> None:
    """Until ``end`` has sent ``count`` nudges; else say how many, and its nudge plan."""
    try:
        wait_until(lambda: end.channel.stats.nudges >= count, 15, message=what)
    except WaitTimeout:
        pass
    connection = end.channel._connection
    session = connection.session if connection is not None else None
    plan = vars(session.nudges) if session is not None else "no session"
    assert end.channel.stats.nudges == count, \
        f"{what}: {end.channel.stats.nudges} sent, {count} expected (plan now: {plan}, " \
        f"round trip {end.channel.round_trip_ms()} ms, connected {end.channel.connected})"


def test_an_unacknowledged_event_is_followed_by_empty_frames_and_a_periodic_one_is_not(
        pair, monkeypatch):
    from bridge.transport import tcp_channel
    from bridge.transport.frame_session import NUDGES

    robot, pilot = pair(period=0.1)
    wait_until(lambda: pilot.heard and robot.heard, 3, message="the first words")
    # ... acknowledged, and a frame built since has seen it: no nudge planned.  (A fixed
    # 0.1 s sleep here was too short beside two burners in fc135: the sender built its next
    # frame only after the patch below, took the words for unacknowledged, and nudged 3 times.)
    wait_until(lambda: robot.channel._connection.session.nudges.at == math.inf, 10,
               message="the words' nudges called off")
    monkeypatch.setattr(tcp_channel, "_only_unacknowledged", lambda sock: True)  # never acked
    for seq in range(2, 12):                          # periodic frames only
        robot.channel.post(STATUS, Bottle([seq, "a"]))
        time.sleep(0.05)
    time.sleep(0.5)
    assert robot.channel.stats.nudges == 0
    robot.channel.post(STATUS, Bottle([20, "b"]), event=True)
    # (a bound for a loaded box, not a figure: fc6 beside two burners took over 3 s)
    wait_for_nudges(robot, NUDGES, "the nudges")
    time.sleep(0.5)                                   # the thing under test: no more than that
    assert robot.channel.stats.nudges == NUDGES
    pilot.channel.send_reliable(SWITCH, Bottle(["start", 1]))   # a command is awaited too
    wait_for_nudges(pilot, NUDGES, "the command's nudges")
    monkeypatch.setattr(tcp_channel, "_only_unacknowledged", lambda sock: False)  # acked
    robot.channel.post(STATUS, Bottle([21, "c"]), event=True)
    wait_until(lambda: pilot.streams[-1][1][0] == 21, 3, message="the event")
    time.sleep(0.5)
    assert robot.channel.stats.nudges == NUDGES
    assert robot.reliable == [Bottle(["start", 1])] and robot.channel.connected


def test_presence_is_told_on_each_connection_and_each_change_at_once(pair):
    robot, pilot = pair(period=30.0)  # no periodic frame within this test
    wait_until(lambda: pilot.heard == [frozenset()], 3, message="the first word")
    robot.here = frozenset({STATUS, SWITCH})
    robot.channel.kick()
    wait_until(lambda: pilot.heard[-1] == {STATUS, SWITCH}, 3, message="the change")
    robot.channel.kick()   # nothing changed: nothing said
    robot.channel.post(STATUS, Bottle([2, "a"]), event=True)
    wait_until(lambda: pilot.streams, 3, message="an event frame")
    assert len(pilot.heard) == 2
    robot.channel._drop("test cut")   # a new connection: told again, unchanged
    wait_until(lambda: len(pilot.heard) == 3, 10, message="the word on the new link")
    assert pilot.heard[-1] == {STATUS, SWITCH}
    robot.here = None      # not known (a bridge still connecting to its modules): not said
    robot.channel._drop("test cut")
    wait_until(lambda: robot.channel.connected, 10, message="reconnect")
    robot.channel.post(STATUS, Bottle([3, "b"]), event=True)
    wait_until(lambda: len(pilot.streams) == 2, 3, message="an event frame")
    robot.here = frozenset({SWITCH})
    robot.channel.kick()
    wait_until(lambda: pilot.heard[-1] == {SWITCH}, 3, message="the word once known")
    assert pilot.heard == [frozenset(), {STATUS, SWITCH}, {STATUS, SWITCH}, {SWITCH}]


def test_a_word_is_taken_after_the_messages_of_its_frame(pair):
    robot, pilot = pair(period=30.0)  # no periodic frame: one frame carries both
    wait_until(lambda: pilot.heard, 3, message="the first word")
    seen = []
    pilot.on_presence = lambda flows: seen.append((flows, list(pilot.reliable)))
    robot.here = frozenset({STATUS})             # the module left after its last warning
    robot.channel.send_reliable(SWITCH, Bottle([1, "overheating"]))
    wait_until(lambda: seen, 3, message="the word")
    assert seen == [({STATUS}, [Bottle([1, "overheating"])])]


def test_a_dropped_connection_loses_and_repeats_nothing(pair):
    robot, pilot = pair(period=0.2)
    pilot.channel.send_reliable(SWITCH, Bottle(["start", 2]))
    wait_until(lambda: len(robot.reliable) == 1, 5)
    # Cut the link under the channels' feet, then keep commanding while it is down.
    robot.channel._drop("test cut")
    for index in range(3, 8):
        pilot.channel.send_reliable(SWITCH, Bottle(["turn", index]))
    wait_until(lambda: robot.channel.connected and len(robot.reliable) == 6, 15,
               message="resend after reconnect")
    assert [b[1] for b in robot.reliable] == [2, 3, 4, 5, 6, 7]
    assert robot.channel.stats.connects >= 2


def test_a_restarted_sender_resends_only_what_was_not_accepted(pair):
    robot, pilot = pair(period=0.2)
    for index in range(2, 6):
        pilot.channel.send_reliable(SWITCH, Bottle(["c", index]))
    wait_until(lambda: len(robot.reliable) == 4, 5)
    pilot.channel.stop()  # as if killed before the acks arrived: its journal still has all
    pilot.journal.close()
    fresh = End("pilot", pair.port, pilot.state_dir, listen=False).start()
    pair.ends.append(fresh)
    fresh.channel.send_reliable(SWITCH, Bottle(["c", 6]))
    wait_until(lambda: len(robot.reliable) == 5, 10, message="the new command")
    wait_until(lambda: fresh.journal.waiting() == 0, 5, message="acks")
    # Every resend is acknowledged by now; a duplicate would have been delivered before.
    assert [b[1] for b in robot.reliable] == [2, 3, 4, 5, 6]


def test_a_peer_with_another_configuration_is_refused_by_name(tmp_path):
    port = free_port()
    robot = End("robot", port, tmp_path / "r", listen=True, config_text="one").start()
    pilot = End("pilot", port, tmp_path / "p", listen=False, config_text="two").start()
    try:
        wait_until(lambda: "different bridge configuration" in pilot.channel.stats.last_error,
                   10, message="the refusal")
        assert not pilot.channel.connected
    finally:
        pilot.stop()
        robot.stop()


def test_garbage_and_strangers_do_not_hurt_the_listener(tmp_path):
    port = free_port()
    robot = End("robot", port, tmp_path / "r", listen=True).start()
    try:
        with socket.create_connection(("127.0.0.1", port)) as rogue:
            rogue.sendall(b"\xff" * 64)
            rogue.settimeout(5)
            try:
                while rogue.recv(4096):
                    pass
            except OSError:
                pass
        assert robot.channel.phase == "down"
        pilot = End("pilot", port, tmp_path / "p", listen=False).start()
        wait_until(lambda: pilot.channel.connected, 10, message="the real peer")
        pilot.channel.send_reliable(SWITCH, Bottle(["start", 2]))
        wait_until(lambda: robot.reliable, 5)
        pilot.stop()
    finally:
        robot.stop()
    stranger_port = free_port()
    picky = End("robot", stranger_port, tmp_path / "s", listen=True, peer="127.0.0.2").start()
    try:
        socket.create_connection(("127.0.0.1", stranger_port)).close()
        wait_until(lambda: picky.channel.drops.get(Reason.STRANGER) == 1, 5,
                   message="rejection")
    finally:
        picky.stop()


def test_a_forged_frame_drops_the_connection_and_it_comes_back(pair):
    robot, pilot = pair(period=0.2)
    connection = pilot.channel._connection
    # A frame with a made-up tag, injected into the live stream as an on-path attacker would.
    forged = frames.data_body((frames.Entry(SWITCH.id, SWITCH.kind, b"\x01\x04stop"),), seq=99)
    connection.sock.sendall(frames.wrap(forged, b"\0" * 8))
    wait_until(lambda: robot.channel.drops.get(Reason.FORGED) == 1, 5,
               message="forged frame counted")
    wait_until(lambda: robot.channel.connected and pilot.channel.connected
               and robot.channel.stats.connects >= 2, 10, message="reconnect")
    pilot.channel.send_reliable(SWITCH, Bottle(["after", 2]))
    wait_until(lambda: robot.reliable, 5)


def test_a_peer_with_another_key_is_refused_on_both_sides(tmp_path):
    port = free_port()
    robot = End("robot", port, tmp_path / "r", listen=True).start()
    rogue = End("pilot", port, tmp_path / "p", listen=False,
                key=LinkKey(b"x" * 32, source="rogue")).start()
    try:
        wait_until(lambda: "authentication failed" in rogue.channel.drops.last_error
                   and robot.channel.drops.get(Reason.UNAUTHENTICATED) >= 1, 10,
                   message="both sides refuse")
        assert "does not hold our key" in robot.channel.drops.last_error
        assert not robot.channel.connected and not rogue.channel.connected
        rogue.channel.send_reliable(SWITCH, Bottle(["home", 2]))
        time.sleep(1.0)  # the rogue keeps retrying; nothing may come through meanwhile
        assert robot.reliable == []
    finally:
        rogue.stop()
        robot.stop()


def test_a_keyless_peer_is_named_as_such(tmp_path):
    port = free_port()
    robot = End("robot", port, tmp_path / "r", listen=True).start()
    keyless = End("pilot", port, tmp_path / "p", listen=False, key=LinkKey.none()).start()
    try:
        wait_until(lambda: "runs without a key" in robot.channel.drops.last_error, 10,
                   message="the robot names the keyless peer")
        wait_until(lambda: "we run with --no-auth" in keyless.channel.drops.last_error, 10,
                   message="the keyless peer names itself")
    finally:
        keyless.stop()
        robot.stop()


def test_strangers_can_neither_stall_the_listener_nor_push_the_pilot_off(pair):
    robot, pilot = pair(period=0.2)
    silent = [socket.create_connection(("127.0.0.1", pair.port)) for _ in range(6)]
    try:
        # A rogue that speaks a plausible HELLO but cannot prove the key.
        rogue_link_bytes = frames.wrap(frames.hello_body(frames.Hello(
            "pilot", robot.channel.fingerprint, 1, bytes(16))))
        with socket.create_connection(("127.0.0.1", pair.port)) as rogue:
            rogue.sendall(rogue_link_bytes + frames.wrap(frames.auth_body(frames.Auth(
                bytes(16)))))
            wait_until(lambda: robot.channel.drops.get(Reason.UNAUTHENTICATED) >= 1
                       or robot.channel.drops.get(Reason.BUSY) >= 1, 10,
                       message="the rogue refused")
        # The real pilot still commands, and its connection was never replaced.
        connects = robot.channel.stats.connects
        pilot.channel.send_reliable(SWITCH, Bottle(["start", 2]))
        wait_until(lambda: len(robot.reliable) == 1, 5, message="the pilot's command")
        assert robot.channel.stats.connects == connects and robot.channel.connected
    finally:
        for sock in silent:
            sock.close()


def test_a_recorded_connection_replayed_is_refused(pair, tmp_path):
    robot, pilot = pair(period=0.2)
    pilot.stop()  # the recording pilot below takes its place
    # Record what a pilot sends on a fresh connection, through a recording proxy.
    captured = bytearray()
    proxy = socket.socket()
    proxy.bind(("127.0.0.1", 0))
    proxy.listen(1)
    recorder = End("pilot", proxy.getsockname()[1], tmp_path / "rec", listen=False)

    done = threading.Event()

    def relay() -> None:
        inbound, _ = proxy.accept()
        outbound = socket.create_connection(("127.0.0.1", pair.port))
        ends = {inbound: (outbound, True), outbound: (inbound, False)}
        try:
            while not done.is_set():
                readable, _, _ = select.select(list(ends), [], [], 0.1)
                for src in readable:
                    dst, record = ends[src]
                    data = src.recv(65536)
                    if not data:
                        return
                    dst.sendall(data)
                    if record:
                        captured.extend(data)
        except OSError:
            pass
        finally:
            inbound.close()
            outbound.close()

    thread = threading.Thread(target=relay, daemon=True)
    thread.start()
    recorder.start()
    recorder.channel.send_reliable(SWITCH, Bottle(["recorded", 2]))
    wait_until(lambda: any(b[0] == "recorded" for b in robot.reliable), 15,
               message="the recorded command arrives once")
    done.set()
    thread.join()
    recorder.stop()
    before = len(robot.reliable)
    with socket.create_connection(("127.0.0.1", pair.port)) as replay:
        replay.sendall(bytes(captured))
        wait_until(lambda: robot.channel.drops.get(Reason.UNAUTHENTICATED) >= 1, 10,
                   message="the replay refused")
    assert len(robot.reliable) == before


def test_frames_sharing_a_read_with_the_handshake_are_not_lost(tmp_path):
    """The pilot's link is up once it sent its RESUME, and it sends what it queued at once:
    when the robot is slow to read, that RESUME and the first data frame come in one read.
    The robot used to return from its handshake on the RESUME and drop the frame: the
    commands were lost until the next reconnect (seen as a 1-in-7 flake of the 30 s cut
    test after the robot bridge was restarted)."""
    port = free_port()
    robot = End("robot", port, tmp_path / "robot", listen=True)
    keys_hook = robot.channel._keys_hook

    def slow_after_resume(event, link):
        keys_hook(event, link)
        if event == "offered":          # the robot's RESUME is out: dawdle before reading
            time.sleep(0.5)

    robot.channel._keys_hook = slow_after_resume
    pilot = End("pilot", port, tmp_path / "pilot", listen=False)
    for index in range(3):              # queued before the link is up: sent once it is
        pilot.channel.send_reliable(SWITCH, Bottle(["c", index]))
    try:
        robot.start()
        pilot.start()
        wait_until(lambda: len(robot.reliable) == 3, 10, message="the queued commands")
        assert [b[1] for b in robot.reliable] == [0, 1, 2]
    finally:
        pilot.stop()
        robot.stop()


def test_the_backlog_of_a_socket_closed_by_the_receive_thread_is_nothing():
    """The sender asks the kernel for the backlog while the receive thread may have closed
    the socket (the peer died): that is no backlog, not an exception."""
    from bridge.transport.tcp_channel import _unsent_bytes

    left, right = socket.socketpair()
    left.sendall(b"x" * 10)
    assert _unsent_bytes(left) > 0        # the peer has not read them: a backlog
    left.close()
    right.close()
    assert _unsent_bytes(left) == 0


def test_a_command_held_while_the_link_is_down_leaves_older_by_that_time(tmp_path):
    """The pilot side adds the time a command sat in its journal to the command's lifetime:
    the module measures a blackout it never saw (walkman.gym.validity)."""
    from walkman.gym.validity import Lifetime, split, stamp

    port = free_port()
    pilot = End("pilot", port, tmp_path / "pilot", listen=False).start()
    robot = None
    try:
        pilot.channel.send_reliable(COMMAND, stamp(Bottle(["go", 2]), Lifetime(0.5, 60.0)))
        held = time.monotonic()
        wait_until(lambda: time.monotonic() - held >= 1.0, 5, message="a second of outage")
        robot = End("robot", port, tmp_path / "robot", listen=True).start()
        wait_until(lambda: robot.reliable, 10, message="the command delivered")
        message, lifetime = split(robot.reliable[0])
        assert message == Bottle(["go", 2])
        assert lifetime.validity == 60.0 and lifetime.age >= 1.5
    finally:
        pilot.stop()
        if robot is not None:
            robot.stop()


class _MeetingJournal:
    """A journal whose first two peer RESUMEs wait for ``go``: two handshake threads then
    finish at the same moment."""

    def __init__(self, journal: Journal) -> None:
        self._journal = journal
        self._count = threading.Lock()
        self.waiting = 0
        self.go = threading.Event()

    def acknowledge(self, upto: int) -> int:
        with self._count:
            self.waiting += 1
            first_two = self.waiting <= 2
        if first_two:
            self.go.wait(5)
        return self._journal.acknowledge(upto)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._journal, name)


def _handshakes_look_slowly_at_the_link(monkeypatch) -> None:
    """A handshake thread pauses whenever it reads the channel's current connection.

    Between a handshake thread reading it and installing its own connection lie a few
    bytecodes, too few for a test to hit by chance; the pause widens them.  Where the read
    and the install are one step under the lock, the pause only makes the other wait."""
    def read(channel: TcpChannel) -> Any:
        connection = channel.__dict__.get("_test_connection")
        if threading.current_thread().name == "bridge tcp handshake":
            time.sleep(0.1)           # ... and acts on what it read, however stale
        return connection

    def write(channel: TcpChannel, value: Any) -> None:
        channel.__dict__["_test_connection"] = value

    monkeypatch.setattr(TcpChannel, "_connection", property(read, write), raising=False)


def _dial_as_pilot(port: int, config_text: str = "config") -> Tuple[socket.socket, Any]:
    """A pilot's end of the link protocol, by hand: up once both RESUMEs are through."""
    from bridge.transport.tcp_channel import fingerprint
    from bridge.wire.link import LinkConnection, PeerAuthenticated, PeerHello

    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    link = LinkConnection("pilot", KEY, fingerprint(config_text), 0x9170)
    sock.sendall(link.start())
    while not link.established:
        data = sock.recv(4096)
        assert data, "the robot closed during the handshake"
        for event in link.receive_data(data):
            if isinstance(event, PeerHello):
                sock.sendall(link.send_auth())
            elif isinstance(event, PeerAuthenticated):
                sock.sendall(link.send_resume(0))
    return sock, link


def _closed_by_peer(sock: socket.socket, within: float) -> bool:
    """Does the robot close ``sock`` within ``within`` s (its frames read meanwhile)?"""
    deadline = time.monotonic() + within
    try:
        while time.monotonic() < deadline:
            sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                if not sock.recv(65536):
                    return True
            except socket.timeout:
                pass
    except OSError:
        return True
    return False


def test_two_handshakes_ending_together_leave_one_link_and_no_leaked_socket(tmp_path,
                                                                           monkeypatch):
    """Two connections proven at the same moment: one becomes the link, the other is
    closed.  The old channel read its link and moved its phase outside its lock: the
    second thread found no link either, installed itself over the first without closing
    it (a leaked socket, whose receive thread went on), then died on an illegal phase move
    before starting its own receive thread -- a link "up" that received nothing."""
    crashed: List[Any] = []
    monkeypatch.setattr(threading, "excepthook", crashed.append)
    _handshakes_look_slowly_at_the_link(monkeypatch)
    port = free_port()
    robot = End("robot", port, tmp_path / "robot", listen=True)
    meeting = robot.channel.journal = _MeetingJournal(robot.journal)
    robot.start()
    clients: List[Tuple[socket.socket, Any]] = []
    try:
        dialers = [threading.Thread(target=lambda: clients.append(_dial_as_pilot(port)))
                   for _ in range(2)]
        for dialer in dialers:
            dialer.start()
        wait_until(lambda: meeting.waiting == 2, 10, message="both handshakes at their end")
        meeting.go.set()
        for dialer in dialers:
            dialer.join(15)
        assert len(clients) == 2, "both handshakes completed"
        wait_until(lambda: robot.channel.stats.connects == 2 or crashed, 5,
                   message="both installed")
        closed = [_closed_by_peer(sock, 1.0) for sock, _ in clients]
        assert crashed == [] and robot.channel.stats.internal_errors == 0
        assert sorted(closed) == [False, True], closed
        assert robot.channel.phase == "up"
        sock, link = clients[closed.index(False)]
        command = frames.Entry(SWITCH.id, SWITCH.kind, compact.encode(Bottle(["start", 2])))
        sock.sendall(link.send_data(frames.data_body((command,), seq=1)))
        wait_until(lambda: robot.reliable == [Bottle(["start", 2])], 5,
                   message="the link's command")
    finally:
        for sock, _ in clients:
            sock.close()
        robot.stop()
