"""The frame session without sockets: acks, resends, duplicates, deltas, events, nudges.

Two sessions face each other over in-memory queues (the journal's outbox and inbox);
the time is an argument.  The channel's threads and sockets around a session are
tested in test_tcp_channel.py, the link that seals its frames in test_link.py.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Dict, List, Optional, Tuple

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.flows import Carriage, FlowKey, Form, Route
from bridge.gym.expiry import aged_payload
from bridge.transport import drops, frame_session
from bridge.transport.copies import ReliableCopy
from bridge.transport.drops import Reason
from bridge.transport.frame_session import (DELAYED_ACK, EVENT_MIN_GAP, KEEPALIVE,
                                            MAX_RELIABLE_PER_FRAME, NUDGE_AFTER, NUDGES,
                                            Acknowledged, Dropped, Due, FrameSession, KernelQueue,
                                            Nudges, PresenceHeard, ReliableAccepted, Streams,
                                            StreamValue)
from bridge.transport.journal import Journal, Queued
from bridge.wire import compact, frames
from bridge.wire.frames import DataFrame, Entry
from bridge.wire.link import (FrameReceived, LinkConnection, LinkKey, LinkUp,
                              PeerAuthenticated, PeerHello)
from bridge.wire.state_codec import Layout, RobotState
from bridge.wire.transit import stamp as clock_stamp
from codec_helpers import FUZZ, bottle_values
from walkman.gym.validity import Lifetime, split, stamp
from yarp_lite.bottle import Bottle

SWITCH, COMMAND, STATUS, STATE = FlowKey(7, 0), FlowKey(7, 1), FlowKey(7, 2), FlowKey(9, 0)
STOP = FlowKey(250, 0)
ROUTES = {route.key: route for route in [
    Route(SWITCH, "gaze_control/switch", Carriage.RELIABLE, Form.BOTTLE),
    Route(COMMAND, "gaze_control/command", Carriage.RELIABLE, Form.BOTTLE, expiring=True),
    Route(STATUS, "gaze_control/status", Carriage.LATEST, Form.BOTTLE, status_events=True),
    Route(STATE, "walkman/state", Carriage.LATEST, Form.STATE),
    Route(STOP, "stop_all", Carriage.URGENT, Form.BOTTLE)]}
PERIOD = 0.5
WALL = 1000.0
NOTHING: frozenset = frozenset()      # no streaming flow: only what the outbox owes
LAYOUT = Layout((("torso", ("t0", "t1", "t2")), ("head", ("h0", "h1"))))


class MemoryQueues:
    """The journal's outbox and inbox in memory, with its rules (the session's Queues)."""

    def __init__(self, session: int) -> None:
        self.session = session
        self.outbox: Dict[int, Queued] = {}
        self.last_seq = 0
        self.peers: Dict[int, int] = {}
        self.inbox: List[Tuple[FlowKey, bytes]] = []
        self.late: List[float] = []         # seconds each message's frame came late

    def append(self, key: FlowKey, bottle: Bottle, queued: float = WALL) -> int:
        self.last_seq += 1
        self.outbox[self.last_seq] = Queued(self.last_seq, key.id, key.kind,
                                            compact.encode(bottle), queued)
        return self.last_seq

    def unacknowledged(self, after: int = 0, limit: int = 1 << 30) -> List[Queued]:
        return [self.outbox[seq] for seq in sorted(self.outbox) if seq > after][:limit]

    def acknowledge(self, upto: int) -> int:
        if upto > self.last_seq:
            raise BridgeProtocolError(f"peer acknowledges {upto} of {self.last_seq}")
        gone = [seq for seq in self.outbox if seq <= upto]
        for seq in gone:
            del self.outbox[seq]
        return len(gone)

    def accepted(self, session: int) -> int:
        return self.peers.get(session, 0)

    def accept(self, session: int, seq: int, ident: int, kind: int, payload: bytes,
               late_by: float = 0.0) -> bool:
        accepted = self.peers.get(session)
        if seq <= (accepted or 0):
            return False
        if accepted is not None and seq != accepted + 1:
            raise BridgeProtocolError(f"reliable message {seq} arrives after {accepted}")
        self.peers[session] = seq
        self.inbox.append((FlowKey(ident, kind), payload))
        self.late.append(late_by)
        return True

    def received(self) -> List[Bottle]:
        return [compact.decode(payload) for _, payload in self.inbox]


class End:
    """One bridge's side: its queues, its streams, its session on the current connection."""

    def __init__(self, journal_session: int, queues=None, routes=ROUTES) -> None:
        self.queues = queues if queues is not None else MemoryQueues(journal_session)
        self.routes = routes
        self.streams = Streams(PERIOD, 0.0)
        self.session: Optional[FrameSession] = None
        self.presence: Optional[frozenset] = frozenset()

    def open(self, peer: "End") -> FrameSession:
        self.session = FrameSession(self.queues, self.routes, self.streams, peer.queues.session,
                                    period=PERIOD, age=aged_payload)
        self.streams.restart()
        return self.session

    def frame(self, now: float, streams=NOTHING, kernel: KernelQueue = KernelQueue(),
              wall: float = WALL) -> frame_session.Outgoing:
        """The frame at ``now``; ``streams`` the flows to send, or what
        :meth:`Streams.due` said (a :class:`Due`: its flows and events)."""
        assert self.session is not None
        due = streams if isinstance(streams, Due) else Due(streams, streams or frozenset())
        return self.session.next_frame(now, wall=wall, due=due, presence=self.presence,
                                       kernel=kernel)


