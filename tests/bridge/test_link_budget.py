"""bridge.transport.link_budget: the radio's queue as one bridge fills it, drained at the rate."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bridge.transport.link_budget import (DATAGRAM_OVERHEAD, MIN_LIMIT, SEGMENT_OVERHEAD,
                                          LinkBudget, LinkBudgetError, datagram_bytes, tcp_bytes)

RATE = 9600.0          # the DRC Finals' link, bit/s: 1200 bytes a second


def test_what_was_spent_drains_at_the_links_rate():
    budget = LinkBudget(RATE)
    budget.spend(1200, now=10.0)
    assert budget.queued(10.0) == 1200
    assert budget.queued(10.5) == pytest.approx(600)
    assert budget.queued(11.0) == 0 and budget.queued(20.0) == 0     # never below empty
    assert budget.spent == 1200


def test_streaming_data_waits_for_room_and_a_large_datagram_for_an_empty_queue():
    budget = LinkBudget(RATE)                     # 9600 * 0.15 / 8 = 180 bytes: the floor
    assert budget.limit == MIN_LIMIT
    assert budget.wait_for(200, now=0.0) == 0 and not budget.full(0.0)
    budget.spend(200, now=0.0)
    # 200 queued + 200 more is 100 over the limit: 100 bytes' time, at 1200 bytes a second
    assert budget.wait_for(200, now=0.0) == pytest.approx(100 / 1200)
    # larger than the limit: it goes once nothing is queued (else it never could)
    assert budget.wait_for(1500, now=0.0) == pytest.approx(200 / 1200)
    assert budget.wait_for(200, now=100 / 1200) == pytest.approx(0, abs=1e-9)
    assert budget.wait_for(1500, now=100 / 1200) == pytest.approx(100 / 1200)
    budget.spend(400, now=100 / 1200)
    assert budget.full(100 / 1200)
    assert budget.spent_over == 0
    budget.spend(100, now=100 / 1200)             # an urgent send goes, and counts, when full
    assert budget.spent_over == 100 and budget.queued(100 / 1200) == pytest.approx(600)


def test_the_limit_is_the_rate_times_the_target_above_the_floor():
    assert LinkBudget(1_000_000).limit == pytest.approx(1_000_000 * 0.15 / 8)
    assert LinkBudget(1_000_000, target=0.05).limit == pytest.approx(6250)


@pytest.mark.parametrize("rate", [0, -9600, math.inf, math.nan, "9600"])
def test_a_rate_the_budget_cannot_use_is_refused_by_name(rate):
    with pytest.raises(LinkBudgetError, match="a link budget needs a rate above 0 bit/s"):
        LinkBudget(rate)


def test_a_target_the_budget_cannot_use_is_refused_by_name():
    with pytest.raises(LinkBudgetError, match="target delay must be above 0 s"):
        LinkBudget(RATE, target=0)


def test_wire_sizes_count_every_header():
    assert datagram_bytes(100) == 100 + DATAGRAM_OVERHEAD
    assert tcp_bytes(100) == 100 + SEGMENT_OVERHEAD
    assert tcp_bytes(3000) == 3000 + 3 * SEGMENT_OVERHEAD        # three segments
    assert tcp_bytes(0) == SEGMENT_OVERHEAD


@given(st.lists(st.tuples(st.floats(0, 5), st.integers(0, 5000)), max_size=40))
def test_the_queue_never_holds_more_than_was_spent_nor_less_than_nothing(steps):
    budget = LinkBudget(RATE)
    now, total = 0.0, 0
    for gap, size in steps:
        now += gap
        before = budget.queued(now)
        budget.spend(size, now)
        total += size
        assert 0 <= before <= total
        assert budget.queued(now) == pytest.approx(before + size)
        # whatever is queued has drained once its time at the rate has passed
        later = now + budget.queued(now) * 8 / RATE + 1e-9
        assert budget.queued(later) == pytest.approx(0, abs=1e-6)
        now = later
