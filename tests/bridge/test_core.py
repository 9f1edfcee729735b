"""The bridge's decisions without sockets (bridge.core): each carriage both ways, the stop
line, datagram copies, and hypothesis over orders of events on the DRC's own configuration.
The node that performs them is tested as processes (test_bridge_processes.py and others)."""

from __future__ import annotations

from typing import Dict, List

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.config import PILOT, ROBOT, load
from bridge.core import (INBOUND, OUTBOUND, AcceptCopy, BridgeCore, CarryOutStop, Deliver, Drop,
                        FrameLeft, LocalMessage, PeerMessage, SendCopies, SendDatagrams,
                        SendLatest, SendReliable, TakeAck, UrgentMessage)
from bridge.errors import BridgeUsageError
from bridge.flows import Carriage, FlowKey
from bridge.gym.status_events import StatusEvents
from bridge.transport.copies import ReliableCopy
from bridge.transport.drops import Reason
from codec_helpers import FUZZ
from harness import ManualClock as Clock
from system.topology import BRIDGE_CONFIG
from yarp_lite.bottle import Bottle

CONFIG = load(BRIDGE_CONFIG)
ROUTES = CONFIG.routes()
STOP = CONFIG.emergency_stop
KEYS = {route.label: key for key, route in ROUTES.items()}
COMMAND, STATUS, WARNING = (KEYS[f"gaze_control/{flow}"] for flow in ("command", "status",
                                                                       "warning"))
IMAGE, STATE = KEYS["/multisense/left/image_color"], KEYS["walkman/state"]


def core(side: str = ROBOT, datagrams: bool = True, clock: Clock = None) -> BridgeCore:
    clock = clock or Clock()
    return BridgeCore(side, ROUTES, datagrams=datagrams, stop=STOP,
                      status_events=StatusEvents(clock))


def status(seq: int, state: str, *data) -> Bottle:
    return Bottle([seq, state, *data])


def test_every_carriage_is_said_both_ways_in_the_one_table():
    assert set(OUTBOUND) == set(INBOUND) == set(Carriage)


def test_a_side_that_is_neither_is_refused_by_name():
    with pytest.raises(BridgeUsageError, match="robot or pilot, not 'both'"):
        BridgeCore("both", ROUTES)
    with pytest.raises(BridgeUsageError, match="not a bridge event"):
        core().handle("hello")   # type: ignore[arg-type]


# -- outbound ------------------------------------------------------------------------------


def test_a_command_is_journalled_and_a_stream_is_the_newest_value():
    bridge = core(PILOT)
    command = Bottle(["look", 1.0])
    assert bridge.handle(LocalMessage(COMMAND, command)) == [SendReliable(COMMAND, command)]
    assert bridge.handle(LocalMessage(IMAGE, b"png")) == [SendDatagrams(IMAGE, b"png")]
    assert bridge.handle(LocalMessage(STATE, "q")) == [SendLatest(STATE, "q", False)]


def test_a_status_a_pilot_waits_for_leaves_at_once_and_as_copies_later_ones_by_tcp_alone():
    clock = Clock()
    bridge = core(ROBOT, clock=clock)
    copies = ROUTES[STATUS].copies
    assert copies > 0
    first = status(1, "idle")
    assert bridge.handle(LocalMessage(STATUS, first)) == [SendLatest(STATUS, first, False)]
    drift = status(2, "idle", 40.5)
    assert bridge.handle(LocalMessage(STATUS, drift)) == [SendLatest(STATUS, drift, False)]
    running = status(3, "running", 40.5)                       # a new state: copies too
    assert bridge.handle(LocalMessage(STATUS, running)) == [SendLatest(STATUS, running, True),
                                                            SendCopies(STATUS, running, copies)]
    bridge.delivered(STATUS.id)                                # a command reached it
    answer, later = status(4, "running", 12.0), status(5, "running", 13.0)
    assert bridge.handle(LocalMessage(STATUS, answer)) == [SendLatest(STATUS, answer, True),
                                                           SendCopies(STATUS, answer, copies)]
    assert bridge.handle(LocalMessage(STATUS, later)) == [SendLatest(STATUS, later, True)]


