"""The HAL's robot-wide RPC words (walkman.hal.robot_rpc), answered without sockets; the
port itself is exercised as processes (test_hal_server.py, test_drc_wall.py, test_walking.py)."""

from __future__ import annotations

from typing import List, Optional

import pytest
from hypothesis import given

from codec_helpers import FUZZ, bottles
from walkman.hal.robot_rpc import USAGE, RobotWordError, answer
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import parse


class Hal:
    """Records what the words asked; ``simulated`` False refuses the simulation's words."""

    def __init__(self, simulated: bool = True) -> None:
        self.simulated = simulated
        self.asked: List[tuple] = []
        self.is_halted = False

    def chain_joints(self):
        return {"head": ["NeckYawj", "NeckPitchj"], "torso": ["WaistLat"]}

    def stats(self):
        return {"steps": 10, "overruns": 0}

    def halt(self, on: bool) -> None:
        self.asked.append(("halt", on))
        self.is_halted = on

    def halted(self) -> bool:
        return self.is_halted

    def _simulation(self, what: str) -> None:
        if not self.simulated:
            raise RobotWordError(f"this backend has no {what} (simulation only)")

    def set_harness(self, mode: str) -> None:
        self._simulation("harness")
        self.asked.append(("harness", mode))

    def push(self, impulse: List[float], seconds: Optional[float]) -> None:
        self._simulation("push")
        if abs(impulse[0]) > 100:
            raise ValueError("a push over 100 N*s would throw the robot")
        self.asked.append(("push", impulse, seconds))

    def go_to_station(self, name: str) -> None:
        self._simulation("stations")
        self.asked.append(("station", name))


OK = Bottle([Vocab("ok")])


def test_the_getters_answer_as_yarp_lists():
    hal = Hal()
    assert answer(parse("get chains"), hal) == parse("(head NeckYawj NeckPitchj) (torso WaistLat)")
    assert answer(parse("get stats"), hal) == parse("(steps 10) (overruns 0)")
    assert answer(parse("get halt"), hal) == Bottle([Vocab("ok"), "off"])


def test_halt_on_and_off():
    hal = Hal()
    assert answer(parse("set halt on"), hal) == OK and hal.halted()
    assert answer(parse("get halt"), hal)[1] == "on"
    assert answer(parse("set halt off"), hal) == OK and not hal.halted()
    assert answer(parse("set halt maybe"), hal) == Bottle([Vocab("fail"), USAGE])


@pytest.mark.parametrize("word, mode", [("on", "locked"), ("1", "locked"), ("true", "locked"),
                                        ("false", "off"), ("trolley", "trolley"),
                                        ("off", "off")])
def test_the_harness_takes_its_modes_and_yarp_s_booleans(word, mode):
    hal = Hal()
    assert answer(parse(f"set harness {word}"), hal) == OK
    assert hal.asked == [("harness", mode)]


def test_a_harness_mode_that_does_not_exist_is_refused_and_nothing_changes():
    hal = Hal()
    reply = answer(parse("set harness loose"), hal)
    assert reply[0] == Vocab("fail") and "harness must be one of" in reply[1] and hal.asked == []


def test_a_push_takes_three_numbers_and_optionally_its_seconds():
    hal = Hal()
    assert answer(parse("set push 0 25 0"), hal) == OK
    assert answer(parse("set push 0 25 0 0.2"), hal) == OK
    assert hal.asked == [("push", [0.0, 25.0, 0.0], None), ("push", [0.0, 25.0, 0.0], 0.2)]


@pytest.mark.parametrize("text", ["set push", "set push 1 2", "set push 1 hard 0",
                                  "set push 1 2 3 4 5", "set push (1 2 3)"])
def test_a_malformed_push_says_what_a_push_takes(text):
    hal = Hal()
    reply = answer(parse(text), hal)
    assert reply[0] == Vocab("fail") and "push takes IX IY IZ" in reply[1] and hal.asked == []


def test_the_backend_s_own_refusal_is_the_pilot_s_to_read():
    assert answer(parse("set push 500 0 0"), Hal())[1] == \
        "a push over 100 N*s would throw the robot"
    real = Hal(simulated=False)
    assert answer(parse("set station wall"), real)[1] == \
        "this backend has no stations (simulation only)"
    assert answer(parse("set harness off"), real)[0] == Vocab("fail")


def test_a_station_must_be_one_of_the_world_s():
    hal = Hal()
    assert answer(parse("set station wall"), hal) == OK and hal.asked == [("station", "wall")]
    reply = answer(parse("set station moon"), hal)
    assert "station must be one of valve, car" in reply[1] and len(hal.asked) == 1


@pytest.mark.parametrize("text", ["", "get", "get nothing", "set", "jump", "7"])
def test_an_unknown_request_lists_the_words(text):
    assert answer(parse(text), Hal()) == Bottle([Vocab("fail"), USAGE])


@FUZZ
@given(bottles)
def test_any_request_is_answered_never_raised(request_bottle):
    assert isinstance(answer(request_bottle, Hal()), Bottle)