def connect(robot: End, pilot: End) -> None:
    """A new connection: both RESUMEs through (what the handshake carries)."""
    robot_session, pilot_session = robot.open(pilot), pilot.open(robot)
    robot_point, pilot_point = robot_session.resume_point(), pilot_session.resume_point()
    robot_session.peer_resumed(pilot_point)
    pilot_session.peer_resumed(robot_point)


def send(sender: End, receiver: End, now: float = 0.0, streams=NOTHING, **kwargs) -> list:
    """One frame from ``sender``, if it has one, received whole; its events."""
    out = sender.frame(now, streams, **kwargs)
    assert receiver.session is not None
    return [] if out.body is None else receiver.session.receive_body(out.body)


@pytest.fixture
def ends() -> Tuple[End, End]:
    robot, pilot = End(0x70B07), End(0x9170)
    connect(robot, pilot)
    return robot, pilot


# -- reliable messages ----------------------------------------------------------------------


def test_commands_cross_once_in_order_and_the_ack_frees_the_outbox(ends):
    robot, pilot = ends
    send(pilot, robot)                       # the first words (presence)
    send(robot, pilot)
    for index in range(3):
        pilot.queues.append(SWITCH, Bottle(["start", index]))
    events = send(pilot, robot, now=0.1)
    assert events == [ReliableAccepted(SWITCH, 1), ReliableAccepted(SWITCH, 2),
                      ReliableAccepted(SWITCH, 3)]
    assert robot.queues.received() == [Bottle(["start", index]) for index in range(3)]
    assert send(pilot, robot, now=0.2) == []           # sent: not again, nothing else to say
    assert send(robot, pilot, now=0.2) == [Acknowledged(3)]
    assert pilot.queues.outbox == {}
    assert send(robot, pilot, now=0.3) == []           # the ack is told once


