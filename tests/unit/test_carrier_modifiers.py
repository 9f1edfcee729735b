"""``+period.S``: a reader of a stream asks the writer for fewer messages (the only carrier
modifier yarp_lite understands; any other is refused by name)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from yarp_lite.carriers import make_carrier, send_period, with_send_period
from yarp_lite.errors import LocalProtocolError
from yarp_lite.port_outputs import OutputUnit


def test_a_period_is_read_from_the_carrier_and_written_back():
    assert send_period("fast_tcp") == 0.0
    assert send_period("fast_tcp+period.0.004") == 0.004
    assert with_send_period("fast_tcp", 0.004) == "fast_tcp+period.0.004"
    assert with_send_period("tcp", 0.0) == "tcp"
    assert make_carrier("fast_tcp+period.0.02").name == "fast_tcp"


@pytest.mark.parametrize("carrier, named", [
    ("tcp+send.portmonitor", "unknown modifier 'send.portmonitor'"),
    ("fast_tcp+period.fast", "got 'fast'"),
    ("fast_tcp+period.0", "got '0'"),
    ("fast_tcp+period.-1", "got '-1'"),
    ("fast_tcp+period.7200", "got '7200'"),
])
def test_a_bad_modifier_is_refused_naming_it(carrier, named):
    with pytest.raises(LocalProtocolError, match=named):
        make_carrier(carrier)


@given(st.floats(min_value=1e-6, max_value=3600, allow_nan=False))
def test_every_period_written_reads_back(seconds):
    assert send_period(with_send_period("fast_tcp", seconds)) == pytest.approx(seconds,
                                                                                 rel=1e-5)


def _sent(period: float, every: float, jitter: float, count: int) -> list:
    """When a stream written every ``every`` s (each write up to ``jitter`` late, in turn)
    goes to an output that asked for ``period``."""
    unit = OutputUnit(None, None, "", period)
    times = [i * every + (jitter if i % 2 else 0.0) for i in range(count)]
    return [t for t in times if unit.due(t)]


@pytest.mark.parametrize("period, expected", [(0.004, 250), (0.005, 200), (0.02, 50),
                                              (0.1, 10)])
def test_a_500_hz_stream_with_jitter_goes_out_at_the_rate_asked(period, expected):
    sent = _sent(period, every=0.002, jitter=0.0003, count=5000)    # 10 s
    assert abs(len(sent) - 10 * expected) <= 2
    gaps = [b - a for a, b in zip(sent, sent[1:])]
    assert min(gaps) >= 0.75 * period - 0.0003 - 1e-9


def test_without_a_period_every_message_goes_and_after_a_pause_the_next_one_does():
    assert len(_sent(0.0, every=0.002, jitter=0.0, count=100)) == 100
    unit = OutputUnit(None, None, "", 0.01)
    assert unit.due(0.0) and not unit.due(0.005)
    assert unit.due(10.0)                       # the writer was silent: sent at once ...
    assert not unit.due(10.005) and unit.due(10.01)   # ... and the schedule starts again
