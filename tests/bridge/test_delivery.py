"""The inbox's delivery (bridge.gym.delivery) over a real journal, with recorded endpoints: what
waits, what is dropped, what is aged, what is said back.  The wiring as processes is in
test_bridge_processes.py and test_when_the_link_breaks.py."""

from __future__ import annotations

import logging
from typing import Any, Dict, List, Optional

import pytest

from bridge import config as bridge_config
from bridge.errors import BridgeUsageError
from bridge.flows import FlowKey
from bridge.gym.delivery import RECEIPT_KIND, Delivery
from bridge.transport.drops import DropLedger
from bridge.transport.journal import TOMBSTONE, Journal
from bridge.wire import compact
from walkman.gym.interfaces import (COMMAND, GYM_PORTS, SWITCH, WARNING, PilotCommand,
                                    encode_command)
from walkman.gym.validity import Lifetime, split, stamp
from yarp_lite.bottle import Bottle
from yarp_lite.errors import YarpError

CONFIG = bridge_config.parse("<bridge><modules><module name='gaze_control' id='7'/>"
                             "</modules></bridge>")
SWITCH_KEY = FlowKey(7, GYM_PORTS.index(SWITCH))
COMMAND_KEY = FlowKey(7, GYM_PORTS.index(COMMAND))
WARNING_KEY = FlowKey(7, GYM_PORTS.index(WARNING))


def look_at(seq: int, life: Lifetime) -> Bottle:
    """A pilot's command as the gateway writes it: ``(look_at 1.0) SEQ`` and its lifetime."""
    return encode_command(PilotCommand("look_at", [1.0], seq, life))


class Endpoint:
    """A local port: takes what it is given while ``ready``, or raises ``fails``."""

    def __init__(self, ready: bool = True, fails: Optional[Exception] = None) -> None:
        self.ready, self.fails = ready, fails
        self.taken: List[Any] = []

    def deliver(self, value: Any) -> bool:
        if self.fails is not None:
            raise self.fails
        self.taken.append(value)
        return True


class Inbox:
    """A delivery on ``side`` with its journal, endpoints and what it posted to the link."""

    def __init__(self, tmp_path, side: str = "robot", one_way: float = 0.0) -> None:
        self.journal = Journal(tmp_path / side)
        self.endpoints: Dict[FlowKey, Endpoint] = {}
        self.posted: List[tuple] = []
        self.answered: List[int] = []
        self.seq = 0
        self.drops = DropLedger("test", logging.getLogger("test"))
        self.delivery = Delivery(CONFIG, side, self.journal, CONFIG.routes(),
                                 source=self.endpoints.get,
                                 post=lambda route, value: self.posted.append((route.key, value)),
                                 one_way=lambda: one_way, on_delivered=self.answered.append,
                                 drops=self.drops)

    def arrive(self, key: FlowKey, payload: Any) -> None:
        self.seq += 1
        data = payload if isinstance(payload, bytes) else compact.encode(payload)
        assert self.journal.accept(1, self.seq, key.id, key.kind, data)

    def round(self, failing: Optional[set] = None) -> None:
        self.delivery.round(set() if failing is None else failing)

    def waiting(self) -> List[FlowKey]:
        return [FlowKey(m.id, m.kind) for m in self.journal.undelivered()]


@pytest.fixture
def inbox(tmp_path):
    box = Inbox(tmp_path)
    yield box
    box.journal.close()


def test_a_message_waits_for_its_port_and_holds_back_only_its_own_flow(inbox):
    inbox.arrive(SWITCH_KEY, stamp(Bottle(["start", 1]), Lifetime(0.0, 10.0)))
    inbox.arrive(SWITCH_KEY, stamp(Bottle(["pause", 2]), Lifetime(0.0, 10.0)))
    inbox.arrive(COMMAND_KEY, look_at(3, Lifetime(0.0, 10.0)))
    inbox.endpoints[COMMAND_KEY] = command = Endpoint()
    inbox.endpoints[SWITCH_KEY] = switch = Endpoint(ready=False)   # the module not there yet
    inbox.round()
    assert [split(v)[0] for v in command.taken] == [split(look_at(3, Lifetime()))[0]]
    assert inbox.waiting() == [SWITCH_KEY, SWITCH_KEY]
    switch.ready = True
    inbox.round()
    assert [split(v)[0][0] for v in switch.taken] == ["start", "pause"]   # in order, once
    inbox.round()
    assert len(switch.taken) == 2 and inbox.waiting() == []
    assert inbox.delivery.delivered == 3 and inbox.answered == [7, 7, 7]