def test_a_new_connection_resends_only_what_the_peer_lacks(tmp_path):
    robot, pilot = End(0, Journal(tmp_path / "robot")), End(0, Journal(tmp_path / "pilot"))
    pilot.presence = None                             # only the commands in these frames
    connect(robot, pilot)
    for index in range(2):
        pilot.queues.append(SWITCH.id, SWITCH.kind, compact.encode(Bottle(["c", index])))
    first = pilot.frame(0.0).body
    robot.session.receive_body(first)                  # accepted; the ack never comes back
    for index in range(2, 4):
        pilot.queues.append(SWITCH.id, SWITCH.kind, compact.encode(Bottle(["c", index])))
    connect(robot, pilot)                             # the link was cut and came back
    assert len(pilot.queues.unacknowledged()) == 2     # the peer's RESUME said 2
    events = send(pilot, robot, now=1.0)
    assert [event for event in events if isinstance(event, ReliableAccepted)] == \
        [ReliableAccepted(SWITCH, 3), ReliableAccepted(SWITCH, 4)]
    # The old frame, replayed into the new connection, is two duplicates.
    assert robot.session.receive_body(first) == [
        Dropped(Reason.DUPLICATE, "gaze_control/switch #1"),
        Dropped(Reason.DUPLICATE, "gaze_control/switch #2")]
    assert [compact.decode(m.payload)[1] for m in robot.queues.undelivered()] == [0, 1, 2, 3]
    robot.queues.close()
    pilot.queues.close()


def test_a_gap_an_unnumbered_entry_and_an_ack_of_nothing_are_the_peers_error(ends):
    robot, _ = ends
    payload = compact.encode(Bottle(["c"]))
    robot.session.receive(DataFrame((Entry(7, 0, payload),), seq=1))
    with pytest.raises(BridgeProtocolError, match="3 arrives after 1"):
        robot.session.receive(DataFrame((Entry(7, 0, payload),), seq=3))
    with pytest.raises(BridgeProtocolError, match="switch without a sequence number"):
        robot.session.receive(DataFrame((Entry(7, 0, payload),)))
    with pytest.raises(BridgeProtocolError, match="switch without a sequence number"):
        robot.session.receive(DataFrame((Entry(7, 0, payload, delta=True),), seq=2))
    with pytest.raises(BridgeProtocolError, match="acknowledges 5"):
        robot.session.receive(DataFrame(ack=5))
    with pytest.raises(BridgeProtocolError):
        robot.session.receive(DataFrame((Entry(7, 0, b"\xff\xff"),), seq=2))  # not a Bottle
    assert robot.queues.received() == [Bottle(["c"])]


def test_an_expiring_command_leaves_older_by_its_time_in_the_outbox(ends):
    robot, pilot = ends
    pilot.queues.append(COMMAND, stamp(Bottle(["go"]), Lifetime(0.5, 60.0)), queued=WALL)
    pilot.queues.append(SWITCH, Bottle(["start"]), queued=WALL)
    send(pilot, robot, wall=WALL + 2.0)
    (command, switch) = robot.queues.received()
    assert split(command) == (Bottle(["go"]), Lifetime(2.5, 60.0))
    assert switch == Bottle(["start"])                 # not expiring: untouched


COPIED = {**ROUTES, COMMAND: dataclasses.replace(ROUTES[COMMAND], copies=2)}


@pytest.fixture
def copied() -> Tuple[End, End]:
    """Ends whose commands also go as datagram copies (bridge.transport.copies)."""
    robot, pilot = End(0x70B07, routes=COPIED), End(0x9170, routes=COPIED)
    pilot.presence = None                             # only the commands in these frames
    connect(robot, pilot)
    return robot, pilot


def test_a_frame_names_its_copied_messages_as_sent_and_no_others(copied):
    robot, pilot = copied
    pilot.queues.append(COMMAND, stamp(Bottle(["go"]), Lifetime(0.5, 60.0)), queued=WALL)
    pilot.queues.append(SWITCH, Bottle(["start"]), queued=WALL)
    out = pilot.frame(0.0, wall=WALL + 2.0)
    ((key, seq, payload),) = out.copies
    assert (key, seq) == (COMMAND, 1)
    assert split(compact.decode(payload)) == (Bottle(["go"]), Lifetime(2.5, 60.0))  # aged
    robot.session.receive_body(out.body)
    assert robot.queues.received()[0] == compact.decode(payload)   # the frame's own bytes
    assert pilot.frame(0.1).copies == ()       # sent once: no copy without its frame


