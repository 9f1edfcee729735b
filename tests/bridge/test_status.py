"""The bridge status Bottle: readable with ``yarp read``, and back to the same dict."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge import status
from bridge.errors import BridgeProtocolError
from yarp_lite.bottle_text import format_bottle, parse

keys = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_/", min_size=1, max_size=12).filter(
    lambda text: text not in ("nan", "inf"))  # YARP text reads those back as floats
leaves = st.one_of(st.integers(-(1 << 31), (1 << 31) - 1), st.floats(-1e6, 1e6),
                   st.text(alphabet="abcdefghijklmnopqrstuvwxyz ", min_size=1, max_size=10)
                   .filter(lambda text: text not in ("nan", "inf")))
trees = st.recursive(leaves, lambda inner: st.dictionaries(keys, inner, min_size=1, max_size=4),
                     max_leaves=20)


@given(st.dictionaries(keys, trees, min_size=1, max_size=6))
def test_round_trip_through_binary_and_text(value):
    bottle = status.to_bottle(value)
    assert status.from_bottle(bottle) == value
    assert status.from_bottle(parse(format_bottle(bottle))) == value  # what `yarp read` shows


def test_integer_keys_come_back_as_strings():
    bottle = status.to_bottle({"tcp": {"bytes_by_id": {7: 10, 30: 4}}, "time": 1.5})
    assert format_bottle(bottle) == '(tcp ((bytes_by_id (("7" 10) ("30" 4))))) (time 1.5)'
    assert status.from_bottle(bottle) == {"tcp": {"bytes_by_id": {"7": 10, "30": 4}},
                                          "time": 1.5}


@pytest.mark.parametrize("line", ["hello", "1 2 3", '"just a string"'])
def test_lines_that_are_not_a_status_are_refused(line):
    with pytest.raises(BridgeProtocolError, match="not a bridge status"):
        status.from_bottle(parse(line))