def test_a_command_leaves_older_by_the_link_and_the_inbox_and_says_it_was_delivered(tmp_path):
    box = Inbox(tmp_path, one_way=0.25)
    box.arrive(COMMAND_KEY, look_at(9, Lifetime(1.0, 10.0)))
    box.endpoints[COMMAND_KEY] = command = Endpoint()
    box.round()
    message, life = split(command.taken[0])
    assert message == split(look_at(9, Lifetime()))[0] and 1.25 <= life.age < 2.0
    assert box.posted == [(FlowKey(7, RECEIPT_KIND), Bottle([9, "delivered"]))]
    box.journal.close()


def test_a_cancelled_command_is_dropped_and_counted_never_delivered(inbox):
    inbox.arrive(COMMAND_KEY, TOMBSTONE)
    inbox.endpoints[COMMAND_KEY] = command = Endpoint()
    inbox.round()
    assert command.taken == [] and inbox.waiting() == []
    assert inbox.delivery.cancelled_dropped == 1 and inbox.posted == []


def test_a_warning_is_not_aged_and_has_no_receipt(tmp_path):
    box = Inbox(tmp_path, side="pilot", one_way=5.0)
    box.arrive(WARNING_KEY, Bottle([4, "overheating"]))
    box.endpoints[WARNING_KEY] = warning = Endpoint()
    box.round()
    assert warning.taken == [Bottle([4, "overheating"])] and box.posted == []
    box.journal.close()


def test_an_undecodable_message_is_a_peer_error_dropped_and_the_rest_go_on(inbox):
    inbox.arrive(WARNING_KEY, b"\xff\xfe not compact")
    inbox.arrive(WARNING_KEY, Bottle([5, "fine"]))
    inbox.endpoints[WARNING_KEY] = warning = Endpoint()
    inbox.round()
    assert warning.taken == [Bottle([5, "fine"])] and inbox.waiting() == []
    assert sum(inbox.drops.counts.values()) == 1


def test_a_message_for_no_configured_flow_is_dropped(inbox):
    inbox.arrive(FlowKey(99, 0), Bottle(["start", 1]))
    inbox.round()
    assert inbox.waiting() == [] and sum(inbox.drops.counts.values()) == 1


def test_a_port_s_network_error_keeps_the_message_for_the_next_round(inbox):
    inbox.arrive(SWITCH_KEY, stamp(Bottle(["start", 1]), Lifetime(0.0, 10.0)))
    inbox.endpoints[SWITCH_KEY] = switch = Endpoint(fails=YarpError("name server gone"))
    inbox.round()
    assert inbox.waiting() == [SWITCH_KEY] and inbox.delivery.internal_errors == 0
    switch.fails = None
    inbox.round()
    assert inbox.waiting() == [] and len(switch.taken) == 1


def test_a_bug_in_a_port_is_counted_logged_once_and_loses_nothing(inbox, caplog):
    inbox.arrive(SWITCH_KEY, stamp(Bottle(["start", 1]), Lifetime(0.0, 10.0)))
    inbox.endpoints[SWITCH_KEY] = switch = Endpoint(fails=KeyError("bug"))
    failing: set = set()
    with caplog.at_level(logging.ERROR, logger="bridge"):
        inbox.round(failing)
        inbox.round(failing)
    assert inbox.delivery.internal_errors == 2
    assert caplog.text.count("it stays queued") == 1
    switch.fails = None
    inbox.round(failing)
    assert len(switch.taken) == 1 and inbox.waiting() == []


def test_cancel_is_the_pilot_side_s_and_for_gym_modules_only(inbox, tmp_path):
    with pytest.raises(BridgeUsageError, match="pilot side"):
        inbox.delivery.cancel("gaze_control", None)
    pilot = Inbox(tmp_path, side="pilot")
    with pytest.raises(BridgeUsageError, match="not a GYM module"):
        pilot.delivery.cancel("nobody", None)
    assert pilot.delivery.cancel("gaze_control", None) == ([], [])
    pilot.journal.close()


def test_a_cancel_before_any_frame_takes_the_command_back_and_tells_the_pilots(tmp_path):
    pilot = Inbox(tmp_path, side="pilot")
    pilot.journal.append(COMMAND_KEY.id, COMMAND_KEY.kind,
                         compact.encode(look_at(12, Lifetime(0.0, 10.0))))
    pilot.endpoints[FlowKey(7, RECEIPT_KIND)] = receipts = Endpoint()
    assert pilot.delivery.cancel("gaze_control", 12) == ([12], [])
    assert receipts.taken == [Bottle([12, "cancelled", "cancelled by a pilot"])]
    pilot.journal.close()