def test_the_first_of_copy_and_frame_is_journalled_and_the_other_is_no_drop(copied):
    robot, pilot = copied
    pilot.queues.append(COMMAND, Bottle(["one"]))
    pilot.queues.append(COMMAND, Bottle(["two"]))
    out = pilot.frame(0.0)
    (_, _, first), (_, _, second) = out.copies
    copy = lambda seq, payload: ReliableCopy(pilot.queues.session, seq, payload)  # noqa: E731
    assert robot.session.accept_copy(COMMAND, copy(2, second)) is None   # ahead of a gap
    assert robot.session.accept_copy(COMMAND, copy(1, first)) == ReliableAccepted(COMMAND, 1)
    assert robot.session.accept_copy(COMMAND, copy(1, first)) is None    # the second copy
    assert robot.session.receive_body(out.body) == [ReliableAccepted(COMMAND, 2)]  # no drop
    assert robot.session.accept_copy(COMMAND, copy(2, second)) is None   # its frame was first
    assert [split(m)[0] for m in robot.queues.received()] == [Bottle(["one"]),
                                                                 Bottle(["two"])]
    assert robot.session.stats.reliable_by_copy == 1


def test_a_copy_of_another_session_or_flow_is_not_taken(copied):
    robot, pilot = copied
    pilot.queues.append(COMMAND, Bottle(["one"]))
    pilot.queues.append(SWITCH, Bottle(["start"]))
    payload = compact.encode(Bottle(["one"]))
    assert robot.session.accept_copy(COMMAND, ReliableCopy(0xBAD, 1, payload)) is None
    assert robot.session.accept_copy(SWITCH, ReliableCopy(pilot.queues.session, 1,
                                                          payload)) is None  # not copied
    with pytest.raises(BridgeProtocolError):
        robot.session.accept_copy(COMMAND, ReliableCopy(pilot.queues.session, 1, b"\xff\xff"))
    assert robot.queues.received() == []


def test_a_full_outbox_asks_for_the_next_frame_at_once(ends):
    robot, pilot = ends
    for index in range(MAX_RELIABLE_PER_FRAME + 10):
        pilot.queues.append(SWITCH, Bottle([index]))
    first = pilot.frame(0.0)
    assert first.more and first.awaited
    second = pilot.frame(0.0)
    assert not second.more
    for out in (first, second):
        robot.session.receive_body(out.body)
    assert len(robot.queues.inbox) == MAX_RELIABLE_PER_FRAME + 10


# -- streaming values ---------------------------------------------------------------------


def test_streams_go_as_deltas_and_start_over_on_each_connection(ends):
    robot, pilot = ends
    robot.streams.post(STATUS, Bottle([2, "walking", 0.5]))
    assert send(robot, pilot, streams=None) == [StreamValue(STATUS, Bottle([2, "walking", 0.5])),
                                               PresenceHeard(frozenset())]
    robot.streams.post(STATUS, Bottle([3, "walking", 0.5]))
    frame = frames.parse_body(robot.frame(0.1, None).body)
    (entry,) = frame.entries
    assert entry.delta and len(entry.payload) < len(compact.encode(Bottle([3, "walking", 0.5])))
    assert pilot.session.receive(frame) == [StreamValue(STATUS, Bottle([3, "walking", 0.5]))]
    assert robot.frame(0.2, None).body is None         # unchanged: not sent again
    connect(robot, pilot)                             # a new connection: in full again
    (entry,) = frames.parse_body(robot.frame(1.0, None).body).entries
    assert not entry.delta
    assert compact.decode(entry.payload) == Bottle([3, "walking", 0.5])


def test_a_delta_before_a_full_value_and_unknown_flows(ends):
    robot, _ = ends
    assert robot.session.receive(DataFrame((Entry(200, 3, b"x"),))) == \
        [Dropped(Reason.UNKNOWN_ID, "entry id 200 kind 3")]
    with pytest.raises(BridgeProtocolError, match="gaze_control/status: a delta before any"):
        robot.session.receive(DataFrame((Entry(7, 2, b"\x00", delta=True),)))


