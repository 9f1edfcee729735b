"""The chaos pilot's plan for each numbered command (system/chaos_pilot.py)."""

from system.chaos_pilot import plan


def test_every_kth_command_is_short_lived_and_every_jth_cancelled():
    plans = {n: plan(n, short_every=5, short_validity=3.0, cancel_every=7) for n in range(1, 36)}
    assert [n for n, p in plans.items() if p.validity] == [5, 10, 15, 20, 25, 30, 35]
    assert all(p.validity == 3.0 for p in plans.values() if p.validity)
    assert [n for n, p in plans.items() if p.cancel] == [7, 14, 21, 28, 35]
    assert [n for n, p in plans.items() if not p.plain] == \
        [5, 7, 10, 14, 15, 20, 21, 25, 28, 30, 35]


def test_zero_sends_every_command_plain():
    assert all(plan(n, 0, 3.0, 0).plain for n in range(1, 50))
