"""The walking module offline on the simulated robot, the harness off: a robot standing at a
station, walks run to their end with the base checked upright, the soles as a pilot measures
them, and the rough-ground courses (the terrain's step, the ramp both ways, the kerb from the
head camera).  Shared by the tests (tests/modules/test_walking.py, tests/walkman/
test_preview.py, the PI's driver) and the benchmarks (bench/bench_walking.py), which must not
import the tests."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path
from collections import deque
from typing import Dict, List, Sequence, Tuple

import numpy as np

from walkman.control.ground_ahead import first_leg, footsteps_from_cloud
from walkman.gym.offline import OfflineModule, OfflineWorld
from walkman.hal.sim import SimBackend
from walkman.model.description import STANDING_PELVIS_HEIGHT
from walkman.model.mjcf import (DEBRIS_BOARD_HALF, DEBRIS_BOARDS, DEBRIS_FIELD_LANE,
                                PILOT_POSES, STATIONS, TERRAIN_COURSE, TERRAIN_RAMP)
from walkman.modules import walking

#: The pelvis walks CROUCH below its standing height; lower than this (m) it has fallen.
LOWEST_PELVIS = STANDING_PELVIS_HEIGHT - walking.CROUCH - 0.06
SOLE_ABOVE_FLOOR = 0.0994   # m: a foot body's height standing on the floor (its sole 0.1 below)
MAX_TILT = 0.1  # rad of the free base: more is not walking upright


class LateSensors:
    """The module's robot with its F/T and IMU readings ``ticks`` of its loop late: as the
    PI's runs have them, streamed over YARP ports to a 100-Hz loop on a loaded machine."""

    def __init__(self, robot, ticks: int) -> None:
        self.robot, self.ticks = robot, ticks
        self.readings: Dict[str, deque] = {}

    def _late(self, what: str, reading):
        kept = self.readings.setdefault(what, deque(maxlen=self.ticks + 1))
        kept.append(reading)
        return kept[0]

    def sense_ft(self, sensor: str) -> np.ndarray:
        return self._late(sensor, self.robot.sense_ft(sensor))

    def sense_imu(self):
        return self._late("imu", self.robot.sense_imu())

    def __getattr__(self, name: str):
        return getattr(self.robot, name)


def walker(station: str = "yard", contact: str = "soft",
           late_ticks: int = 0) -> Tuple[OfflineWorld, OfflineModule]:
    """The walking module started on the robot at ``station``; ``late_ticks``: its F/T and
    IMU readings that many ticks late (:class:`LateSensors`)."""
    backend = SimBackend(station=station, harness="off", contact=contact)
    world = OfflineWorld(backend)
    world.step(0.5)
    module = world.add(walking.Module, "walking")
    if late_ticks:
        module.thread.robot = LateSensors(module.thread.robot, late_ticks)
    module.switch("start")
    world.step(walking.CROUCH_TIME + 0.5)
    return world, module


def free_body(world: OfflineWorld, joint: str) -> np.ndarray:
    """A free body's position and orientation (x y z, qw qx qy qz) in the world."""
    plant = world.backend.plant
    adr = plant.m.joint(joint).qposadr[0]
    return np.array(plant.d.qpos[adr:adr + 7])


def tilt(backend) -> float:
    roll, pitch, _ = backend.imu().rpy
    return math.hypot(roll, pitch)


def upright(backend) -> bool:
    return tilt(backend) < MAX_TILT and backend.plant.base_pose()[2] > LOWEST_PELVIS


def both_feet_loaded(backend) -> bool:
    return all(backend.ft(sensor)[2] < -100 for sensor in ("l_leg_ft", "r_leg_ft"))


def walk_through(world, module, command: str, limit: float = 40.0) -> float:
    """Send ``command``, run until the module is idle again with the base upright every
    50 ms; returns the smallest ZMP margin the module measured on the way."""
    module.command(command)
    world.step(0.1)
    assert module.state != "idle", module.warnings
    smallest, start = math.inf, world.time
    while module.state != "idle":
        world.step(0.05)
        assert upright(world.backend), (command, world.time, world.backend.plant.base_pose())
        assert world.time - start < limit, command
        if module.thread.margin is not None:
            smallest = min(smallest, module.thread.margin)
    world.step(0.5)
    return smallest


def _data(source):
    """The MuJoCo data of a backend, or the data itself (a probe's, tests/modules/scene.py)."""
    plant = getattr(source, "plant", None)
    return source if plant is None else plant.d


def sole_heights(backend) -> Tuple[float, float]:
    """The world height of each sole's bottom (m): 0 on the floor."""
    return tuple(float(_data(backend).body(f"{side}_foot").xpos[2]) - SOLE_ABOVE_FLOOR
                 for side in "lr")


