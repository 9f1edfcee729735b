"""The emulated radio's schedule (netem/radio_model.py): pure, so every time here is exact."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, strategies as st

from netem.radio_model import (MAX_FRAME, QUEUE_MIN_FRAMES, Drop, RadioChannel,
                                RadioSettings, RadioSettingsError)

DEGRADED = RadioSettings(rate=9600, delay=0.05)


def never_lost() -> float:
    raise AssertionError("no random draw without loss")


def frame(size: int) -> bytes:
    return bytes(size)


def test_a_100_byte_frame_at_9600_bit_s_takes_83_ms_plus_the_delay():
    channel = RadioChannel(DEGRADED, never_lost)
    arrival = channel.offer(frame(100), 10.0)
    assert arrival == pytest.approx(10.0 + 100 * 8 / 9600 + 0.05)
    assert arrival - 10.0 >= 0.0833 + 0.05
    assert channel.next_due() == arrival
    assert channel.take_due(arrival - 1e-6) == []
    assert channel.take_due(arrival) == [frame(100)]
    assert channel.next_due() is None
    assert channel.counters == {"offered": 1, "delivered": 1, "blackout": 0, "queue_full": 0,
                                "loss": 0}


def test_back_to_back_frames_serialise():
    channel = RadioChannel(DEGRADED, never_lost)
    arrivals = [channel.offer(frame(100), 0.0) for _ in range(3)]
    one = 100 * 8 / 9600
    assert arrivals == pytest.approx([one + 0.05, 2 * one + 0.05, 3 * one + 0.05])
    # A frame offered once the link is idle again starts at once, not behind the others.
    assert channel.offer(frame(100), 10.0) == pytest.approx(10.0 + one + 0.05)
    # One offered while the third is still being sent waits for it.
    channel = RadioChannel(DEGRADED, never_lost)
    channel.offer(frame(1200), 0.0)                               # 1 s on the air
    assert channel.offer(frame(1200), 0.4) == pytest.approx(2.0 + 0.05)


def test_the_queue_limit_drops_the_tail():
    channel = RadioChannel(RadioSettings(rate=9600, queue_bytes=2000), never_lost)
    assert isinstance(channel.offer(frame(1000), 0.0), float)     # sent from 0 to 0.833 s
    assert isinstance(channel.offer(frame(1000), 0.0), float)     # waits: 2000 bytes held
    assert channel.offer(frame(1000), 0.0) is Drop.QUEUE_FULL     # the tail
    assert channel.offer(frame(100), 0.1) is Drop.QUEUE_FULL
    assert channel.backlog(0.5) == 2000
    # Once the first has left, there is room for one more, behind the second.
    arrival = channel.offer(frame(1000), 0.9)
    assert arrival == pytest.approx(3 * 1000 * 8 / 9600)
    assert channel.counters[Drop.QUEUE_FULL.value] == 2


def test_an_empty_link_takes_a_frame_bigger_than_its_queue():
    channel = RadioChannel(RadioSettings(rate=9600, queue_bytes=MAX_FRAME), never_lost)
    assert isinstance(channel.offer(frame(MAX_FRAME), 0.0), float)
    assert channel.offer(frame(60), 0.0) is Drop.QUEUE_FULL


def test_the_default_queue_holds_half_a_second_or_three_full_frames():
    assert RadioSettings(rate=1e6).queue_limit == 62500
    assert RadioSettings(rate=9600).queue_limit == QUEUE_MIN_FRAMES * MAX_FRAME
    assert RadioSettings().queue_limit == math.inf
    assert RadioSettings(rate=9600, queue_bytes=5000).queue_limit == 5000


def test_a_lost_frame_used_its_airtime():
    draws = iter([0.01, 0.9])  # the first frame is lost (0.01 < 0.05), the second is not
    channel = RadioChannel(RadioSettings(rate=9600, loss=0.05), lambda: next(draws))
    assert channel.offer(frame(120), 0.0) is Drop.LOSS
    assert channel.offer(frame(120), 0.0) == pytest.approx(2 * 0.1)
    assert (channel.counters["offered"], channel.counters["loss"]) == (2, 1)


def test_the_same_random_source_gives_the_same_losses():
    def outcomes(seed: int):
        import random
        source = random.Random(seed)
        channel = RadioChannel(RadioSettings(rate=1e6, loss=0.3, delay=0.05), source.random)
        return [channel.offer(frame(100), i * 0.001) for i in range(200)]

    first = outcomes(7)
    assert first == outcomes(7)
    assert 20 < sum(outcome is Drop.LOSS for outcome in first) < 100


def test_no_rate_means_only_the_delay():
    channel = RadioChannel(RadioSettings(delay=0.2), never_lost)
    assert [channel.offer(frame(MAX_FRAME), 1.0) for _ in range(100)] == [1.2] * 100


def test_a_blackout_drops_arrivals_and_loses_what_is_under_way():
    channel = RadioChannel(DEGRADED, never_lost)
    channel.offer(frame(100), 0.0)
    channel.offer(frame(100), 0.0)
    channel.configure(RadioSettings(rate=9600, delay=0.05, blackout=True), 0.1)
    assert channel.next_due() is None and channel.take_due(10.0) == []
    assert channel.offer(frame(100), 0.2) is Drop.BLACKOUT
    assert channel.counters[Drop.BLACKOUT.value] == 3
    # The radio comes back empty: the next frame does not wait for the lost ones.
    channel.configure(DEGRADED, 5.0)
    assert channel.offer(frame(100), 5.0) == pytest.approx(5.0 + 100 * 8 / 9600 + 0.05)


def test_frames_keep_their_order_when_the_delay_shrinks():
    channel = RadioChannel(RadioSettings(delay=1.0), never_lost)
    first = channel.offer(b"first", 0.0)
    channel.configure(RadioSettings(delay=0.0), 0.1)
    second = channel.offer(b"second", 0.1)
    assert second >= first
    assert channel.take_due(1.0) == [b"first", b"second"]


def test_settings_name_what_is_wrong():
    for wrong, field in (({"rate": 0}, "rate"), ({"rate": -5.0}, "rate"),
                         ({"rate": math.inf}, "rate"), ({"delay": -1}, "delay"),
                         ({"loss": 1.5}, "loss"), ({"queue_bytes": 100}, "queue_bytes"),
                         ({"blackout": "yes"}, "blackout")):
        with pytest.raises(RadioSettingsError, match=field):
            RadioSettings(**wrong)
    with pytest.raises(RadioSettingsError, match="unknown setting.*speed"):
        RadioSettings().updated({"speed": 1})
    assert RadioSettings().updated({"rate": 9600, "loss": 0.1}) == RadioSettings(9600, 0, 0.1)


def test_only_a_plain_cable_is_ideal():
    assert RadioSettings().ideal
    for changes in ({"rate": 1e9}, {"delay": 0.001}, {"loss": 0.01}, {"blackout": True}):
        assert not RadioSettings().updated(changes).ideal


@given(rate=st.sampled_from([9600.0, 1e5, 1e6]),
       delay=st.sampled_from([0.0, 0.05]),
       queue=st.sampled_from([None, MAX_FRAME, 4000]),
       offers=st.lists(st.tuples(st.floats(0, 0.5), st.integers(42, MAX_FRAME)),
                       min_size=1, max_size=60))
def test_any_offers_keep_the_link_honest(rate, delay, queue, offers):
    """Whatever is offered: nothing comes out sooner than its own serialisation and delay,
    out of order, or sooner than the link could have sent everything before it; the queue
    never holds more than its limit; every frame is delivered or dropped, once."""
    settings = RadioSettings(rate=rate, delay=delay, queue_bytes=queue)
    channel = RadioChannel(settings, never_lost)
    now, accepted, previous = 0.0, [], -math.inf
    for gap, size in offers:
        now += gap
        held = channel.backlog(now)
        outcome = channel.offer(frame(size), now)
        if outcome is Drop.QUEUE_FULL:
            assert held and held + size > settings.queue_limit
            continue
        assert held == 0 or held + size <= settings.queue_limit
        assert outcome >= now + size * 8 / rate + delay - 1e-9
        assert outcome >= previous
        previous = outcome
        accepted.append((now, size, outcome))
    # Work conservation: frames j..k were all offered no sooner than j was, and the
    # transmitter sends one at a time, so k cannot leave before they have all been sent.
    for k, (_, _, arrival) in enumerate(accepted):
        for j in range(k + 1):
            airtime = sum(size for _, size, _ in accepted[j:k + 1]) * 8 / rate
            assert arrival >= accepted[j][0] + airtime + delay - 1e-9
    delivered = channel.take_due(previous)
    assert len(delivered) == len(accepted)
    assert channel.counters["offered"] == len(offers)
    assert channel.counters["delivered"] + channel.counters["queue_full"] == len(offers)
