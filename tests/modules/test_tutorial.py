"""The README's tutorial module, exactly as printed there, run as a user runs it."""

import os
import re
import sys
from pathlib import Path

from tests.walkman.test_gym_hal import Pilot, start_hal

README = Path(__file__).resolve().parents[2] / "README.md"
STATES = ["down", "raising", "up", "waving", "lowering"]


def tutorial_code() -> str:
    text = README.read_text()
    match = re.search(r"<!-- tutorial:my_wave.py -->\n```python\n(.*?)```", text, re.S)
    assert match, "README lost its tutorial block"
    return match.group(1)


def test_the_tutorial_module_runs_first_time(lite_world, lite, tmp_path):
    (tmp_path / "my_wave.py").write_text(tutorial_code())
    start_hal(lite_world, "sim")
    env = dict(lite_world.env)
    env["PYTHONPATH"] = f"{tmp_path}{os.pathsep}{env.get('PYTHONPATH', '')}"
    module = lite_world.start([sys.executable, "-m", "walkman.gym.supervisor", "my_wave:Module"],
                              "my_wave", env=env)
    module.wait_for("ready for the pilot", timeout=60)
    pilot = Pilot(lite_world, "my_wave", STATES)
    try:
        pilot.send(lite, "switch", "start")
        pilot.wait_state("down", 30)
        pilot.send(lite, "command", "wave")
        pilot.wait_warning("'wave' is not accepted in state down (accepted: raise)")
        for command, state in (("raise", "up"), ("wave", "up"), ("lower", "down")):
            pilot.send(lite, "command", command)
            moving = {"raise": "raising", "wave": "waving", "lower": "lowering"}[command]
            pilot.wait_state(moving, 10)
            pilot.wait_state(state, 30)
    finally:
        pilot.close()
