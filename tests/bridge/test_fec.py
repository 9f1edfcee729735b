"""Reed-Solomon erasure code: any k of k + m datagrams rebuild the data."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.wire import fec
from codec_helpers import FUZZ


@FUZZ
@given(st.lists(st.binary(max_size=60), min_size=1, max_size=12), st.integers(1, 5), st.data())
def test_any_k_of_k_plus_m_rebuild_everything(payloads, m, data):
    k = len(payloads)
    repairs = fec.encode(payloads, m)
    lost = data.draw(st.sets(st.integers(0, k + m - 1), max_size=m))
    have = {i: p for i, p in enumerate(payloads) if i not in lost}
    spare = {row: r for row, r in enumerate(repairs) if k + row not in lost}
    recovered = fec.recover(k, have, spare)
    assert {**have, **recovered} == dict(enumerate(payloads))


def test_every_loss_pattern_of_a_small_group():
    payloads = [bytes([i]) * (5 + i) for i in range(4)]
    repairs = fec.encode(payloads, 2)
    for lost in itertools.combinations(range(6), 2):
        have = {i: p for i, p in enumerate(payloads) if i not in lost}
        spare = {r: x for r, x in enumerate(repairs) if 4 + r not in lost}
        assert {**have, **fec.recover(4, have, spare)} == dict(enumerate(payloads))


def test_too_few_datagrams_is_a_peer_error():
    payloads = [b"a", b"b", b"c"]
    repairs = fec.encode(payloads, 1)
    with pytest.raises(BridgeProtocolError, match="too few"):
        fec.recover(3, {0: b"a"}, {0: repairs[0]})


def test_corrupt_repairs_never_crash():
    payloads = [b"abc", b"de", b"f"]
    repairs = fec.encode(payloads, 2)
    broken = {0: repairs[0][:-1] + b"\xff", 1: repairs[1][:2]}
    with pytest.raises(BridgeProtocolError):
        fec.recover(3, {2: b"f"}, broken)


def test_repair_counts():
    assert fec.repair_count(10, 0.0) == 0
    assert fec.repair_count(10, 0.3) == 3
    assert fec.repair_count(1, 0.01) == 1


@pytest.mark.parametrize("k, data, repairs, problem", [
    (0, {}, {0: b"\0\0"}, "FEC group of 0"),
    (200, {}, {0: b"\0\0"}, "FEC group of 200"),
    (2, {5: b"x"}, {0: b"\0\0\0"}, "data datagram 5 outside a group of 2"),   # IndexError before
    (2, {0: b"x"}, {128: b"\0\0\0"}, "repair row 128"),                       # 0 had no inverse
    (1, {}, {0: b"\0"}, "repair datagrams of 1 bytes"),                      # struct.error before
])
def test_every_group_field_is_checked_before_use(k, data, repairs, problem):
    with pytest.raises(BridgeProtocolError, match=problem):
        fec.recover(k, data, repairs)


def test_a_payload_too_long_for_its_length_field_is_a_usage_error():
    with pytest.raises(BridgeUsageError, match="too long for FEC"):
        fec.encode([bytes(70000)], 1)
