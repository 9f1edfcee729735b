"""The tutorial module of docs/drc-tasks.md, exactly as printed there, run as a user runs it:
the pilot's commands, the module's states, and the right hand where the HAL says it is."""

import os
import re
import sys
import threading
from pathlib import Path

import numpy as np

from tests.walkman.test_gym_hal import Pilot, probe, start_hal  # noqa: F401 (a fixture)

TUTORIAL = Path(__file__).resolve().parents[2] / "docs" / "drc-tasks.md"
STATES = ["down", "raising", "up", "waving", "lowering"]


def tutorial_code() -> str:
    text = TUTORIAL.read_text()
    match = re.search(r"<!-- tutorial:my_wave.py -->\n```python\n(.*?)```", text, re.S)
    assert match, f"{TUTORIAL.name} lost its tutorial block"
    return match.group(1)


class Hand:
    """The right hand's position, from the joints the HAL streams (forward kinematics)."""

    def __init__(self, robot) -> None:
        from walkman.control.kinematics import Kinematics

        self.robot, self.kinematics = robot, Kinematics()
        self.samples = []
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()

    def now(self) -> np.ndarray:
        return self.kinematics.pose(self.robot.sense_position(), "r_hand")[0]

    def _sample(self) -> None:
        while not self.done.wait(0.02):
            self.samples.append(self.now())

    def since(self, count: int) -> np.ndarray:
        return np.array(self.samples[count:])

    def close(self) -> None:
        self.done.set()
        self.thread.join(2)


def test_the_tutorial_module_runs_first_time(lite_world, lite, tmp_path, probe):
    (tmp_path / "my_wave.py").write_text(tutorial_code())
    start_hal(lite_world, "sim")
    env = dict(lite_world.env)
    env["PYTHONPATH"] = f"{tmp_path}{os.pathsep}{env.get('PYTHONPATH', '')}"
    module = lite_world.start([sys.executable, "-m", "walkman.gym.supervisor", "my_wave:Module"],
                              "my_wave", env=env)
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "my_wave", STATES)
    hand = Hand(probe())
    try:
        pilot.send(lite, "switch", "start")
        pilot.wait_state("down", 30)
        down = hand.now()
        pilot.send(lite, "command", "wave")
        pilot.wait_warning("'wave' is not accepted in state down (accepted: raise)")
        assert np.linalg.norm(hand.now() - down) < 0.02, "a refused command moved the arm"
        reached = {}
        for command, state in (("raise", "up"), ("wave", "up"), ("lower", "down")):
            before = len(hand.samples)
            pilot.send(lite, "command", command)
            moving = {"raise": "raising", "wave": "waving", "lower": "lowering"}[command]
            pilot.wait_state(moving, 10)
            pilot.wait_state(state, 30)
            reached[command], reached[command + " path"] = hand.now(), hand.since(before)
    finally:
        hand.close()
        pilot.close()
    # raise: 30 cm forward, 35 up (the tutorial's goal), as the HAL's joints place the hand
    assert np.linalg.norm(reached["raise"] - (down + [0.3, 0.0, 0.35])) < 0.06, \
        (down, reached["raise"])
    # wave: an arc of 0.8 rad about the forward axis, 20 cm below the hand: it ends 14 cm
    # (0.2 sin 0.8) sideways and 6 cm (0.2 (1 - cos 0.8)) lower, as far forward
    arc = reached["wave"] - reached["raise"]
    assert abs(abs(arc[1]) - 0.2 * np.sin(0.8)) < 0.04 and abs(arc[0]) < 0.04, arc
    assert abs(-arc[2] - 0.2 * (1 - np.cos(0.8))) < 0.04, arc
    assert len(reached["wave path"]) > 5, "the hand was not followed while it waved"
    # lower: back where it started
    assert np.linalg.norm(reached["lower"] - down) < 0.06, (down, reached["lower"])