def test_the_robot_state_crosses_in_its_codec_and_a_lazy_value_is_read_when_sent(ends):
    robot, pilot = ends
    reads = []

    def snapshot() -> RobotState:
        reads.append(1)
        return RobotState(LAYOUT, 1.0, np.linspace(-1, 1, 5), np.full(5, 3.0),
                          np.full(5, 40.0))

    robot.streams.post(STATE, snapshot)
    assert reads == []
    (event, _) = send(robot, pilot, streams=None)
    assert reads == [1] and event.key == STATE
    assert np.allclose(event.value.q, np.linspace(-1, 1, 5), atol=1e-3)


def test_a_backlog_holds_streaming_values_back_but_not_commands(ends):
    robot, pilot = ends
    robot.streams.post(STATUS, Bottle([2, "a"]))
    robot.queues.append(SWITCH, Bottle(["warning"]))
    slow = KernelQueue(unsent=drops.BACKLOG_LIMIT + 1)
    out = robot.frame(0.0, None, kernel=slow)
    assert out.held_back == drops.BACKLOG_LIMIT + 1
    assert [type(e) for e in pilot.session.receive_body(out.body)] == \
        [ReliableAccepted, PresenceHeard]
    assert send(robot, pilot, 0.1, None) == [StreamValue(STATUS, Bottle([2, "a"]))]


@pytest.mark.parametrize("slow, held", [
    (KernelQueue(unsent=drops.BACKLOG_LIMIT + 1), drops.BACKLOG_LIMIT + 1),
    # the link budget's radio queue is full (bridge.transport.link_budget), the kernel not
    (KernelQueue(unsent=0, radio_queued=400, radio_full=True), 400)])
def test_a_backlog_never_holds_back_the_stop_all(ends, slow, held):
    robot, pilot = ends
    robot.streams.post(STATUS, Bottle([2, "a"]))
    robot.streams.post(STOP, Bottle(["stop_all", 42]), event=True)
    out = robot.frame(0.0, None, kernel=slow)
    assert out.held_back == held
    assert [e for e in pilot.session.receive_body(out.body) if isinstance(e, StreamValue)] \
        == [StreamValue(STOP, Bottle(["stop_all", 42]))]                # the status waits
    assert send(robot, pilot, 0.1, None) == [StreamValue(STATUS, Bottle([2, "a"]))]


def test_events_leave_at_once_at_most_once_per_gap_and_with_the_periodic_frame():
    streams = Streams(PERIOD, 0.0)
    assert streams.wake_at() == PERIOD
    assert streams.post(STATUS, Bottle([1]), event=True)          # a first event: due now
    assert not streams.post(STATUS, Bottle([2]), event=True)      # coalesced with it
    assert streams.due(0.01) == Due({STATUS}, {STATUS})
    assert streams.take({STATUS}) == [(STATUS, Bottle([2]))]
    assert streams.post(STATUS, Bottle([3]), event=True)
    assert streams.wake_at() == pytest.approx(0.01 + EVENT_MIN_GAP)  # one gap after the last
    assert streams.due(0.02) == Due(frozenset(), frozenset())
    assert streams.due(0.01 + EVENT_MIN_GAP) == Due({STATUS}, {STATUS})
    streams.post(STATUS, Bottle([4]))                             # a change, not an event
    assert streams.due(0.2) == Due(frozenset()) and streams.take(frozenset()) == []
    assert streams.post(STATUS, Bottle([5]), event=True)
    assert streams.due(PERIOD) == Due(None, {STATUS})   # the tick takes it along, an event
    assert streams.take(None) == [(STATUS, Bottle([5]))]
    assert streams.wake_at() == 2 * PERIOD
    assert streams.due(10.0) == Due(None) and streams.wake_at() == 10.0  # late: no burst


