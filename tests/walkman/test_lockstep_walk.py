"""The robot on the lockstep clock, as processes: a walk is a function of its inputs (issue 65).

The HAL runs at ``--rtf max``, started paused (``--paused``, as Gazebo's ``-u``); the walking
module joins its clock (``--lockstep``).  The test steps the physics through ``/clock/rpc``
(``stepSimulationAndWait``), sends the walk with a reply (so it is in the module's inbox
before the next step), and reads the whole scene's ``qpos`` at the end of each chunk.  Two
runs, one quiet and one beside two CPU burners, must agree to 1e-6 m (in fact exactly: the
same states reach the module, the same commands reach the physics at the same steps).
"""

from __future__ import annotations

import signal
import threading
from typing import Dict, List

import numpy as np
import pytest

from tests.flake_hunt import burners
from tests.harness import wait_until
from tests.walkman.test_gym_hal import start_hal, start_module
from walkman.hal import protocol
from walkman.model import SCENE_PATH
from yarp_lite.bottle import Bottle
from yarp_lite.bottle_text import parse
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

#: Alone, though nothing in it is real-time: it starts two CPU burners, which would starve a
#: real-time robot of another test.
pytestmark = [pytest.mark.lockstep, pytest.mark.alone]

DT = 0.001
WORLD_EVERY = round((1.0 / 30) / DT)       # the HAL's world stream: every 33 steps
CHUNK = 15 * WORLD_EVERY                   # steps between two readings of the scene
CROUCH_STEPS = 4 * CHUNK                   # ~2 s: crouched, standing on its own
WALK_CHUNKS = 26                           # ~13 s: the metre walked, the robot idle again


class Scene:
    """Every ``/walkman/sim/world:o`` message, by the step it was published at."""

    def __init__(self, name: str) -> None:
        import mujoco

        self.nq = mujoco.MjModel.from_xml_path(str(SCENE_PATH)).nq
        self.at: Dict[int, np.ndarray] = {}
        self._lock = threading.Lock()
        self.port = BufferedPort(name, on_read=self._read, strict=True)
        # fast_tcp: no acknowledgement to wait for, so the HAL never skips this reader as busy
        NameClient().subscribe(protocol.world_port_name("walkman"), f"fast_tcp:/{self.port.name}")
        assert self.port.wait_for_inputs(1, 20)

    def _read(self, bottle: Bottle) -> None:
        when, qpos = protocol.decode_world(bottle, self.nq)
        with self._lock:
            self.at[round(when / DT)] = np.array(qpos)

    def qpos_at(self, step: int) -> np.ndarray:
        wait_until(lambda: step in self.at, 20, message=f"the scene at step {step}")
        with self._lock:
            return self.at[step]

    def close(self) -> None:
        self.port.close()


class ClockClient:
    def __init__(self, name: str) -> None:
        self.port = Port().open(name)
        self.port.add_output("/clock/rpc")

    def ask(self, text: str) -> Bottle:
        reply = self.port.write_with_reply(parse(text), timeout=120)
        assert reply is not None and (not reply or reply[0] != "fail"), f"{text}: {reply}"
        return reply

    def close(self) -> None:
        self.port.close()


def walk_once(world, run: str) -> List[np.ndarray]:
    """The metre walked from a paused start: the scene at the end of each chunk."""
    hal = start_hal(world, "sim", "--station", "yard", "--harness", "off", "--clock",
                    "--rtf", "max", "--paused")
    module = start_module(world, "walking", "--lockstep")
    module.wait_for("ready for the pilot", timeout=60)
    scene = Scene(f"/test/{run}/world:i")
    clock = ClockClient(f"/test/{run}/clock:o")
    commands = Port().open(f"/test/{run}/command:o")
    commands.add_output("/walking/command:i")
    switch = Port().open(f"/test/{run}/switch:o")
    switch.add_output("/walking/switch:i")
    try:
        assert switch.write_with_reply(parse("start"), timeout=30) is not None
        hal.wait_for("lockstep: /walking joined", timeout=30)
        taken = 0
        clock.ask(f"stepSimulationAndWait {CROUCH_STEPS}")
        taken += CROUCH_STEPS
        poses = [scene.qpos_at(taken)]
        # In its inbox before the next step: the reply comes once the port's reader took it.
        assert commands.write_with_reply(parse("go_straight 1.0"), timeout=30) is not None
        for _ in range(WALK_CHUNKS):
            clock.ask(f"stepSimulationAndWait {CHUNK}")
            taken += CHUNK
            poses.append(scene.qpos_at(taken))
    finally:
        for port in (commands, switch):
            port.close()
        clock.close()
        scene.close()
        for proc in (module, hal):
            proc.kill(signal.SIGTERM)
            proc.wait(30)
    # No module left the barrier: a run where one did is not the robot in lockstep.
    assert "'lockstep_timeouts': 0" in hal.output(), hal.output()[-3000:]
    return poses


def own_world(make_world, lite, monkeypatch, name: str):
    """A name server for one walk.  Not one for both: the first walk's module, ending while
    the second's starts, would unsubscribe the connections of the same names (its robot's
    state and sensors) that the second had just made."""
    world = make_world(lite, name)
    world.apply_to_process(monkeypatch)
    return world


def test_a_metre_walked_twice_in_lockstep_at_max_quiet_and_beside_two_burners_agrees(
        make_world, lite, monkeypatch):
    quiet = walk_once(own_world(make_world, lite, monkeypatch, "quiet"), "quiet")
    base = quiet[-1][:3]
    assert base[0] - quiet[0][0] >= 0.9, f"walked {base[0] - quiet[0][0]:.3f} m, not a metre"
    assert base[2] > 0.7, f"the pelvis at {base[2]:.3f} m: fallen"
    with burners(2):
        loaded = walk_once(own_world(make_world, lite, monkeypatch, "loaded"), "loaded")
    worst = max(float(np.max(np.abs(a - b))) for a, b in zip(quiet, loaded))
    assert worst <= 1e-6, f"the two walks differ by up to {worst:.3g} (m or rad)"
