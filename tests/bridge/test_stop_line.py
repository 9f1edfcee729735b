"""bridge.gym.stop_line: a stop-all is sent until acknowledged and carried out once per id."""

from __future__ import annotations

import threading

import pytest

from bridge.gym.stop_line import (ANSWER_GAP, Ack, PilotStops, RobotStops, StopLineError,
                                  encode_ack, parse_ack, parse_order)
from harness import wait_until
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse


def test_orders_and_acknowledgements_read_back_and_bad_ones_are_refused():
    assert parse_order(parse("stop_all 42")) == ("stop_all", 42)
    ack = Ack(42, "held", True, 12.5, ("gaze_control", "walking"))
    assert parse_ack(parse(encode_ack(ack).to_text())) == ack
    for text in ("stop 42", "stop_all", "stop_all x", "stop_all 1 2"):
        with pytest.raises(StopLineError, match="a stop order is"):
            parse_order(parse(text))
    for text in ("held", "held 1 1", "gone 1 1 2", "held 1 1 x", "held 1 1 2 3"):
        with pytest.raises(StopLineError, match="a stop acknowledgement is"):
            parse_ack(parse(text))


def test_the_robot_carries_out_each_stop_once_and_answers_copies_now_and_then():
    done, answers = [], []
    gate = threading.Event()
    now = [0.0]

    def carry_out(word: str, stop_id: int) -> Ack:
        gate.wait(5)
        done.append((word, stop_id))
        return Ack(stop_id, "held", True, 3.0, ("m",))

    robot = RobotStops(carry_out, lambda ack, again: answers.append((ack, again)),
                       clock=lambda: now[0])
    for _ in range(3):                          # three copies before it is done: one answer
        robot.on_order(Bottle(["stop_all", 7]))
    gate.set()
    wait_until(lambda: answers, 5, message="the answer")
    robot.on_order(Bottle(["stop_all", 7]))     # a copy right after: the answer is on its way
    now[0] = ANSWER_GAP
    robot.on_order(Bottle(["stop_all", 7]))     # a late copy: answered again, not redone
    robot.on_order(Bottle(["stop_all", 7]))     # and its twin: not again so soon
    robot.on_order(Bottle(["stop", 7]))         # garbage: logged, nothing done
    assert done == [("stop_all", 7)]
    assert [(parse_ack(a).stop_id, again) for a, again in answers] == [(7, False), (7, True)]


def test_the_pilot_resends_until_the_robot_answers():
    sent, again = [], []
    pilot = PilotStops(lambda order, resent: None)

    def robot_answers_the_third_copy(order: Bottle, resent: bool) -> None:
        sent.append(order)
        again.append(resent)
        if len(sent) == 3:
            threading.Thread(target=pilot.on_ack,
                             args=(encode_ack(Ack(order[1], "held", True, 1.0)),)).start()

    pilot._send = robot_answers_the_third_copy
    ack = pilot.order("stop_all", timeout=5.0)
    assert ack is not None and ack.hal and len(sent) == 3
    assert all(order == sent[0] for order in sent)          # the same id each time
    assert again == [False, True, True]                     # the first by every way
    assert ack.round_trip_ms >= (250 + 500) * 0.9           # the wait doubles
    assert PilotStops(lambda order, resent: None).order("release", timeout=0.3) is None