def test_an_event_frame_is_awaited_and_a_periodic_one_is_not(ends):
    robot, pilot = ends
    send(robot, pilot)                                 # the first word (presence): awaited
    robot.streams.post(STATUS, Bottle([1]))
    assert not robot.frame(0.1, None).awaited
    robot.streams.post(STATUS, Bottle([2]), event=True)
    assert robot.frame(0.2, robot.streams.due(0.2)).awaited


def test_an_event_that_rides_with_the_periodic_frame_is_awaited_too(ends):
    """A sender late for both the tick and an event (a loaded machine) sends one frame:
    the pilot waits for it all the same, so it is nudged (fc3 of 2026-11-27: 0 nudges)."""
    robot, pilot = ends
    send(robot, pilot)
    robot.streams.post(STATUS, Bottle([1]))
    robot.streams.post(STATUS, Bottle([2]), event=True)
    due = robot.streams.due(PERIOD + 0.5)
    assert due.flows is None
    out = robot.frame(PERIOD + 0.5, due)
    assert out.awaited and robot.session.nudge_at < math.inf
    assert [e.value for e in pilot.session.receive_body(out.body)
            if isinstance(e, StreamValue)] == [Bottle([2])]


# -- presence, nudges, keepalive ------------------------------------------------------------


def test_presence_is_said_once_per_change_and_after_the_messages_of_its_frame(ends):
    robot, pilot = ends
    robot.presence = None                              # not known yet: not said
    assert robot.frame(0.0).body is not None           # (the first frame still goes)
    robot.presence = frozenset({STATUS})
    robot.queues.append(SWITCH, Bottle(["last warning"]))
    assert send(robot, pilot, 0.1) == [ReliableAccepted(SWITCH, 1),
                                       PresenceHeard(frozenset({STATUS}))]
    assert send(robot, pilot, 0.2) == []               # unchanged: not said again
    connect(robot, pilot)
    assert send(robot, pilot, 0.3) == [PresenceHeard(frozenset({STATUS}))]  # new connection


def test_nudges_follow_an_awaited_frame_while_it_is_unacknowledged():
    nudges = Nudges()
    assert nudges.at == math.inf                       # nothing sent: nothing planned
    nudges.awaited_frame_sent(10.0)
    assert nudges.at == pytest.approx(10.0 + NUDGE_AFTER)
    sent = []
    while nudges.at < math.inf:
        now = nudges.at
        if nudges.take(now, unacknowledged=True):
            sent.append(now)
    assert len(sent) == NUDGES
    gaps = [b - a for a, b in zip([10.0, *sent], sent)]
    assert gaps == pytest.approx([NUDGE_AFTER * 2 ** i for i in range(NUDGES)])
    nudges.awaited_frame_sent(20.0)                    # acknowledged by the first look:
    assert not nudges.take(nudges.at, unacknowledged=False)
    assert nudges.at == math.inf                       # no more
    nudges.awaited_frame_sent(30.0, round_trip=0.2)    # a slow link: a round trip and the
    assert nudges.at == pytest.approx(30.0 + 0.2 + DELAYED_ACK)  # delayed ACK


def test_a_session_nudges_with_empty_frames_only_while_bytes_are_unacknowledged(ends):
    robot, pilot = ends
    lost = KernelQueue(only_unacknowledged=True)
    robot.queues.append(SWITCH, Bottle(["warning"]))
    assert robot.frame(0.0, kernel=lost).awaited
    at = robot.session.nudge_at
    assert at == pytest.approx(NUDGE_AFTER)
    assert robot.frame(at - 0.001, kernel=lost).body is None      # not yet
    empties, times = [], []
    while robot.session.nudge_at < math.inf:
        times.append(robot.session.nudge_at)
        out = robot.frame(times[-1], kernel=lost)
        empties.append(frames.parse_body(out.body))
    assert empties == [DataFrame(clock=clock_stamp(at)) for at in times]   # nothing but the clock
    assert len(empties) == NUDGES
    assert robot.session.stats.nudges == NUDGES
    robot.queues.append(SWITCH, Bottle(["another"]))
    robot.frame(1.0, kernel=KernelQueue(round_trip=0.3))
    assert robot.session.nudge_at == pytest.approx(1.0 + 0.3 + DELAYED_ACK)
    assert robot.frame(1.5, kernel=KernelQueue()).body is None    # acknowledged: no nudge
    assert robot.session.nudge_at == math.inf and robot.session.stats.nudges == NUDGES