def soles_in_pelvis_frame(backend) -> Tuple[np.ndarray, np.ndarray]:
    """Each sole's centre as a pose (x, y, z, roll, pitch, yaw) in the pelvis frame, as a
    pilot measures it (from the world, the simulator's truth)."""
    d = _data(backend)
    pelvis, turn = d.body("pelvis").xpos, d.body("pelvis").xmat.reshape(3, 3)
    soles = []
    for side in "lr":
        rotation = d.body(f"{side}_foot").xmat.reshape(3, 3)
        x, y, z = turn.T @ (d.body(f"{side}_foot").xpos + rotation @ walking.SOLE - pelvis)
        r = turn.T @ rotation
        soles.append(np.array([x, y, z, math.atan2(r[2, 1], r[2, 2]), -math.asin(r[2, 0]),
                               math.atan2(r[1, 0], r[0, 0])]))
    return soles[0], soles[1]


def seen_from_the_crouched_pelvis(task: str, x: float, y: float, z: float) -> List[float]:
    """The README's pose numbers for ``task`` (given from the pelvis standing at the
    station, the harness holding it) moved by where the pelvis is now (``x y z`` in the
    world, the robot facing as the station does): what the perception pilot places for a
    robot that walking crouched.  Every point moves -- the object's, and the wall's circle
    centre (walldatasent's CX CY CZ); plugdatasent's DX DY is an offset and stays."""
    numbers = [float(word) for word in PILOT_POSES[task].split()[1:]]
    station_x, station_y, _ = STATIONS[task]
    shift = (station_x - x, station_y - y, STANDING_PELVIS_HEIGHT - z)
    for first in (0, 6) if task == "wall" else (0,):
        for axis, amount in enumerate(shift):
            numbers[first + axis] += amount
    return numbers


def footsteps(*soles: Sequence[float]) -> str:
    """The ``footsteps`` command for these sole poses (pelvis frame)."""
    return "footsteps " + " ".join(f"{v:.4f}" for sole in soles for v in sole)


Leg = Tuple[str, float, float]   # a course's command, its smallest ZMP margin (m), seconds

#: The debris field's boards lying across the way (nearly square to it), by index
#: (:data:`walkman.model.mjcf.DEBRIS_BOARDS`); the others lie beside the feet's lanes.
BOARDS_ACROSS = tuple(index for index, (_, _, yaw) in enumerate(DEBRIS_BOARDS)
                      if abs(math.cos(yaw)) > 0.9)
#: World x of the debris field's far end: the far edge of its last board across the way.
DEBRIS_FIELD_END = max(DEBRIS_BOARDS[index][0] for index in BOARDS_ACROSS) + \
    DEBRIS_BOARD_HALF[1]


def board_pose(source, index: int) -> np.ndarray:
    """Where debris board ``index`` lies now: world x, y offset from the field's lane, yaw
    (as :data:`walkman.model.mjcf.DEBRIS_BOARDS` gives it)."""
    d = _data(source)
    x, y, _ = d.body(f"debris_board{index}").xpos
    turn = d.body(f"debris_board{index}").xmat.reshape(3, 3)
    return np.array([x, y - DEBRIS_FIELD_LANE, math.atan2(turn[1, 0], turn[0, 0])])


def timed_walk(world, module, command: str) -> Leg:
    """:func:`walk_through` with its simulated time."""
    began = world.time
    margin = walk_through(world, module, command)
    return command, margin, world.time - began


def terrain_course(world, module) -> List[Leg]:
    """Station ``terrain``: to the kerb, up the 5-cm step, along, down (TERRAIN_COURSE)."""
    return [timed_walk(world, module, command) for command in TERRAIN_COURSE]


def ramp_course(world, module) -> List[Leg]:
    """Station ``ramp``: to the ramp's foot, onto the 10-degree ramp by two footsteps placed
    on it (pitched like it), up it, onto the level landing at its top by two more; each
    command timed, with its smallest ZMP margin.  The footsteps are placed as a pilot would from
    what perception shows: the ramp's surface under each sole, measured in the world."""
    _, _, _, slope = TERRAIN_RAMP
    return _on_the_ramp(world, module, ("go_straight 0.20", 0.33, -slope, "go_straight 0.36",
                                        0.33, 0.0))


def ramp_down_course(world, module, standing: float = 0.0) -> List[Leg]:
    """Station ``ramp_top``, the way back: from the landing to its edge, onto the ramp by two
    footsteps pitched down like it, down its slope, onto the floor at its foot by two more;
    the robot stands ``standing`` s before each pair is measured (a pilot placing them)."""
    _, _, _, slope = TERRAIN_RAMP
    return _on_the_ramp(world, module, ("go_straight 0.08", 0.33, slope, "go_straight 0.22",
                                        0.30, 0.0), standing)


def ramp_footsteps(source, forward: float, pitch: float) -> str:
    """The ``footsteps`` command of two footsteps ``forward`` m ahead of each sole, on the
    ramp's surface there (the world's), pitched ``pitch``: what a pilot places from what
    perception shows.  ``source``: a backend, or a probe's MuJoCo data."""
    _, foot, length, slope = TERRAIN_RAMP
    top = length * math.sin(slope)

    def surface(x: float) -> float:
        return min(max(x - foot, 0.0) * math.tan(slope), top)

    d = _data(source)
    soles = soles_in_pelvis_frame(d)
    heights = sole_heights(d)
    _, _, _, w, _, _, qz = d.joint("base").qpos
    ahead = math.cos(2.0 * math.atan2(qz, w))       # +1 facing up the ramp, -1 down
    x = float(d.body("l_foot").xpos[0]) + ahead * (walking.SOLE[0] + forward)
    return footsteps(*(walking.sole_ahead(sole, forward, surface(x) - height, pitch)
                       for sole, height in zip(soles, heights)))


