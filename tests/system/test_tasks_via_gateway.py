"""A DRC task piloted only with the ROS tools, through the pilot gateway (one PC, lab)."""

import math
import sys

from system.processes import wait_until
from system.topology import REPO

PYTHON = sys.executable
CONFIG = REPO / "models" / "bridge_drc.xml"
VALVE_ANGLE = """
from walkman.hal import protocol
from walkman.model import SCENE_PATH
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient
import mujoco
model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
port = BufferedPort("/probe/world:i")
NameClient().subscribe(protocol.world_port_name("walkman"), port.name)
values = protocol.decode_world(port.read(timeout=20), model.nq)[1]
print("valve", values[model.joint("valve").qposadr[0]])
port.close()
"""


def rosservice(pc, *args: str) -> str:
    return pc.run(["rosservice", "call", *args], timeout=60).output()


def valve_angle(pc) -> float:
    out = pc.run([PYTHON, "-c", VALVE_ANGLE], timeout=60).output()
    return float(out.split("valve")[-1].split()[0])


def test_the_valve_task_through_rosservice(make_pc):
    pc = make_pc()
    pc.start_name_servers()
    pc.start("hal", [PYTHON, "-m", "walkman.hal.server", "--station", "valve"]).wait_for(
        "HAL for walkman", 60)
    pc.start("drc_valve", [PYTHON, "-m", "walkman.gym.supervisor", "drc_valve"]).wait_for(
        "ready for the pilot", 60)
    gateway = pc.start("gateway", [PYTHON, "-m", "rosnodes.gateway", "--config", str(CONFIG),
                                   "--modules", "drc_valve"])
    gateway.wait_for(r"ROS topics and services up", 60)
    gateway.wait_for(r"connected .*/drc_valve/command:o -> /drc_valve/command:i", 30)

    def wait_state(state: str, timeout: float = 60, after: str = "") -> None:
        wait_until(lambda: f'state: "{state}"' in rosservice(pc, "/drc_valve/get_status"),
                   timeout, message=f"drc_valve {state} after {after}")

    def step(request: str, state: str, timeout: float = 60) -> None:
        reply = rosservice(pc, "/drc_valve/send_command", request)
        assert "ok: True" in reply, reply
        wait_state(state, timeout, request)

    assert "ok: True" in rosservice(pc, "/drc_valve/switch_and_wait", "{command: start}")
    wait_until(lambda: 'state: "idle"' in rosservice(pc, "/drc_valve/get_status"), 30,
               message="drc_valve idle")
    # Illegal in this state: refused by the module, said on /drc_valve/warning.
    step("{command: grasp}", "idle", 10)
    step("{text: 'valvedatasent 0.66 0.25 0.08 0 0 0 0.15'}", "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped")):
        step(f"{{command: {command}}}", state)
    before = valve_angle(pc)
    step("{command: turn, numbers: [1.5708]}", "turning", 20)
    wait_state("grasped", 60, "the turn")
    turned = valve_angle(pc) - before
    assert math.isclose(turned, math.pi / 2, rel_tol=0.1), turned
    for command, state in (("ungrasp", "ungrasped"), ("move_away", "moved_away"),
                           ("home", "idle")):
        step(f"{{command: {command}}}", state)
