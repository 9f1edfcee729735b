"""Helpers shared by the codec tests: byte-by-byte feeding and fuzz settings."""

from __future__ import annotations

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from yarp_lite.bottle import Bottle, Float32, Int8, Int16, Int64, Vocab

# At least 300 examples; more under the long "fuzz" profile (tests/conftest.py).
FUZZ = settings(max_examples=max(300, settings.default.max_examples), deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def feed_one_byte_at_a_time(decoder, data: bytes, pull):
    """Feed ``data`` one byte at a time, collecting whatever ``pull`` yields."""
    events = []
    for index in range(len(data)):
        decoder.feed(data[index:index + 1])
        while True:
            event = pull(decoder)
            if event is None:
                break
            events.append(event)
    return events


#: Any Bottle value YARP can carry, each type pinned by its wrapper.
bottle_primitives = st.one_of(
    st.integers(-(1 << 63), (1 << 63) - 1),
    st.integers(-128, 127).map(Int8), st.integers(-(1 << 15), (1 << 15) - 1).map(Int16),
    st.integers(-(1 << 31), (1 << 31) - 1).map(Int64),
    st.floats(allow_nan=False), st.floats(width=32, allow_nan=False).map(Float32),
    st.text(max_size=20), st.binary(max_size=20),
    st.text("abcdefgh", min_size=1, max_size=4).map(Vocab),
)
bottle_values = st.recursive(bottle_primitives,
                             lambda children: st.lists(children, max_size=5).map(Bottle),
                             max_leaves=25)
bottles = st.lists(bottle_values, max_size=8).map(Bottle)