def test_without_a_udp_channel_nothing_goes_as_datagrams_and_a_datagram_flow_says_why():
    bridge = core(ROBOT, datagrams=False)
    running = status(2, "running")
    bridge.handle(LocalMessage(STATUS, status(1, "idle")))
    assert bridge.handle(LocalMessage(STATUS, running)) == [SendLatest(STATUS, running, True)]
    [drop] = bridge.handle(LocalMessage(IMAGE, b"png"))
    assert drop.reason is Reason.UNCONFIGURED and "no UDP channel" in drop.detail
    copy = ReliableCopy(1, 1, b"x")
    assert bridge.handle(FrameLeft(((COMMAND, copy),))) == []
    assert bridge.handle(UrgentMessage(STOP.stop_key, "stop")) == \
        [SendLatest(STOP.stop_key, "stop", True)]


def test_a_frame_with_copied_commands_sends_their_copies_and_a_stop_goes_every_way():
    bridge = core(PILOT)
    copy = ReliableCopy(7, 3, b"payload")
    assert bridge.handle(FrameLeft(((COMMAND, copy),))) == \
        [SendCopies(COMMAND, copy, ROUTES[COMMAND].copies)]
    assert bridge.handle(UrgentMessage(STOP.stop_key, "stop")) == \
        [SendLatest(STOP.stop_key, "stop", True), SendCopies(STOP.stop_key, "stop", STOP.copies)]
    # A resending: the TCP connection already carries it, the datagrams go again.
    assert bridge.handle(UrgentMessage(STOP.stop_key, "stop", again=True)) == \
        [SendCopies(STOP.stop_key, "stop", STOP.copies, again=True)]


def test_a_local_message_on_no_configured_flow_is_dropped_by_name():
    [drop] = core().handle(LocalMessage(FlowKey(199, 3), "x"))
    assert drop.reason is Reason.UNCONFIGURED and "id 199 kind 3" in drop.detail


# -- inbound -------------------------------------------------------------------------------


def test_a_copy_goes_to_the_journal_and_a_reliable_message_outside_it_is_refused():
    bridge = core(ROBOT)
    copy = ReliableCopy(7, 3, b"payload")
    assert bridge.handle(PeerMessage(COMMAND, copy)) == [AcceptCopy(COMMAND, copy)]
    [drop] = bridge.handle(PeerMessage(COMMAND, Bottle(["look"])))
    assert drop.reason is Reason.MALFORMED and "gaze_control/command" in drop.detail
    [drop] = bridge.handle(PeerMessage(WARNING, Bottle(["hot"])))
    assert drop.reason is Reason.MALFORMED


def test_the_first_copy_of_a_status_is_written_the_other_and_a_late_one_never():
    bridge = core(PILOT)
    newer, older = status(9, "running"), status(8, "idle")
    assert bridge.handle(PeerMessage(STATUS, newer)) == [Deliver(STATUS, newer)]
    assert bridge.handle(PeerMessage(STATUS, newer)) == []     # the datagram copy of it
    assert bridge.handle(PeerMessage(STATUS, older)) == []     # overtaken
    bridge.module_gone(STATUS)                                 # restarted: numbers anew
    assert bridge.handle(PeerMessage(STATUS, older)) == [Deliver(STATUS, older)]


def test_streams_are_delivered_as_they_come_and_an_unknown_flow_is_dropped():
    bridge = core(PILOT)
    assert bridge.handle(PeerMessage(IMAGE, b"png")) == [Deliver(IMAGE, b"png")]
    assert bridge.handle(PeerMessage(IMAGE, b"png")) == [Deliver(IMAGE, b"png")]
    assert bridge.handle(PeerMessage(STATE, "q")) == [Deliver(STATE, "q")]
    [drop] = bridge.handle(PeerMessage(FlowKey(199, 0), b"?"))
    assert drop.reason is Reason.UNKNOWN_ID


