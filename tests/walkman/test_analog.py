"""The F/T sensors' analogServer rpc: tare and offsets (walkman.hal.analog)."""

from __future__ import annotations

import numpy as np
import pytest

from walkman.hal import analog
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import parse

RAW = np.array([1.0, 2.0, 300.0, 0.1, 0.2, 0.3])


def ask(offsets: analog.AnalogOffsets, text: str, errors=None) -> Bottle:
    return analog.respond(parse(text), offsets, lambda: RAW.copy(),
                          (errors if errors is not None else []).append)


def test_cal_tares_every_channel_and_calc_one():
    offsets = analog.AnalogOffsets(6)
    assert ask(offsets, "iana cal") == Bottle([0])
    assert np.allclose(offsets.apply(RAW), 0)
    assert ask(offsets, "[iana] [calc] 2 10.0") == Bottle([0])
    assert offsets.apply(RAW)[2] == pytest.approx(290.0)
    assert ask(offsets, "iana calc 2") == Bottle([0])
    assert offsets.apply(RAW)[2] == pytest.approx(0.0)


@pytest.mark.parametrize("values", ["1 2 3 4 5 6", "(1 2 3 4 5 6)"])  # YARP's server / client forms
def test_cal_with_values_sets_the_offsets(values):
    offsets = analog.AnalogOffsets(6)
    assert ask(offsets, f"iana cal {values}") == Bottle([0])
    assert list(offsets.offsets) == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("text, problem", [
    ("iana fly", "try [iana] [cal]"), ("hello", "try [iana] [cal]"),
    ("iana cal 1 2", "takes 6 finite numbers"), ("iana cal 1 2 3 4 5 nan", "takes 6"),
    ("iana calc 9", "channel 0..5"), ("iana calc x", "channel 0..5"),
    ("iana calc 1 2 3", "at most one"),
])
def test_anything_else_is_refused_with_the_reason(text, problem):
    offsets, errors = analog.AnalogOffsets(6), []
    assert ask(offsets, text, errors) == Bottle([Vocab("fail")])
    assert problem in errors[0]
    assert not offsets.offsets.any()
