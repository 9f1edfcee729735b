"""Adaptive FEC: repairs sized for the measured loss, within the rate, from the receiver's totals."""

from __future__ import annotations

import math
import random

import pytest

from bridge.transport.adaptive_fec import (MAX_FRACTION, MIN_CAP, PRIOR_LOSS, TARGET, WINDOW,
                                           FecAdapter, LossMeter, repairs_needed, wilson_upper)
from bridge.wire.datagrams import Report


def decodes(k: int, m: int, loss: float) -> float:
    """P(at most m of k + m lost), the same binomial written independently."""
    n = k + m
    return sum(math.comb(n, j) * loss ** j * (1 - loss) ** (n - j) for j in range(m + 1))


@pytest.mark.parametrize("k", [1, 4, 12, 32])
@pytest.mark.parametrize("loss", [0.01, 0.05, 0.2, 0.3])
def test_repairs_are_the_fewest_that_reach_the_target(k, loss):
    m = repairs_needed(k, loss)
    assert decodes(k, m, loss) >= TARGET
    assert m == 0 or decodes(k, m - 1, loss) < TARGET


def test_repairs_grow_with_loss_and_none_on_a_clean_link():
    counts = [repairs_needed(32, loss / 100) for loss in range(0, 40, 5)]
    assert counts[0] == 0 and counts == sorted(counts) and counts[-1] > counts[1]
    # At 30 % a fixed fraction of 0.3 (10 repairs for 32) is far from enough.
    assert repairs_needed(32, 0.3) > 2 * 10


def test_the_limit_caps_the_repairs():
    assert repairs_needed(32, 0.3, limit=5) == 5
    assert repairs_needed(10, 0.9) == int(10 * MAX_FRACTION)
    assert repairs_needed(1, 0.9) == MIN_CAP


def test_the_wilson_bound_is_above_the_rate_and_tightens_with_samples():
    assert wilson_upper(0, 0) == 1.0
    few, many = wilson_upper(20, 100), wilson_upper(2000, 10000)
    assert few > many > 0.2


def test_the_meter_reports_only_when_something_was_counted():
    meter = LossMeter()
    assert meter.report() is None
    meter.record(received=9, expected=10)
    meter.late()
    assert meter.report() == Report(received=10, expected=10)
    assert meter.report() is None
    meter.record(received=0, expected=4)
    assert meter.report() == Report(received=10, expected=14) and meter.loss == pytest.approx(4 / 14)


def test_the_adapter_starts_from_the_prior_then_follows_the_reports():
    adapter = FecAdapter()
    assert adapter.loss_bound() == PRIOR_LOSS and adapter.measured() is None
    rng = random.Random(3)
    received = expected = 0
    for tick in range(20):        # 20 % loss, 200 datagrams every half second
        expected += 200
        received += sum(rng.random() > 0.2 for _ in range(200))
        adapter.on_report(Report(received, expected), now=tick * 0.5)
    lost, seen = adapter.measured()
    assert seen == 200 * (WINDOW / 0.5 + 1)              # only the window counts
    assert 0.17 < lost / seen < 0.23
    assert lost / seen < adapter.loss_bound() < 0.26
    assert adapter.repairs(32, now=10.0) == repairs_needed(32, round(adapter.loss_bound(), 3))


def test_a_lost_report_is_covered_by_the_next_and_a_restart_starts_over():
    adapter = FecAdapter()
    adapter.on_report(Report(90, 100), now=0.0)
    adapter.on_report(Report(270, 300), now=1.0)      # one report in between was lost
    assert adapter.measured() == (30, 300)
    adapter.on_report(Report(50, 50), now=2.0)        # the receiver restarted
    assert adapter.measured() == (30, 350)


def test_the_rate_budget_caps_the_repairs():
    adapter = FecAdapter(rate=100_000)
    adapter.on_report(Report(700, 1000), now=0.0)     # 30 % loss
    for second in range(5):                           # 80 kbit/s of data out of 100
        adapter.note_sent(10_000, now=float(second))
    cap = adapter.fraction_cap(now=5.0)
    assert cap == pytest.approx(0.9 * 100_000 / 80_000 - 1, abs=0.01)
    assert adapter.repairs(32, now=5.0) == math.floor(32 * cap)
    unpaced = FecAdapter()
    unpaced.on_report(Report(700, 1000), now=0.0)
    assert unpaced.repairs(32, now=5.0) == repairs_needed(32, round(unpaced.loss_bound(), 3))


def test_a_stops_copies_follow_the_loss_never_fewer_than_configured():
    from bridge.transport.adaptive_fec import MAX_COPIES, copies_needed

    assert copies_needed(0.0, 3) == 3 and copies_needed(0.05, 3) == 3
    assert copies_needed(0.3, 3) == 6            # 0.3 ** 6 = 0.07 % all lost
    assert 0.3 ** copies_needed(0.3, 3) <= 0.001 < 0.3 ** (copies_needed(0.3, 3) - 1)
    assert copies_needed(0.9, 3) == copies_needed(1.0, 3) == MAX_COPIES
    assert copies_needed(0.3, 10) == 10          # the configuration's, when it asks more
