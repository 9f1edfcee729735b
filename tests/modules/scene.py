"""The simulator's scene read from the HAL's world port, for tests that check the task's outcome.

Used in the test process (``tests/modules/conftest.py``) and run as a probe inside another
PC's environment (``python -m tests.modules.scene JOINT...``, tests/system).
"""

from __future__ import annotations

import math
import sys
from typing import List, Tuple

import mujoco

from walkman.hal import protocol
from walkman.model import SCENE_PATH
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient


class World:
    """The simulator's scene state, as the HAL publishes it (``/walkman/sim/world:o``)."""

    def __init__(self, port_name: str = "/test/world:i") -> None:
        self.model = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
        self.port = BufferedPort(port_name)
        NameClient().subscribe(protocol.world_port_name("walkman"), self.port.name)
        assert self.port.wait_for_inputs(1, 20)

    def _positions(self) -> List[float]:
        bottle = self.port.read(timeout=5)
        return protocol.decode_world(bottle, self.model.nq)[1]

    def prop(self, joint: str) -> float:
        """A scene joint's position: ``valve``, ``steering``, ``throttle``, ``door``..."""
        return self.timed_prop(joint)[1]

    def timed_prop(self, joint: str) -> Tuple[float, float]:
        """The simulator's time (s) and a scene joint's position then: durations measured on
        the robot's clock, which a reader held up by its machine does not stretch."""
        bottle = self.port.read(timeout=5)
        when, positions = protocol.decode_world(bottle, self.model.nq)
        return when, positions[self.model.joint(joint).qposadr[0]]

    def base(self) -> list:
        """The pelvis in the world: x, y, z, yaw (ground truth)."""
        adr = self.model.joint("base").qposadr[0]
        x, y, z, w, _, _, qz = self._positions()[adr:adr + 7]
        return [x, y, z, 2.0 * math.atan2(qz, w)]

    def tilt(self) -> float:
        """How far the pelvis leans from upright (rad), whichever way (ground truth)."""
        adr = self.model.joint("base").qposadr[0]
        w, x, y, z = self._positions()[adr + 3:adr + 7]
        # the pelvis's z axis in the world: its angle to the vertical
        up_z = 1.0 - 2.0 * (x * x + y * y)
        return math.acos(max(-1.0, min(1.0, up_z)))

    def body_position(self, joint: str) -> List[float]:
        """Where a free body is (x, y, z in the world), by its free joint's name."""
        adr = self.model.joint(joint).qposadr[0]
        return list(self._positions()[adr:adr + 3])

    def upright(self, joint: str) -> float:
        """The cosine of a free body's tilt from upright (1: standing straight)."""
        adr = self.model.joint(joint).qposadr[0]
        w, x, y, z = self._positions()[adr + 3:adr + 7]
        return 1.0 - 2.0 * (x * x + y * y)

    def data(self) -> mujoco.MjData:
        """The scene's kinematics now (bodies where the world's positions put them)."""
        d = mujoco.MjData(self.model)
        d.qpos[:] = self._positions()
        mujoco.mj_kinematics(self.model, d)
        return d

    def close(self) -> None:
        self.port.close()


def follow(world: World, joint: str) -> None:
    """Print ``following JOINT`` once subscribed, then ``JOINT VALUE`` for every world
    message, until killed: a test that waits for a passing motion (the throttle pressed for
    a few seconds) watches it happen instead of sampling it with probes slower than it."""
    print("following", joint, flush=True)
    while True:
        print(joint, world.prop(joint), flush=True)


def main(args: List[str]) -> None:
    """Print ``base_x X base_y Y base_yaw YAW``, ``base_z Z tilt T`` (m, rad) then ``JOINT VALUE``
    for each joint asked (``JOINT X Y Z upright COS`` for a free body's: the plug, the
    drill); ``--follow JOINT``: that joint's every value (:func:`follow`); ``--onto-ramp
    FORWARD PITCH``: the ``footsteps`` command onto the ramp's surface that far ahead
    (:func:`walkman.courses.ramp_footsteps`)."""
    world = World("/probe/world:i")
    try:
        if args[:1] == ["--follow"] and len(args) == 2:
            follow(world, args[1])
        if args[:1] == ["--onto-ramp"] and len(args) == 3:
            from walkman.courses import ramp_footsteps

            print(ramp_footsteps(world.data(), float(args[1]), float(args[2])))
            return
        joints = args
        x, y, z, yaw = world.base()
        print("base_x", x, "base_y", y, "base_yaw", yaw)
        print("base_z", z, "tilt", world.tilt())
        for joint in joints:
            if world.model.joint(joint).type == mujoco.mjtJoint.mjJNT_FREE:    # a loose part
                print(joint, *world.body_position(joint), "upright", world.upright(joint))
            else:
                print(joint, world.prop(joint))
    finally:
        world.close()


if __name__ == "__main__":
    main(sys.argv[1:])