def test_an_empty_frame_says_we_are_alive_after_a_second_of_silence(ends):
    robot, _ = ends
    assert robot.frame(0.0).body is not None           # the first word
    assert robot.frame(KEEPALIVE - 0.01).body is None
    assert frames.parse_body(robot.frame(KEEPALIVE).body) == DataFrame(clock=clock_stamp(KEEPALIVE))


# -- misuse and bad input -------------------------------------------------------------------


def test_a_session_is_used_only_between_both_resumes():
    robot, pilot = End(1), End(2)
    session = robot.open(pilot)
    with pytest.raises(BridgeUsageError, match="before both RESUMEs"):
        session.receive(DataFrame())
    session.resume_point()
    with pytest.raises(BridgeUsageError, match="already made"):
        session.resume_point()
    with pytest.raises(BridgeUsageError, match="before both RESUMEs"):
        session.next_frame(0.0, wall=WALL)
    session.peer_resumed(0)
    with pytest.raises(BridgeUsageError, match="already taken"):
        session.peer_resumed(0)
    with pytest.raises(BridgeProtocolError, match="Resume frame after the handshake"):
        session.receive_body(frames.resume_body(frames.Resume(3)))


def _linked(robot: End, pilot: End) -> Tuple[LinkConnection, LinkConnection]:
    """Both links through their handshake fed one byte at a time, RESUMEs from the sessions."""
    key = LinkKey(bytes(range(32)))
    links = {"robot": LinkConnection("robot", key, b"config!!", robot.queues.session),
             "pilot": LinkConnection("pilot", key, b"config!!", pilot.queues.session)}
    ends = {"robot": robot, "pilot": pilot}
    for name in links:
        ends[name].open(ends["pilot" if name == "robot" else "robot"])
    wires = {name: links[name].start() for name in links}
    while any(wires.values()):
        for sender, receiver in (("robot", "pilot"), ("pilot", "robot")):
            data, wires[sender] = wires[sender], b""
            for index in range(len(data)):
                for event in links[receiver].receive_data(data[index:index + 1]):
                    if isinstance(event, PeerHello):
                        wires[receiver] += links[receiver].send_auth()
                    elif isinstance(event, PeerAuthenticated):
                        point = ends[receiver].session.resume_point()
                        wires[receiver] += links[receiver].send_resume(point)
                    elif isinstance(event, LinkUp):
                        ends[receiver].session.peer_resumed(event.peer_accepted)
    return links["robot"], links["pilot"]


def test_sealed_frames_fed_one_byte_at_a_time_give_the_same_events(tmp_path):
    robot, pilot = End(0x70B07), End(0x9170)
    pilot.queues.append(SWITCH, Bottle(["c", 1]))
    robot.queues.append(SWITCH, Bottle(["warning"]))
    robot_link, pilot_link = _linked(robot, pilot)
    robot.streams.post(STATUS, Bottle([2, "a"]))
    wire = robot_link.send_data(robot.frame(0.0, None).body)
    robot.streams.post(STATUS, Bottle([3, "a"]))
    wire += robot_link.send_data(robot.frame(0.1, None).body)
    events = []
    for index in range(len(wire)):
        for event in pilot_link.receive_data(wire[index:index + 1]):
            assert isinstance(event, FrameReceived)
            events += pilot.session.receive(event.frame)
    assert events == [ReliableAccepted(SWITCH, 1), StreamValue(STATUS, Bottle([2, "a"])),
                      PresenceHeard(frozenset()), StreamValue(STATUS, Bottle([3, "a"]))]
    (event,) = robot_link.receive_data(pilot_link.send_data(pilot.frame(0.2).body))
    assert robot.session.receive(event.frame)[:2] == [Acknowledged(1),
                                                      ReliableAccepted(SWITCH, 1)]


