"""The ``sim`` backend: Walk-Man in MuJoCo, 1 kHz physics, compliant position control.

Each joint is a position servo whose stiffness is the joint's series-elastic
spring (a few thousand N*m/rad) with damping, saturated at the joint's
effort: modules command positions, the robot is compliant under contact, as
the real series-elastic actuators are.  Idle joints get zero torque.

Grasping is modelled, not simulated finger by finger: when a hand closes
(``l_handj`` above 0.8 rad) with its grip point within 8 cm of a graspable
part (valve rim, steering wheel, door handle), a weld between hand and part
is switched on at their current relative pose; opening the hand (below 0.4
rad) releases it.  The door's latch (a joint equality holding the door shut)
lets go while the handle is turned down past ``LATCH_RELEASE`` and catches
again when the door is back in its frame.  The drill runs while a hand that
holds it squeezes its trigger (closes past ``DRILL_TRIGGER``); its bit's path
through the drywall is judged by :class:`walkman.hal.drywall.Drywall`.

The pelvis hangs from the scene's support harness (``walkman/model/mjcf.py``)
in one of three modes: ``locked`` (trolley braked: the robot hangs still, the
default), ``trolley`` (brake off: the harness keeps the pelvis level and
carries part of the weight, the feet must walk to move the robot) or ``off``.
:meth:`MujocoPlant.place` puts the robot at a station.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import mujoco
import numpy as np

from walkman.hal.backend import Backend, Imu, quat_to_rpy
from walkman.hal.drywall import Drywall
from walkman.hal.thermal import ThermalModel
from walkman.model import MJCF_PATH, SCENE_PATH
from walkman.model.description import Robot, walkman
from walkman.model.mjcf import (CAR_SEAT_TOP, GRASPABLE, HANDS, STATION_GROUND, STATION_POSTURE,
                                STATIONS, WALL_CIRCLE_RADIUS)

GRASP_CLOSED = 0.8
GRASP_OPEN = 0.4
GRASP_DISTANCE = 0.08  # m: the soft hand closes on a part with large position errors
LATCH_RELEASE = -0.5   # rad of the door handle (down) that frees the latch
DRILL_TRIGGER = 1.38   # rad: a hand holding the drill closed past this squeezes its trigger
PUSH_BODY = "torso"    # where a simulated push lands (a hand on the robot's chest)
PUSH_TIME = 0.1        # s a push lasts
MAX_PUSH = 500.0       # N*s: the largest impulse the simulator accepts
MAX_PUSH_FORCE = 5000.0  # N: and the largest force (a short push is a hard one)
HARNESS_MODES = ("locked", "trolley", "off")
#: How soles hold on the ground.  ``soft``: MuJoCo's defaults (pyramidal friction cones,
#: friction as soft as the normal contact), what the world runs on.  A loaded sole then
#: creeps where a real one would hold: 5 mm/s down the 10-degree ramp, standing (the walk
#: frame's plan drifts from the world, the landing at the ramp's top comes 2 cm high).
#: ``firm``: elliptic cones with friction ``impratio`` times stiffer than the normal
#: contact (MuJoCo's own advice against slip): 0.9 mm/s there, the sole's normal
#: compliance unchanged.  ``grip``: soft's cones with MuJoCo's no-slip solver after the
#: main one (5 iterations), which removes the creep the soft friction allows: 0.0002
#: mm/s -- a sole holds, and with it any disagreement between the plan's footholds and the
#: ground (position-controlled legs then press one foot and unload the other: stepping
#: down the ramp onto the floor, the robot rolled over its outer edge; a foot force
#: difference loop, tried, was too slow for it).  Walking is tuned on ``soft``;
#: ``bench/bench_walking.py --contact`` compares the courses on each.
CONTACT_MODELS: Dict[str, Tuple[int, float, int]] = {
    "soft": (int(mujoco.mjtCone.mjCONE_PYRAMIDAL), 1.0, 0),
    "firm": (int(mujoco.mjtCone.mjCONE_ELLIPTIC), 3.0, 0),
    "grip": (int(mujoco.mjtCone.mjCONE_PYRAMIDAL), 1.0, 5),
}


def check_contact(contact: str) -> None:
    """Refuse a contact model that is not one of :data:`CONTACT_MODELS`."""
    if contact not in CONTACT_MODELS:
        raise ValueError(f"unknown contact model {contact!r}: one of "
                         f"{', '.join(CONTACT_MODELS)}")


def use_contact(model: mujoco.MjModel, contact: str) -> None:
    """Set ``model``'s friction cones, impedance ratio and no-slip iterations to the contact
    model ``contact``."""
    check_contact(contact)
    model.opt.cone, model.opt.impratio, model.opt.noslip_iterations = CONTACT_MODELS[contact]


class MujocoPlant:
    """The MuJoCo model and data, with whole-body index maps (shared by both backends)."""

    def __init__(self, model: Robot, scene: bool = True, harness: str = "locked",
                 path: Optional[Path] = None, station: str = "valve",
                 contact: str = "soft") -> None:
        check_contact(contact)
        self.robot = model
        self.m = mujoco.MjModel.from_xml_path(str(path or (SCENE_PATH if scene else MJCF_PATH)))
        use_contact(self.m, contact)
        self.d = mujoco.MjData(self.m)
        mujoco.mj_resetDataKeyframe(self.m, self.d, 0)
        names = model.joint_names
        self.qpos_adr = np.array([self.m.joint(n).qposadr[0] for n in names])
        self.dof_adr = np.array([self.m.joint(n).dofadr[0] for n in names])
        self.actuator = np.array([self.m.actuator(n).id for n in names])
        self.stiffness = np.array([model.joint(n).stiffness for n in names])
        self.damping = np.array([model.joint(n).damping for n in names])
        self.position_range = self.m.actuator_ctrlrange[self.actuator].copy()
        self.effort = np.array([model.joint(n).effort for n in names])
        self.harness_id = self.m.equality("harness").id
        self.brake_id = self.m.equality("harness_brake").id
        self.trolley = [self.m.joint(f"harness_{axis}").qposadr[0] for axis in "xyz"] + \
            [self.m.joint("harness_yaw").qposadr[0]]
        self.base = self.m.joint("base").qposadr[0]
        try:
            self.latch_id: Optional[int] = self.m.equality("door_latch").id
            self.door, self.door_handle = (self.m.joint(n).qposadr[0]
                                           for n in ("door", "door_handle"))
        except KeyError:
            self.latch_id = None
        self.sensor_adr: Dict[str, Tuple[int, int]] = {}
        for index in range(self.m.nsensor):
            sensor = self.m.sensor(index)
            self.sensor_adr[sensor.name] = (sensor.adr[0], sensor.dim[0])
        self.grasps: Dict[str, int] = {}
        self.grasp_sites: Dict[str, Tuple[int, int]] = {}
        for hand in HANDS:
            for part, body, site in GRASPABLE:
                try:
                    eq_id = self.m.equality(f"grasp_{hand}_{part}").id
                except KeyError:
                    continue
                self.grasps[f"{hand}_{part}"] = eq_id
                self.grasp_sites[f"{hand}_{part}"] = (self.m.site(f"{hand}_hand_grip").id,
                                                      self.m.site(site).id)
        self.drill_running = False
        try:
            self.drill_tip: Optional[int] = self.m.site("drill_tip").id
        except KeyError:
            self.drill_tip = None
        else:
            mujoco.mj_forward(self.m, self.d)
            wall = self.m.body("drywall").id
            self.drywall = Drywall(self.d.site_xpos[self.m.site("wall_circle").id].copy(),
                                   -self.d.xmat[wall].reshape(3, 3)[:, 0], WALL_CIRCLE_RADIUS)
        self.place(station)
        self.set_harness(harness)

    def station_posture(self, station: str) -> np.ndarray:
        """The joint angles (rad, the robot's joint order) the robot is in at ``station``:
        the home posture, or seated in the car (:data:`STATION_POSTURE`)."""
        posture = self.m.key_qpos[0][self.qpos_adr].copy()
        for joint, angle in STATION_POSTURE.get(station, {}).items():
            posture[self.robot.joint_names.index(joint)] = angle
        return posture

    def place(self, station: str) -> None:
        """Put the robot (pelvis, joints and trolley) at a station of the scene, still, in
        the station's posture: standing on its ground, or seated, its thighs on the car's
        seat."""
        if station not in STATIONS:
            raise ValueError(f"unknown station {station!r}: choose {', '.join(STATIONS)}")
        x, y, yaw = STATIONS[station]
        ground = STATION_GROUND.get(station, 0.0)
        qpos = self.d.qpos
        qpos[self.trolley] = (x, y, ground, yaw)
        qpos[self.qpos_adr] = self.station_posture(station)
        height = self.m.key_qpos[0][self.base + 2] + ground    # the standing keyframe's
        qpos[self.base:self.base + 7] = (x, y, height, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
        self.d.qvel[:] = 0.0
        mujoco.mj_forward(self.m, self.d)
        if station in STATION_POSTURE:       # seated: the thighs on the seat
            qpos[self.base + 2] += CAR_SEAT_TOP - self.lowest_point(("l_thigh", "r_thigh"))
            mujoco.mj_forward(self.m, self.d)
        self._weld_here(self.harness_id)
        self._weld_here(self.brake_id)

    def lowest_point(self, bodies: Sequence[str] = ("l_foot", "r_foot")) -> float:
        """The height (m) of the lowest point of the bodies' geoms (their bounding boxes):
        by default, the lower sole."""
        lowest = math.inf
        for name in bodies:
            body = self.m.body(name).id
            for geom in range(self.m.body_geomadr[body],
                              self.m.body_geomadr[body] + self.m.body_geomnum[body]):
                rotation = self.d.geom_xmat[geom].reshape(3, 3)
                centre, half = self.m.geom_aabb[geom][:3], self.m.geom_aabb[geom][3:]
                bottom = self.d.geom_xpos[geom][2] + rotation[2] @ centre - \
                    np.abs(rotation[2]) @ half
                lowest = min(lowest, float(bottom))
        return lowest

    def set_harness(self, mode: str) -> None:
        """``locked`` (hang still), ``trolley`` (brake off: walk) or ``off``."""
        if mode not in HARNESS_MODES:
            raise ValueError(f"harness mode must be one of {', '.join(HARNESS_MODES)}, "
                             f"got {mode!r}")
        if mode == "locked":  # brake where the trolley is now
            mujoco.mj_forward(self.m, self.d)
            self._weld_here(self.brake_id)
        self.d.eq_active[self.harness_id] = 0 if mode == "off" else 1
        self.d.eq_active[self.brake_id] = 1 if mode == "locked" else 0
        self.harness_mode = mode

    def base_pose(self) -> Tuple[float, float, float, float]:
        """x, y, z and yaw of the pelvis in the world (ground truth, for tests and benches)."""
        x, y, z, w, _, _, qz = (float(v) for v in self.d.qpos[self.base:self.base + 7])
        return x, y, z, 2.0 * np.arctan2(qz, w)

    def update_latch(self) -> List[str]:
        """The latch frees the door while the handle is down, catches it when shut."""
        if self.latch_id is None:
            return []
        latched = bool(self.d.eq_active[self.latch_id])
        handle, door = self.d.qpos[self.door_handle], self.d.qpos[self.door]
        if latched and handle < LATCH_RELEASE:
            self.d.eq_active[self.latch_id] = 0
            return ["door unlatched"]
        if not latched and handle > LATCH_RELEASE / 2 and abs(door) < 0.01:
            self.d.eq_active[self.latch_id] = 1
            return ["door latched"]
        return []

    def sensor(self, name: str) -> np.ndarray:
        adr, dim = self.sensor_adr[name]
        return self.d.sensordata[adr:adr + dim]

    def set_servo(self, indices: np.ndarray, torque_mode: np.ndarray, idle: np.ndarray) -> None:
        """Configure actuators: compliant position servo, raw torque, or off."""
        for index in indices:
            actuator = self.actuator[index]
            gain = self.m.actuator_gainprm[actuator]
            bias = self.m.actuator_biasprm[actuator]
            if idle[index]:
                gain[0], bias[1], bias[2] = 0.0, 0.0, 0.0
            elif torque_mode[index]:
                gain[0], bias[1], bias[2] = 1.0, 0.0, 0.0
            else:
                gain[0], bias[1], bias[2] = (self.stiffness[index], -self.stiffness[index],
                                                -self.damping[index])
            # ctrl is a position (clamped to the joint range) or a torque (to the effort).
            self.m.actuator_ctrlrange[actuator] = (
                (-self.effort[index], self.effort[index]) if torque_mode[index]
                else self.position_range[index])

    def update_grasps(self, hand_positions: Dict[str, float]) -> List[str]:
        """Switch grasp welds on/off from hand closure and distance; return events."""
        events = []
        for key, eq_id in self.grasps.items():
            hand = key.split("_", 1)[0]
            closure = hand_positions[hand]
            active = bool(self.d.eq_active[eq_id])
            if not active and closure > GRASP_CLOSED:
                hand_site, part_site = self.grasp_sites[key]
                gap = np.linalg.norm(self.d.site_xpos[hand_site] - self.d.site_xpos[part_site])
                if gap < GRASP_DISTANCE:
                    self._weld_here(eq_id)
                    self.d.eq_active[eq_id] = 1
                    events.append(f"grasped {key}")
            elif active and closure < GRASP_OPEN:
                self.d.eq_active[eq_id] = 0
                events.append(f"released {key}")
        return events

    def update_drill(self, hand_positions: Dict[str, float]) -> List[str]:
        """The drill runs while a hand holding it squeezes the trigger; feed the drywall."""
        if self.drill_tip is None:
            return []
        running = any(self.d.eq_active[self.grasps[f"{hand}_drill"]] and
                      hand_positions[hand] > DRILL_TRIGGER for hand in HANDS)
        events = []
        if running != self.drill_running:
            self.drill_running = running
            events.append("drill on" if running else "drill off")
        return events + self.drywall.feed(self.d.site_xpos[self.drill_tip], running)

    def _weld_here(self, eq_id: int) -> None:
        """Make the weld hold the two bodies where they are now."""
        body1, body2 = self.m.eq_obj1id[eq_id], self.m.eq_obj2id[eq_id]
        p1, p2 = self.d.xpos[body1], self.d.xpos[body2]
        q1, q2 = self.d.xquat[body1], self.d.xquat[body2]
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, q1)
        relpos = rotation.reshape(3, 3).T @ (p2 - p1)
        inverse, relquat = np.zeros(4), np.zeros(4)
        mujoco.mju_negQuat(inverse, q1)
        mujoco.mju_mulQuat(relquat, inverse, q2)
        self.m.eq_data[eq_id][0:3] = 0.0
        self.m.eq_data[eq_id][3:6] = relpos
        self.m.eq_data[eq_id][6:10] = relquat
        self.m.eq_data[eq_id][10] = 1.0

    def grasped(self) -> List[str]:
        return [key for key, eq_id in self.grasps.items() if self.d.eq_active[eq_id]]

    def prop_position(self, joint: str) -> float:
        return float(self.d.qpos[self.m.joint(joint).qposadr[0]])


class PlantBackend(Backend):
    """A backend over a :class:`MujocoPlant` (the simulation, the emulated EtherCAT bus):
    its servo references start, and start again at each station, in the station's posture
    -- the robot seated in the car would otherwise stand up into the seat."""

    plant: MujocoPlant

    def _use_plant(self, plant: MujocoPlant, station: str) -> None:
        self.plant = plant
        self.dt = float(plant.m.opt.timestep)
        self.reference[:] = plant.station_posture(station)

    def place(self, station: str) -> None:
        """Set the robot down at ``station`` (:meth:`MujocoPlant.place`), the references
        its posture there."""
        self.plant.place(station)
        self.reference[:] = self.plant.station_posture(station)


class SimBackend(PlantBackend):
    """MuJoCo at 1 kHz with compliant position servos."""

    def __init__(self, model: Optional[Robot] = None, scene: bool = True, harness: str = "locked",
                 thermal_speedup: float = 1.0, station: str = "valve",
                 contact: str = "soft") -> None:
        super().__init__(model or walkman())
        self._use_plant(MujocoPlant(self.model, scene=scene, harness=harness, station=station,
                                    contact=contact), station)
        self.thermal = ThermalModel(len(self.joint_names), speedup=thermal_speedup)
        self._torque_mode = np.zeros(len(self.joint_names), dtype=bool)
        self._hands = (self.index["l_handj"], self.index["r_handj"])
        self.events: List[str] = []
        self._steps = 0
        self._push_body = self.plant.m.body(PUSH_BODY).id
        self._push_force = np.zeros(3)
        self._push_until = 0.0

    def push(self, impulse: Tuple[float, float, float], duration: float = PUSH_TIME) -> None:
        """Push the torso with ``impulse`` (N*s, world frame) spread over ``duration`` s: what
        a pilot tries a balance controller with (the walking module's push tests)."""
        impulse = np.asarray(impulse, dtype=float)
        if impulse.shape != (3,) or not np.all(np.isfinite(impulse)):
            raise ValueError(f"a push is three finite numbers (N*s), got {impulse.tolist()}")
        if np.linalg.norm(impulse) > MAX_PUSH:
            raise ValueError(f"a push of {np.linalg.norm(impulse):.0f} N*s is more than "
                             f"{MAX_PUSH:.0f} N*s")
        if not 0.001 <= duration <= 1.0:
            raise ValueError(f"a push lasts 0.001..1 s, got {duration}")
        if np.linalg.norm(impulse) / duration > MAX_PUSH_FORCE:
            raise ValueError(f"a push of {np.linalg.norm(impulse):.0f} N*s over {duration} s "
                             f"is more than {MAX_PUSH_FORCE:.0f} N: make it last longer")
        self._push_force = impulse / duration
        self._push_until = self.time + duration

    def _apply_modes(self, indices: np.ndarray) -> None:
        self.plant.set_servo(indices, self._torque_mode, self.idle)

    def step(self) -> None:
        plant = self.plant
        plant.d.ctrl[plant.actuator] = np.where(self.idle, 0.0, self.reference)
        pushing = self.time < self._push_until
        plant.d.xfrc_applied[self._push_body, :3] = self._push_force if pushing else 0.0
        mujoco.mj_step(plant.m, plant.d)
        self.time += self.dt
        self.thermal.step(self.torques(), self.dt)
        self._steps += 1
        if self._steps % 10 == 0 and plant.grasps:
            q = self.positions()
            hands = {"l": q[self._hands[0]], "r": q[self._hands[1]]}
            self.events += plant.update_grasps(hands)
            self.events += plant.update_latch()
            self.events += plant.update_drill(hands)

    def positions(self) -> np.ndarray:
        return self.plant.d.qpos[self.plant.qpos_adr].copy()

    def velocities(self) -> np.ndarray:
        return self.plant.d.qvel[self.plant.dof_adr].copy()

    def torques(self) -> np.ndarray:
        return self.plant.d.actuator_force[self.plant.actuator].copy()

    def temperatures(self) -> np.ndarray:
        return self.thermal.temperature.copy()

    def ft(self, sensor: str) -> np.ndarray:
        return np.concatenate([self.plant.sensor(f"{sensor}_force"),
                               self.plant.sensor(f"{sensor}_torque")])

    def imu(self) -> Imu:
        quat = self.plant.sensor("imu_orientation")
        return Imu(quat_to_rpy(*quat), tuple(self.plant.sensor("imu_accelerometer")),
                   tuple(self.plant.sensor("imu_gyro")))

    def status(self) -> Dict[str, object]:
        status = {"backend": "sim", "time": round(self.time, 3),
                  "grasped": self.plant.grasped(), "harness": self.plant.harness_mode}
        if self.plant.drill_tip is not None and (self.plant.drill_running or
                                                 self.plant.drywall.cut_points):
            status["drill"] = "on" if self.plant.drill_running else "off"
            status["drywall"] = self.plant.drywall.summary()
        return status