def test_an_order_is_the_robots_to_carry_out_an_acknowledgement_the_pilots_to_take():
    assert core(ROBOT).handle(PeerMessage(STOP.stop_key, "o")) == [CarryOutStop("o")]
    assert core(PILOT).handle(PeerMessage(STOP.ack_key, "a")) == [TakeAck("a")]
    for side, key in ((PILOT, STOP.stop_key), (ROBOT, STOP.ack_key)):
        [drop] = core(side).handle(PeerMessage(key, "x"))
        assert drop.reason is Reason.UNKNOWN_ID and f"the {side}'s side" in drop.detail


# -- any order of events -------------------------------------------------------------------

_values = st.one_of(st.none(), st.integers(), st.binary(max_size=8),
                    st.builds(status, st.integers(0, 20), st.sampled_from(["idle", "running"]),
                              st.floats(0, 2, allow_nan=False)),
                    st.builds(ReliableCopy, st.integers(1, 3), st.integers(1, 9),
                              st.binary(min_size=1, max_size=4)))
_keys = st.sampled_from(sorted(ROUTES) + [FlowKey(199, 0)])
_events = st.lists(st.tuples(st.sampled_from(["local", "peer", "delivered", "gone", "tick"]),
                             _keys, _values), max_size=60)


@FUZZ
@given(side=st.sampled_from([ROBOT, PILOT]), datagrams=st.booleans(), events=_events)
def test_any_order_of_events_keeps_every_rule(side, datagrams, events):
    """Whatever comes in whatever order (a peer's decoded values are anything): the core
    never raises; each local message leaves exactly one way, its carriage's; copies go only
    on flows configured with them and only with a UDP channel; a peer's message is delivered
    at most once and only on its own flow; a copied status flow never writes the same
    status twice in a row."""
    clock = Clock()
    bridge = core(side, datagrams, clock)
    last_written: Dict[FlowKey, object] = {}
    for kind, key, value in events:
        if kind == "delivered":
            bridge.delivered(key.id)
            continue
        if kind == "gone":
            bridge.module_gone(key)
            last_written.pop(key, None)
            continue
        if kind == "tick":
            clock.now += 0.7
            continue
        event = LocalMessage(key, value) if kind == "local" else PeerMessage(key, value)
        actions: List[object] = bridge.handle(event)
        route = ROUTES.get(key)
        if route is None:
            assert [type(a) for a in actions] == [Drop]
            continue
        for action in actions:
            assert getattr(action, "key", key) == key
            if isinstance(action, (SendCopies, SendDatagrams)):
                assert datagrams
            if isinstance(action, SendCopies):
                assert route.copies or route.carriage is Carriage.URGENT
        if kind == "local":
            primary = [a for a in actions if not isinstance(a, SendCopies)]
            assert len(primary) == 1
            expected = {Carriage.RELIABLE: SendReliable, Carriage.LATEST: SendLatest,
                        Carriage.URGENT: SendLatest,
                        Carriage.DATAGRAMS: SendDatagrams if datagrams else Drop}
            assert type(primary[0]) is expected[route.carriage]
        else:
            assert len(actions) <= 1
            delivered = [a for a in actions if isinstance(a, Deliver)]
            if delivered and route.copies:
                assert key not in last_written or last_written[key] != value
                last_written[key] = value
            if route.carriage is Carriage.DATAGRAMS:
                assert delivered == [Deliver(key, value)]
            if route.carriage is Carriage.RELIABLE:
                assert actions == ([AcceptCopy(key, value)] if isinstance(value, ReliableCopy)
                                   else [Drop(Reason.MALFORMED, actions[0].detail)])
