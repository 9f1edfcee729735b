"""How the gateway writes a sent command for the pilots' logs."""

import math

from rosnodes.gateway import readable
from yarp_lite.bottle import Bottle


def test_floats_read_as_a_pilot_typed_them_and_the_rest_as_yarp_writes_it():
    bottle = Bottle([Bottle(["look_at", 1.45, 0.2, 3.0, math.pi / 2, "two words", 7]), 655722274])
    assert Bottle([1.45]).to_text() != "1.45"          # YARP's own text: every digit
    assert readable(bottle) == '(look_at 1.45 0.2 3.0 1.570796327 "two words" 7) 655722274'
    assert readable(Bottle(["start", 12])) == "start 12"
    assert readable(Bottle([float("nan"), 1e-9])) == f"{Bottle([float('nan')]).to_text()} 1e-09"
