"""yarp_lite/time.py: YARP's Time over the system clock, a network clock, or a manual one."""

from __future__ import annotations

import os
import socket
import threading

import pytest

from harness import wait_until
from yarp_lite import time as yarp_time
from yarp_lite.bottle import Bottle
from yarp_lite.errors import LocalProtocolError


def delayed_in_thread(clock, seconds: float) -> threading.Event:
    done = threading.Event()
    threading.Thread(target=lambda: (clock.delay(seconds), done.set()), daemon=True).start()
    return done


def test_the_port_a_process_reads_its_clock_on_is_named_as_yarp_names_it():
    name = yarp_time.process_clock_port()
    host, rest = f"/{socket.gethostname()}/", f"/{os.getpid()}/clock:i"
    assert name.startswith(host) and name.endswith(rest)
    with open("/proc/self/cmdline", "rb") as cmdline:
        program = cmdline.read().split(b"\0")[0].decode()
    assert name == f"{host}{program}{rest}"


@pytest.mark.parametrize("value, source", [("", None), ("  ", None), ("/clock", "/clock"),
                                           ("/robot/clock", "/robot/clock")])
def test_yarp_clock_names_the_source_and_empty_means_the_system_clock(value, source):
    assert yarp_time.source_from_environment({"YARP_CLOCK": value}) == source
    assert yarp_time.source_from_environment({}) is None


def test_a_delay_on_a_network_clock_returns_when_a_tick_reaches_it_however_long_that_takes():
    clock = yarp_time.NetworkClock("/clock", "/test/clock:i")
    clock.feed(5.0)
    done = delayed_in_thread(clock, 0.1)
    clock.feed(5.05)
    assert not done.wait(0.3), "returned before the clock reached 5.1 s"
    clock.feed(5.1)
    assert done.wait(5.0)
    assert clock.now() == 5.1


def test_a_malformed_tick_is_refused_and_the_time_stays():
    clock = yarp_time.NetworkClock("/clock", "/test/clock:i")
    clock.feed(2.0)
    clock._on_tick(Bottle([2.5]))
    clock._on_tick(Bottle(["soon", 0]))
    assert clock.now() == 2.0 and clock.refused == 2 and clock.ticks == 1


def test_a_clock_going_back_moves_every_pending_delay_back_with_it():
    """A simulation's time reset: each delay still waits the simulated time it asked for
    (YARP moves only the first waiter's)."""
    clock = yarp_time.NetworkClock("/clock", "/test/clock:i")
    clock.feed(10.0)
    short, long_ = delayed_in_thread(clock, 0.5), delayed_in_thread(clock, 1.0)
    wait_until(lambda: len(clock._cond._waiters) == 2, timeout=5, message="both waiting")
    clock.feed(10.2)
    clock.feed(1.0)                      # reset: 0.2 s had passed of each wait
    clock.feed(1.29)
    assert not short.wait(0.2) and not long_.is_set()
    clock.feed(1.3)
    assert short.wait(5.0) and not long_.wait(0.2)
    clock.feed(1.8)
    assert long_.wait(5.0)


def test_closing_a_network_clock_lets_every_delay_finish_on_the_system_clock():
    clock = yarp_time.NetworkClock("/clock", "/test/clock:i")
    clock.feed(1.0)
    done = delayed_in_thread(clock, 3600.0 * 24)
    short = delayed_in_thread(clock, 0.05)
    assert not short.wait(0.2)
    clock.close()
    assert short.wait(5.0)
    assert not done.is_set()             # a day's delay still takes a day, of wall time now


def test_a_pacer_ticks_on_its_clocks_schedule_and_restarts_after_a_long_stall():
    clock = yarp_time.ManualClock(100.0)
    pacer = yarp_time.Pacer(0.01, clock)
    woke = []

    def loop():
        for _ in range(3):
            woke.append(pacer.wait())

    runner = threading.Thread(target=loop, daemon=True)
    runner.start()
    for _ in range(3):
        wait_until(lambda: clock._cond._waiters, timeout=5, message="pacer waiting")
        clock.advance(0.01)
    runner.join(5.0)
    assert woke == [0.0, 0.0, 0.0] and pacer.overruns == 0
    clock.advance(0.5)                   # the loop stalled 50 periods: no burst after
    assert pacer.wait() == pytest.approx(0.49)
    assert pacer.overruns == 1 and pacer.due == pytest.approx(100.53 + 0.01)


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan")])
def test_a_pacer_needs_a_period_above_zero(period):
    with pytest.raises(LocalProtocolError, match="period must be above 0"):
        yarp_time.Pacer(period, yarp_time.ManualClock())


def test_a_manual_clock_only_goes_forward():
    with pytest.raises(LocalProtocolError, match="only goes forward"):
        yarp_time.ManualClock().advance(-1)


def test_the_process_clock_is_the_system_clock_without_yarp_clock(monkeypatch):
    monkeypatch.delenv("YARP_CLOCK", raising=False)
    monkeypatch.setattr(yarp_time, "_clock", None)
    assert yarp_time.is_system_clock()
    before = yarp_time.now()
    yarp_time.delay(0.01)
    assert yarp_time.now() >= before + 0.01
