"""Each DRC task piloted only with the ROS tools, through the pilot gateway (one PC, lab).

The HAL (MuJoCo) at the task's station, the module under the supervisor, the gateway;
the pilot uses ``rosservice call`` alone, and the scene is read from the HAL's world port.
"""

import itertools
import math
import sys

import pytest

from system.processes import wait_until
from walkman.model.mjcf import PILOT_POSES
from walkman import MODELS_DIR

PYTHON = sys.executable
CONFIG = MODELS_DIR / "bridge_drc.xml"
VALVE, WHEEL, DOOR = PILOT_POSES["valve"], PILOT_POSES["car"], PILOT_POSES["door"]
GRASP = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"))


class RosPilot:
    """One module piloted with ``rosservice call``, its states and warnings followed with
    ``rostopic echo`` (which sees every state, even one shorter than a service call)."""

    def __init__(self, pc, module: str) -> None:
        self.pc, self.module = pc, module
        self.states = pc.start(f"{module}-states",
                               ["rostopic", "echo", f"/{module}/status/state"])
        self.warnings = pc.start(f"{module}-warnings",
                                 ["rostopic", "echo", f"/{module}/warning/text"])
        # The module sends its status every second: the first one says we are subscribed.
        self.states.wait_for(r'^"', 30)

    def call(self, service: str, request: str = "") -> str:
        args = ["rosservice", "call", f"/{self.module}/{service}"] + ([request] if request else [])
        return self.pc.run(args, timeout=60).output()

    def _seen(self) -> list:
        """Every state the status topic said so far, in order."""
        return [line.strip('"') for line in list(self.states.lines) if line.startswith('"')]

    def wait_state(self, state: str, timeout: float = 60, after: str = "") -> None:
        """Until the module's latest status says ``state``."""
        wait_until(lambda: self._seen()[-1:] == [state], timeout,
                   message=f"{self.module} {state} after {after} (states: {self._seen()[-5:]})")

    def send(self, request: str) -> None:
        reply = self.call("send_command", request)
        assert "ok: True" in reply, reply

    def step(self, request: str, state: str, timeout: float = 60) -> None:
        """Send, and wait until the module has said ``state`` since; from ``state`` back to
        it, see it leave first."""
        mark = len(self._seen())
        was = self._seen()[-1]
        self.send(request)

        def reached() -> bool:
            since = self._seen()[mark:]
            if was == state:  # only what follows the first other state counts
                since = list(itertools.dropwhile(lambda seen: seen == state, since))
            return state in since

        wait_until(reached, timeout, message=f"{self.module} {state} after {request} "
                                             f"(states since: {self._seen()[mark:][-5:]})")

    def refused(self, request: str, reason: str) -> None:
        """Send; the module refuses it (its warning says ``reason``) and stays where it was."""
        was = self._seen()[-1]
        self.send(request)
        self.warnings.wait_for(reason, 20)
        assert self._seen()[-1] == was, self._seen()[-5:]

    def steps(self, pairs) -> None:
        for command, state in pairs:
            self.step(f"{{command: {command}}}", state)

    def follow(self, joint: str):
        """A probe printing the scene joint's every value (``JOINT VALUE`` lines)."""
        probe = self.pc.start(f"follow-{joint}",
                              [PYTHON, "-m", "tests.modules.scene", "--follow", joint])
        probe.wait_for(f"^{joint} ", 60)
        return probe

    def scene(self, *joints: str) -> dict:
        """The sim's ground truth: ``base_x``, ``base_yaw`` and the scene joints asked."""
        out = self.pc.run([PYTHON, "-m", "tests.modules.scene", *joints], timeout=60).output()
        words = out.split()
        names = ["base_x", "base_yaw", *joints]
        return {name: float(words[words.index(name) + 1]) for name in names}


