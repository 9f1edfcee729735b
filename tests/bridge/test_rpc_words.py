"""The bridge's RPC words, parsed and answered without sockets (the ports are tested as
processes: ``pilot_side.py``, ``test_stop_all.py``)."""

from __future__ import annotations

from typing import List, Optional, Tuple

import pytest
from hypothesis import given

from codec_helpers import FUZZ, bottles

from bridge.errors import BridgeUsageError
from bridge.gym.stop_line import Ack
from bridge.rpc_words import answer
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse


class Bridge:
    """Records what the words asked for."""

    def __init__(self, ack: Optional[Ack] = None, refuse: str = "") -> None:
        self.ack, self.refuse = ack, refuse
        self.asked: List[tuple] = []

    def status(self):
        return {"side": "pilot", "link": "up", "tcp": {"frames": 3}}

    def cancel(self, module: str, seq: Optional[int]) -> Tuple[List[int], List[int]]:
        self.asked.append(("cancel", module, seq))
        if self.refuse:
            raise BridgeUsageError(self.refuse)
        return [4, 5], [3]

    def stop_all(self, word: str = "stop_all", timeout: float = 5.0) -> Optional[Ack]:
        self.asked.append((word,))
        if self.refuse:
            raise BridgeUsageError(self.refuse)
        return self.ack


def test_status_is_the_bridge_s_status_as_a_property_list():
    assert answer(parse("status"), Bridge()) == parse("(side pilot) (link up) (tcp ((frames 3)))")


def test_cancel_takes_a_module_and_a_number_or_all():
    bridge = Bridge()
    assert answer(parse("cancel gaze_control 4"), bridge) == \
        parse("ok (cancelled 4 5) (too_late 3)")
    answer(parse("cancel gaze_control all"), bridge)
    assert bridge.asked == [("cancel", "gaze_control", 4), ("cancel", "gaze_control", None)]


@pytest.mark.parametrize("request_text", ["cancel", "cancel gaze_control",
                                          "cancel gaze_control 4.5", "cancel 7 4",
                                          "cancel gaze_control 4 5", "cancel gaze_control some"])
def test_a_malformed_cancel_is_answered_with_its_usage_and_nothing_is_cancelled(request_text):
    bridge = Bridge()
    assert answer(parse(request_text), bridge) == Bottle(["error",
                                                          "usage: cancel MODULE SEQ|all"])
    assert bridge.asked == []


def test_a_cancel_the_bridge_refuses_says_why():
    reply = answer(parse("cancel nobody 1"), Bridge(refuse="'nobody' is not a GYM module"))
    assert reply == Bottle(["error", "'nobody' is not a GYM module"])


def test_stop_all_answers_the_robot_s_acknowledgement():
    ack = Ack(7, "held", True, 3.25, ("gaze_control", "walking"), round_trip_ms=104.04)
    assert answer(parse("stop_all"), Bridge(ack)) == \
        parse("ok held (hal ok) (round_trip_ms 104.0) (robot_ms 3.2) "
              "(paused gaze_control walking)")


def test_a_stop_all_without_an_answer_or_refused_is_an_error():
    assert answer(parse("release"), Bridge(None)) == \
        Bottle(["error", "release: the robot did not acknowledge within 5 s"])
    assert answer(parse("stop_all"), Bridge(refuse="not the pilot's bridge")) == \
        Bottle(["error", "not the pilot's bridge"])
    bridge = Bridge()
    assert answer(parse("stop_all now"), bridge)[0] == "error" and bridge.asked == []


@pytest.mark.parametrize("request_text", ["", "frobnicate", "7", "(status)"])
def test_an_unknown_word_names_the_words_there_are(request_text):
    reply = answer(parse(request_text), Bridge())
    assert reply[0] == "error" and "try status, cancel, stop_all, release or help" in reply[1]


def test_help_lists_every_word():
    text = answer(parse("help"), Bridge())[0]
    assert all(word in text for word in ("status", "cancel", "stop_all", "release"))


# -- the asking side: what the pilot gateway reads back ----------------------------------------


def test_a_cancel_reply_reads_back_what_the_bridge_answered():
    from bridge.rpc_words import cancel_request, read_cancel_reply

    bridge = Bridge()
    assert cancel_request("gaze_control", None) == parse("cancel gaze_control all")
    assert read_cancel_reply(answer(cancel_request("gaze_control", 4), bridge)) == ([4, 5], [3])
    with pytest.raises(BridgeUsageError, match="not a GYM module"):
        read_cancel_reply(answer(parse("cancel x 1"), Bridge(refuse="'x' is not a GYM module")))


def test_a_stop_reply_reads_back_the_acknowledgement():
    from bridge.rpc_words import read_stop_reply

    ack = Ack(7, "held", False, 3.25, ("gaze_control",), round_trip_ms=104.04)
    assert read_stop_reply(answer(parse("stop_all"), Bridge(ack))) == \
        Ack(0, "held", False, 3.2, ("gaze_control",), 104.0)
    with pytest.raises(BridgeUsageError, match="did not acknowledge"):
        read_stop_reply(answer(parse("stop_all"), Bridge(None)))


@pytest.mark.parametrize("reply", ["", "ok", "ok (cancelled 1)", "ok (too_late) (cancelled)",
                                   "ok (cancelled 1.5) (too_late)", "ok (cancelled x) (too_late)",
                                   "yes (cancelled) (too_late)", "error", "(cancelled) (too_late)",
                                   "ok (cancelled) (too_late) (more)"])
def test_a_cancel_reply_of_another_form_is_a_protocol_error(reply):
    from bridge.errors import BridgeProtocolError
    from bridge.rpc_words import read_cancel_reply

    with pytest.raises(BridgeProtocolError, match="cancel reply|reply's fields"):
        read_cancel_reply(parse(reply))


@pytest.mark.parametrize("reply", ["ok", "ok held", "ok held (hal ok)",
                                   "ok held (hal ok) (round_trip_ms x) (robot_ms 1) (paused)",
                                   "ok held (hal) (round_trip_ms 1) (robot_ms 1) (paused)",
                                   "ok 7 (hal ok) (round_trip_ms 1) (robot_ms 1) (paused)",
                                   "ok held (hal ok) (robot_ms 1) (round_trip_ms 1) (paused)"])
def test_a_stop_reply_of_another_form_is_a_protocol_error(reply):
    from bridge.errors import BridgeProtocolError
    from bridge.rpc_words import read_stop_reply

    with pytest.raises(BridgeProtocolError, match="stop reply|reply's fields"):
        read_stop_reply(parse(reply))


@FUZZ
@given(bottles)
def test_any_reply_is_read_or_refused_with_a_bridge_error(reply):
    from bridge.errors import BridgeError
    from bridge.rpc_words import read_cancel_reply, read_stop_reply

    for read in (read_cancel_reply, read_stop_reply):
        try:
            read(reply)
        except BridgeError:
            pass


@FUZZ
@given(bottles)
def test_any_request_is_answered_never_raised(request_bottle):
    bridge = Bridge()
    assert isinstance(answer(request_bottle, bridge), Bottle)
