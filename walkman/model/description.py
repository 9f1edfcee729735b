"""The Walk-Man robot, described once: links, the 33 joints, chains and sensors.

This module is the single source of truth.  :mod:`walkman.model.urdf` turns
it into the URDF that Pinocchio (and ROS) load, :mod:`walkman.model.mjcf`
into the MuJoCo model and the DRC scene; a test checks both loaders agree on
joint names, order and limits.

Joint names, chains, limits and efforts are Walk-Man's (``FACTS.md``); the
geometry is a plausible 1.9 m, ~120 kg humanoid: frames are z-up, x-forward,
every joint at zero gives the robot standing with arms down.  Masses and
inertias come from simple solids (boxes and capsules), which is enough for
the controllers and the simulator, not a CAD model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple

Vec3 = Tuple[float, float, float]

#: Chains in the order the whole-body interface lists joints.
CHAINS = ("torso", "head", "left_arm", "right_arm", "left_leg", "right_leg",
          "left_hand", "right_hand")


@dataclass(frozen=True)
class Geom:
    """A collision/visual solid: ``box`` (half sizes) or ``capsule`` (radius, half length)."""

    kind: str
    size: Tuple[float, ...]
    pos: Vec3 = (0.0, 0.0, 0.0)
    axis: str = "z"  # capsules lie along this axis of the link frame
    rgba: Tuple[float, float, float, float] = (0.6, 0.6, 0.65, 1.0)


@dataclass(frozen=True)
class Link:
    name: str
    mass: float
    geoms: Tuple[Geom, ...]
    com: Vec3 = (0.0, 0.0, 0.0)

    def inertia(self) -> Vec3:
        """Principal moments of a solid box enclosing the geoms (about the com)."""
        lo = [float("inf")] * 3
        hi = [float("-inf")] * 3
        for geom in self.geoms:
            half = _half_extents(geom)
            for axis in range(3):
                lo[axis] = min(lo[axis], geom.pos[axis] - half[axis])
                hi[axis] = max(hi[axis], geom.pos[axis] + half[axis])
        x, y, z = (max(hi[i] - lo[i], 0.02) for i in range(3))
        m = self.mass
        return (m * (y * y + z * z) / 12, m * (x * x + z * z) / 12, m * (x * x + y * y) / 12)


def _half_extents(geom: Geom) -> Vec3:
    if geom.kind == "box":
        return geom.size  # type: ignore[return-value]
    radius, half_length = geom.size
    extents = [radius, radius, radius]
    extents["xyz".index(geom.axis)] = radius + half_length
    return tuple(extents)  # type: ignore[return-value]


#: N*m*s/rad: servo damping of the joints that carry the robot (the legs).
SUPPORT_DAMPING = 400.0


@dataclass(frozen=True)
class Joint:
    name: str
    chain: str
    parent: str
    child: str
    origin: Vec3
    axis: Vec3
    lower: float
    upper: float
    effort: float
    velocity: float = 3.0
    #: Series-elastic stiffness (N*m/rad) of the actuator; hands are stiff.
    stiffness: float = 3000.0
    #: Servo damping (N*m*s/rad).  The legs carry the whole robot: at 60 their
    #: springs and the body's mass sway at ~1 Hz with 8 % damping, which a walking
    #: controller cannot outrun; at :data:`SUPPORT_DAMPING` the sway is well damped.
    damping: float = 60.0


@dataclass(frozen=True)
class Sensor:
    """A frame the simulator and the HAL know: F/T, IMU or camera."""

    name: str
    kind: str  # "ft", "imu", "camera"
    link: str
    pos: Vec3 = (0.0, 0.0, 0.0)


@dataclass
class Robot:
    name: str
    base: str
    links: Dict[str, Link] = field(default_factory=dict)
    joints: List[Joint] = field(default_factory=list)
    sensors: List[Sensor] = field(default_factory=list)

    @property
    def joint_names(self) -> List[str]:
        """The whole-body joint order: chains in :data:`CHAINS` order."""
        return [joint.name for chain in CHAINS for joint in self.joints if joint.chain == chain]

    def joint(self, name: str) -> Joint:
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise KeyError(name)

    def chain(self, chain: str) -> List[Joint]:
        return [joint for joint in self.joints if joint.chain == chain]

    def children(self, link: str) -> List[Joint]:
        return [joint for joint in self.joints if joint.parent == link]

    @property
    def total_mass(self) -> float:
        return sum(link.mass for link in self.links.values())


X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
DARK = (0.25, 0.25, 0.3, 1.0)
ORANGE = (0.95, 0.5, 0.1, 1.0)


def _capsule(radius: float, length: float, axis: str = "z", center: Optional[Vec3] = None,
             rgba=(0.6, 0.6, 0.65, 1.0)) -> Geom:
    if center is None:
        center = {"x": (length / 2, 0, 0), "y": (0, length / 2, 0),
                  "z": (0, 0, -length / 2)}[axis]
    return Geom("capsule", (radius, length / 2), center, axis, rgba)


def _box(hx: float, hy: float, hz: float, pos: Vec3 = (0, 0, 0), rgba=(0.6, 0.6, 0.65, 1.0)) -> Geom:
    return Geom("box", (hx, hy, hz), pos, "z", rgba)


def walkman() -> Robot:
    """Walk-Man: 31 body joints + 2 hands, joint table from FACTS.md."""
    robot = Robot(name="walkman", base="pelvis")
    link, joint = _link(robot), _joint(robot)
    link("pelvis", 14.0, _box(0.12, 0.17, 0.08, (0, 0, -0.02), DARK), com=(0, 0, -0.02))

    # -- torso: WaistLat (roll), WaistSag (pitch), WaistYaw ------------------------------
    link("waist_lat", 1.0, _box(0.04, 0.04, 0.03))
    link("waist_sag", 1.5, _box(0.05, 0.05, 0.04, (0, 0, 0.04)))
    link("torso", 28.0, _box(0.13, 0.2, 0.22, (0, 0, 0.24), ORANGE),
         _box(0.09, 0.12, 0.06, (-0.15, 0, 0.26), DARK), com=(0, 0, 0.24))
    joint("WaistLat", "torso", "pelvis", "waist_lat", (0, 0, 0.1), X, -0.6109, 0.6109, 120.0)
    joint("WaistSag", "torso", "waist_lat", "waist_sag", (0, 0, 0.0), Y, -0.3491, 1.3963, 220.0)
    joint("WaistYaw", "torso", "waist_sag", "torso", (0, 0, 0.08), Z, -2.8449, 2.8449, 120.0)

    # -- head: NeckYawj, NeckPitchj; the camera looks along +x ---------------------------
    link("neck", 0.8, _capsule(0.04, 0.08, "z", (0, 0, 0.04)))
    link("head", 4.5, _box(0.09, 0.12, 0.09, (0.02, 0, 0.07), DARK), com=(0.02, 0, 0.07))
    joint("NeckYawj", "head", "torso", "neck", (0, 0, 0.48), Z, -0.6109, 0.6109, 60.0)
    joint("NeckPitchj", "head", "neck", "head", (0, 0, 0.08), Y, -0.2618, 1.0472, 60.0)
    robot.sensors.append(Sensor("multisense", "camera", "head", (0.12, 0.0, 0.08)))

    for side, sign in (("l", 1.0), ("r", -1.0)):
        _arm(robot, side, sign)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        _leg(robot, side, sign)
    robot.sensors.append(Sensor("imu", "imu", "pelvis", (0, 0, 0)))
    return robot


def _arm(robot: Robot, side: str, sign: float) -> None:
    """An arm: ShSag, ShLat, ShYaw, Elbj, ForearmPlate, Wrj1, Wrj2, and its hand."""
    link, joint = _link(robot), _joint(robot)
    prefix = side.upper()
    chain = "left_arm" if side == "l" else "right_arm"
    lat_limits = (0.0873, 3.8572) if side == "l" else (-3.8572, -0.1222)
    names = [link(f"{side}_shoulder_sag", 1.2, _box(0.05, 0.05, 0.05)),
             link(f"{side}_shoulder_lat", 1.2, _box(0.04, 0.04, 0.05)),
             link(f"{side}_upper_arm", 3.0, _capsule(0.05, 0.24), com=(0, 0, -0.12)),
             link(f"{side}_elbow", 1.0, _capsule(0.045, 0.08), com=(0, 0, -0.04)),
             link(f"{side}_forearm", 2.0, _capsule(0.04, 0.2), com=(0, 0, -0.1)),
             link(f"{side}_wrist", 0.4, _box(0.03, 0.03, 0.02)),
             link(f"{side}_hand", 1.2, _box(0.03, 0.05, 0.06, (0, 0, -0.07), DARK),
                  com=(0, 0, -0.07)),
             link(f"{side}_fingers", 0.3, _box(0.02, 0.045, 0.035, (0.0, 0, -0.035)))]
    joint(f"{prefix}ShSag", chain, "torso", names[0], (0, sign * 0.25, 0.40), Y,
          -2.8798, 2.7925, 120.0)
    joint(f"{prefix}ShLat", chain, names[0], names[1], (0, sign * 0.03, 0), X,
          *lat_limits, 120.0)
    joint(f"{prefix}ShYaw", chain, names[1], names[2], (0, 0, -0.06), Z,
          -2.8449, 2.8449, 120.0)
    joint(f"{prefix}Elbj", chain, names[2], names[3], (0, 0, -0.24), Y,
          -2.9671, 0.5934, 60.0)
    joint(f"{prefix}ForearmPlate", chain, names[3], names[4], (0, 0, -0.08), Z,
          -2.529, 2.529, 60.0)
    joint(f"{prefix}Wrj1", chain, names[4], names[5], (0, 0, -0.2), Y, -1.48, 1.48, 60.0)
    joint(f"{prefix}Wrj2", chain, names[5], names[6], (0, 0, -0.02), X, -1.48, 1.48, 60.0)
    joint(f"{side}_handj", "left_hand" if side == "l" else "right_hand", names[6], names[7],
          (0.03, 0, -0.08), Y, 0.0, 1.5, 20.0, stiffness=100000.0)
    robot.sensors.append(Sensor(f"{side}_arm_ft", "ft", names[6], (0, 0, -0.01)))


def _leg(robot: Robot, side: str, sign: float) -> None:
    """A leg: HipLat, HipYaw, HipSag, KneeSag, AnkSag, AnkLat, damped for support."""
    link, joint = _link(robot), _joint(robot)
    support = {"damping": SUPPORT_DAMPING}
    prefix = side.upper()
    chain = "left_leg" if side == "l" else "right_leg"
    hip_lat = (-0.6978, 0.8722) if side == "l" else (-0.8722, 0.6978)
    hip_yaw = (-0.8722, 1.57) if side == "l" else (-1.57, 0.8722)
    names = [link(f"{side}_hip_lat", 2.0, _box(0.05, 0.05, 0.04)),
             link(f"{side}_hip_yaw", 2.0, _box(0.05, 0.05, 0.04)),
             link(f"{side}_thigh", 8.0, _capsule(0.07, 0.42), com=(0, 0, -0.21)),
             link(f"{side}_shank", 5.0, _capsule(0.06, 0.42), com=(0, 0, -0.21)),
             link(f"{side}_ankle", 1.0, _box(0.04, 0.04, 0.03)),
             link(f"{side}_foot", 2.0, _box(0.13, 0.07, 0.025, (0.03, 0, -0.075), DARK),
                  com=(0.03, 0, -0.075))]
    joint(f"{prefix}HipLat", chain, "pelvis", names[0], (0, sign * 0.11, -0.08), X,
          *hip_lat, 220.0, **support)
    joint(f"{prefix}HipYaw", chain, names[0], names[1], (0, 0, -0.05), Z, *hip_yaw, 120.0, **support)
    joint(f"{prefix}HipSag", chain, names[1], names[2], (0, 0, -0.05), Y,
          -2.0933, 1.0467, 220.0, **support)
    joint(f"{prefix}KneeSag", chain, names[2], names[3], (0, 0, -0.42), Y, 0.0, 2.4422, 220.0,
          **support)
    joint(f"{prefix}AnkSag", chain, names[3], names[4], (0, 0, -0.42), Y,
          -1.3956, 0.6978, 220.0, **support)
    joint(f"{prefix}AnkLat", chain, names[4], names[5], (0, 0, 0.0), X, -0.785, 0.785, 120.0,
          **support)
    robot.sensors.append(Sensor(f"{side}_leg_ft", "ft", names[5], (0, 0, -0.05)))


def _link(robot: Robot) -> Callable[..., str]:
    """``link(name, mass, *geoms, com=...)``: add a link to ``robot``; its name."""
    def link(name: str, mass: float, *geoms: Geom, com: Vec3 = (0, 0, 0)) -> str:
        robot.links[name] = Link(name, mass, geoms, com)
        return name
    return link


def _joint(robot: Robot) -> Callable[..., None]:
    """``joint(name, chain, parent, child, origin, axis, lower, upper, effort, **extra)``."""
    def joint(name: str, chain: str, parent: str, child: str, origin: Vec3, axis: Vec3,
              lower: float, upper: float, effort: float, **extra) -> None:
        robot.joints.append(Joint(name, chain, parent, child, origin, axis, lower, upper,
                                  effort, **extra))
    return joint


#: Height of the pelvis frame above the floor when standing with all joints at zero.
STANDING_PELVIS_HEIGHT = 0.08 + 0.05 + 0.05 + 0.42 + 0.42 + 0.1


def home_posture(robot: Robot) -> Dict[str, float]:
    """A safe standing posture inside every limit: arms slightly out and bent."""
    posture = {name: 0.0 for name in robot.joint_names}
    posture.update({"LShLat": 0.25, "RShLat": -0.25, "LElbj": -0.5, "RElbj": -0.5,
                    "LShSag": 0.2, "RShSag": 0.2, "LHipSag": -0.15, "RHipSag": -0.15,
                    "LKneeSag": 0.3, "RKneeSag": 0.3, "LAnkSag": -0.15, "RAnkSag": -0.15})
    return posture