def _up_session() -> FrameSession:
    robot, pilot = End(1), End(2)
    for index in range(5):
        robot.queues.append(SWITCH, Bottle([index]))
    connect(robot, pilot)
    return robot.session


@FUZZ
@given(st.sampled_from([0x00, 0x01, 0x02, 0x03, 0x20, 0x23]), st.binary(max_size=200))
def test_any_body_gives_events_or_the_peer_error(flags, data):
    session = _up_session()
    for body in (bytes([flags]) + data, data):
        try:
            session.receive_body(body)
        except BridgeProtocolError:
            pass


entries = st.builds(Entry, st.sampled_from([7, 9, 200]), st.integers(0, 7),
                    st.one_of(st.binary(max_size=40),
                              st.lists(bottle_values, max_size=3).map(Bottle)
                              .map(compact.encode)),
                    st.booleans())


@FUZZ
@given(st.lists(st.builds(DataFrame, st.lists(entries, max_size=4).map(tuple),
                          st.none() | st.integers(0, 8), st.none() | st.integers(0, 8)),
                max_size=4))
def test_any_data_frames_give_events_or_the_peer_error(sequence):
    session = _up_session()
    for frame in sequence:
        try:
            session.receive(frame)
        except BridgeProtocolError:
            return


# -- the whole story, any order ---------------------------------------------------------------


operations = st.lists(st.one_of(
    st.just(("command",)), st.tuples(st.just("status"), st.booleans()),
    st.just(("exchange",)), st.just(("cut",))), max_size=30)


@FUZZ
@given(operations)
def test_any_story_delivers_each_command_once_in_order_and_the_newest_status(story):
    """Commands from the pilot, statuses from the robot, frames exchanged or lost with the
    connection: in the end every command arrived once, in order, and the newest status."""
    robot, pilot = End(0x70B07), End(0x9170)
    connect(robot, pilot)
    commands, status, now = [], None, 0.0
    heard: List[Bottle] = []

    def exchange() -> None:
        for event in send(pilot, robot, now):
            assert not isinstance(event, Dropped)      # nothing resent that was accepted
        heard.extend(event.value for event in send(robot, pilot, now, robot.streams.due(now))
                     if isinstance(event, StreamValue))

    for step in story:
        now += 0.3
        if step[0] == "command":
            commands.append(Bottle(["c", len(commands)]))
            pilot.queues.append(SWITCH, commands[-1])
        elif step[0] == "status":
            status = Bottle([int(now * 10), "s"])
            robot.streams.post(STATUS, status, event=step[1])
        elif step[0] == "exchange":
            exchange()
        else:
            pilot.frame(now)                            # built, then lost in the cut
            robot.frame(now, robot.streams.due(now))
            connect(robot, pilot)
    connect(robot, pilot)
    for _ in range(2):
        now += 0.3
        exchange()
    assert robot.queues.received() == commands
    assert pilot.queues.outbox == {} and robot.queues.outbox == {}
    assert (heard[-1] if heard else None) == status


def test_a_frame_read_late_ages_its_messages_by_the_time_it_was_held(ends):
    """The sender's clock on every frame: a frame left unread 6 s in a stalled bridge's
    socket (or retransmitted after a blackout) is journalled as that much older, whatever
    the two PCs' clocks say (bridge.wire.transit)."""
    robot, pilot = ends
    offset = 5000.0                                   # the robot's clock is 5000 s behind
    robot.session.receive_body(pilot.frame(10.0).body, read_at=10.02 - offset)
    pilot.queues.append(COMMAND, Bottle(["on", "time"]))
    robot.session.receive_body(pilot.frame(11.0).body, read_at=11.02 - offset)
    pilot.queues.append(COMMAND, Bottle(["held"]))
    robot.session.receive_body(pilot.frame(12.0).body, read_at=18.02 - offset)
    assert robot.queues.late == [0.0, 6.0]