def _on_the_ramp(world, module, course, standing: float = 0.0) -> List[Leg]:
    """Walk ``course``: commands, and pairs (forward, pitch) of two footsteps that far ahead
    of each sole, on the ramp's surface there, pitched so, measured after ``standing`` s."""

    def onto(forward: float, pitch: float) -> str:
        world.step(standing)
        return ramp_footsteps(world.backend, forward, pitch)

    done = []
    steps = list(course)
    while steps:
        if isinstance(steps[0], str):
            done.append(timed_walk(world, module, steps.pop(0)))
        else:
            forward, pitch = steps.pop(0), steps.pop(0)
            done.append(("footsteps", *timed_walk(world, module, onto(forward, pitch))[1:]))
    return done


#: walkman-perception's own rendering of the head camera (walkman.head_camera), its points
#: taken into the world by the camera's pose: in a process of its own, since MuJoCo picks
#: its GL once per process (osmesa here, whatever the test process has)
_SEE = r"""
import sys
import numpy as np
from walkman.head_camera import CAMERA, SceneCamera, cloud_points, intrinsics
camera = SceneCamera(320, 240)
rgb, depth = camera.render(np.load(sys.argv[1]))
f, cx, cy = intrinsics(camera.width, camera.height, camera.fovy)
optical = cloud_points(depth, rgb, f, cx, cy, 2)[..., :3].reshape(-1, 3).astype(float)
cam = camera.model.cam(CAMERA).id
turn = camera.data.cam_xmat[cam].reshape(3, 3)
# the optical frame (x right, y down, z ahead) is MuJoCo's camera frame (y up, z back) flipped
np.save(sys.argv[2], camera.data.cam_xpos[cam] + (optical * [1.0, -1.0, -1.0]) @ turn.T)
np.save(sys.argv[3], optical)
"""


def camera_cloud(backend, folder: Path) -> Tuple[np.ndarray, np.ndarray]:
    """What the head camera sees now: its points in the optical frame (as
    ``/multisense/points`` carries them), and in the pelvis frame by MuJoCo's own camera
    pose (the frame of :func:`soles_in_pelvis_frame`; the PI takes it from the kinematics)."""
    qpos, points, optical = folder / "qpos.npy", folder / "cloud.npy", folder / "optical.npy"
    np.save(qpos, backend.plant.d.qpos)
    root = Path(__file__).resolve().parents[2]
    result = subprocess.run([sys.executable, "-c", _SEE, str(qpos), str(points), str(optical)],
                            capture_output=True, text=True, timeout=300, cwd=root,
                            env={**os.environ, "MUJOCO_GL": "osmesa", "PYTHONPATH": str(root)})
    assert result.returncode == 0, result.stderr[-3000:]
    world = np.load(points)
    d = backend.plant.d
    return np.load(optical), (world - d.body("pelvis").xpos) @ d.body("pelvis").xmat.reshape(3, 3)


def cloud_in_pelvis_frame(backend, folder: Path) -> np.ndarray:
    """What the head camera sees now, in the pelvis frame (:func:`camera_cloud`)."""
    return camera_cloud(backend, folder)[1]


#: rad: the head bent all the way down for the courses on the camera's footsteps: from
#: 0.2 m ahead of the toes, the ground before a kerb is in view (at 0.5 rad, from 1 m; then
#: the feet's own ground is not seen, and the footsteps are refused)
LOOKING_DOWN = 1.04


def camera_course(world, module, goal: float, folder: Path,
                  looks: int = 8) -> Tuple[List[Leg], List[List[float]]]:
    """Walk on footsteps the camera places (walkman.control.ground_ahead), a leg at a time
    (each cut where the feet next stand together: at an edge, or the goal): look, place,
    walk, look again, until the soles' centres are within 5 cm of world x ``goal`` ahead.
    Returns each leg (:func:`timed_walk`) and its footsteps' x (pelvis frame, rounded)."""
    backend = world.backend
    backend.set_references([backend.index["NeckPitchj"]], [LOOKING_DOWN])
    world.step(1.0)
    legs: List[Leg] = []
    plans: List[List[float]] = []
    for _ in range(looks):
        soles = dict(zip(("left", "right"), map(tuple, soles_in_pelvis_frame(backend))))
        here = min(float(backend.plant.d.body(f"{side}_foot").xpos[0]) for side in "lr") + \
            walking.SOLE[0]
        if goal - here < 0.05:
            break
        steps = footsteps_from_cloud(cloud_in_pelvis_frame(backend, folder), soles,
                                     goal - here)
        leg = first_leg(steps)
        plans.append([round(step[0], 2) for step in leg])
        legs.append(timed_walk(world, module, footsteps(*leg)))
    return legs, plans
