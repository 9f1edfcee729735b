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


def test_a_station_s_posture_is_every_chain_s_goal_seated_in_the_car_and_standing_again():
    """``set station``: the robot set down seated (the car) or standing, every chain's goal
    and reference its posture there -- a goal left from before would stand the robot up
    into the car's seat, or walk its legs back to the seat at the next station."""
    import numpy as np

    from walkman.model.mjcf import SEATED_POSTURE

    backend = server.make_backend("sim", True, "off", 1.0, "valve")
    hal = server.HalServer(backend, load_config(MODELS_DIR / "hal_chains.ini"))
    home = backend.reference.copy()
    try:
        for station, posture in (("car", SEATED_POSTURE), ("yard", {})):
            hal.go_to_station(station)
            hal._apply_commands()
            for joint, angle in posture.items():
                assert backend.reference[backend.index[joint]] == pytest.approx(angle)
            unset = [i for i, name in enumerate(backend.joint_names) if name not in posture]
            assert backend.reference[unset] == pytest.approx(home[unset])
            for chain in hal.chains.values():
                here = np.degrees(backend.reference[chain.indices])
                assert chain.vector("target_positions") == pytest.approx(here.tolist())
                assert chain.vector("direct_references") == pytest.approx(here.tolist())
                assert chain.motion_done(range(len(chain.joints)))
            placed = backend.plant.base_pose()
            for _ in range(500):
                hal._apply_commands()
                backend.step()
            # Still where it was set down, seated on the seat or standing on its feet.
            assert backend.plant.base_pose() == pytest.approx(placed, abs=0.02), station
    finally:
        backend.close()