@pytest.fixture
def pilot_at(make_pc):
    """``pilot_at(station, module, *hal_options)``: HAL, module and gateway up, started."""

    def start(station: str, module: str, *hal_options: str) -> RosPilot:
        pc = make_pc()
        pc.start_name_servers()
        pc.start("hal", [PYTHON, "-m", "walkman.hal.server", "--station", station,
                         *hal_options]).wait_for("HAL for walkman", 60)
        pc.start(module, [PYTHON, "-m", "walkman.gym.supervisor", module]).wait_for(
            "ready for the pilot", 60)
        gateway = pc.start("gateway", [PYTHON, "-m", "rosnodes.gateway", "--config",
                                       str(CONFIG), "--modules", module])
        gateway.wait_for(r"ROS topics and services up", 60)
        gateway.wait_for(rf"connected .*/{module}/command:o -> /{module}/command:i", 30)
        pilot = RosPilot(pc, module)
        assert "ok: True" in pilot.call("switch_and_wait", "{command: start}")
        pilot.wait_state("idle", 30, "start")
        return pilot

    return start


def test_the_valve_task_through_rosservice(pilot_at):
    valve = pilot_at("valve", "drc_valve")
    # Illegal in this state: refused by the module, said on /drc_valve/warning.
    valve.refused("{command: grasp}", "'grasp' is not accepted in state idle")
    valve.step(f"{{text: '{VALVE}'}}", "ready")
    valve.steps(GRASP)
    before = valve.scene("valve")["valve"]
    valve.step("{command: turn, numbers: [1.5708]}", "turning", 20)
    valve.wait_state("grasped", 60, "the turn")
    turned = valve.scene("valve")["valve"] - before
    assert math.isclose(turned, math.pi / 2, rel_tol=0.1), turned
    valve.steps((("ungrasp", "ungrasped"), ("move_away", "moved_away"), ("home", "idle")))


def test_the_drive_task_through_rosservice(pilot_at):
    drive = pilot_at("car", "drc_drive", "--harness", "off")     # seated: the seat holds it
    drive.step(f"{{text: '{WHEEL}'}}", "ready")
    drive.steps(GRASP + (("drive", "drive"),))
    before = drive.scene("steering")["steering"]
    drive.step("{command: turn_left, numbers: [0.5]}", "turning_left", 20)
    drive.wait_state("drive", 60, "turn_left")
    turned = drive.scene("steering")["steering"] - before
    assert math.isclose(turned, 0.5, rel_tol=0.1), turned
    drive.step("{command: rotate_foot}", "drive")
    # Pressed for three seconds only: watched as it happens (a probe per look may take
    # longer than the press on a loaded machine, and look before and after it).
    throttle = drive.follow("throttle")
    drive.step("{command: accelerate, numbers: [3.0]}", "accelerating", 20)
    drive.wait_state("drive", 60, "accelerate")
    pressed = max(float(line.split()[1]) for line in list(throttle.lines)
                  if line.startswith("throttle "))
    assert pressed > 0.05, pressed  # of the pad's 0.35 rad
    drive.steps((("move_away_foot", "drive"), ("ungrasp", "ungrasped"),
                 ("move_away_hand", "moved_away_hand")))


def test_the_door_task_through_rosservice(pilot_at):
    door = pilot_at("door", "drc_door")
    door.step(f"{{text: '{DOOR}'}}", "ready")
    door.steps(GRASP + (("turn", "turned"), ("open", "opened"), ("ungrasp", "ungrasped"),
                        ("move_away", "moved_away"), ("home", "idle")))
    assert math.degrees(door.scene("door")["door"]) > 30


@pytest.mark.free_standing
def test_walking_through_rosservice(pilot_at):
    walk = pilot_at("yard", "walking", "--harness", "off")
    before = walk.scene()["base_x"]
    walk.step("{command: go_straight, numbers: [0.5]}", "walking", 20)
    walk.wait_state("idle", 60, "go_straight 0.5")
    assert walk.scene()["base_x"] - before >= 0.4
