"""walkman/hal/server.py's physics loop: the steps of a state period back to back, one
wake-up each, and every state still published on its period."""

from __future__ import annotations

import threading
import time

import pytest

from walkman.hal import server
from walkman import MODELS_DIR
from walkman.hal.config import load_config


@pytest.mark.parametrize("state_every, dt, burst", [
    (2, 0.001, 2),      # the chains' HAL: a state every 2 ms, two steps per wake-up
    (1, 0.001, 1),      # the whole-body HAL: a state every step, a wake-up every step
    (10, 0.001, 2),     # a slow state stream: still at most 2 ms of steps at once
    (1, 0.002, 1),
    (4, 0.0005, 4),
])
def test_a_wakeup_runs_one_state_periods_steps_up_to_2_ms(state_every, dt, burst):
    assert server.steps_per_wakeup(state_every, dt) == burst


@pytest.mark.parametrize("config, most_sleeps_per_step", [("hal_chains.ini", 0.5),
                                                          ("hal_whole_body.ini", 1.0)])
def test_the_physics_thread_wakes_once_per_state_period(lite_world, monkeypatch, config,
                                                        most_sleeps_per_step):
    monkeypatch.setenv("WALKMAN_NO_RT", "1")     # not this test process's threads
    backend = server.make_backend("sim", False, "locked", 1.0, "valve")
    hal = server.HalServer(backend, load_config(MODELS_DIR / config), realtime=True)
    loop = threading.get_ident()
    sleeps = []
    real_sleep = time.sleep

    def sleep(seconds: float) -> None:
        if threading.get_ident() == loop:
            sleeps.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(server.time, "sleep", sleep)
    try:
        hal.open()
        hal.run(duration=0.4)
    finally:
        hal.close()
        backend.close()
    period_steps = round(hal.config.period_ms / 1000 / backend.dt)
    assert hal.steps == pytest.approx(400, abs=1)
    assert hal.state_stamp.count == hal.steps // period_steps     # every state published
    assert 0 < len(sleeps) <= hal.steps * most_sleeps_per_step + 1, (len(sleeps), hal.steps)
