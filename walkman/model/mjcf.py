"""Walk-Man in MuJoCo: the robot, its sensors, and the DRC scene.

Generated from :mod:`walkman.model.description`, like the URDF, so the two
never disagree.  Bodies are written children-sorted-by-name, the order
Pinocchio reads the URDF in, so joint indices match between the two.

Actuators are ``general`` actuators whose gains the HAL sets at run time:
a compliant position servo (stiffness = the series-elastic spring) for the
``sim`` backend, plain torque for the ``ethercat`` backend whose firmware
boards close their own PID loops.

The scene (``drc=True``) adds what the DRC modules act on, all articulated:

* a valve (hand wheel, radius 0.15 m) on a wall in front of the robot;
* a car (to the robot's right): a seat with a low backrest, a steering wheel
  before the chest and a throttle pedal in front of the right foot -- the robot
  drives seated, as Walk-Man did at the DRC (the station seats it:
  :data:`STATION_POSTURE`);
* a door with a lever handle and a latch (to the robot's left): it opens
  away from the robot only while the handle is turned down;
* the surprise task's table (station ``plug``): two open sockets side by side
  and a plug with a handle standing in the left one, free to be lifted out;
* a **support harness**: the pelvis is welded (``harness``) to a trolley
  (``harness_trolley``) that rides on x/y rails and turns about z, its height
  on a spring that carries part of the weight.  The trolley's brake
  (``harness_brake``, a weld to the world) is on by default: the robot hangs
  still while it manipulates.  With the brake off the robot's feet carry the
  rest of its weight and must walk to move it (see ``walkman/hal/sim.py``);
* grasp welds between each hand and each graspable part, off until the HAL
  closes a hand next to the part (see ``walkman/hal/sim.py``).

* the rough-ground course (station ``terrain``): a 5-cm step across the way,
  a 10-degree ramp up to a level landing in the lane to the right (station
  ``ramp`` stands before it), debris blocks in the lane to the left;
* the debris field (station ``debris_field``): light boards, free bodies, lying
  scattered on the floor in a lane of their own, asleep until a foot touches one.

Stations (:data:`STATIONS`) are where the robot starts: in front of the
valve, seated in the car, before the door, at the plug's table and the
drywall, before the rough ground.
"""

from __future__ import annotations

import math
from typing import List, Sequence

from walkman.model.description import (STANDING_PELVIS_HEIGHT, Geom, Robot, home_posture,
                                       walkman)

#: Parts a hand can grasp: (name, body, site) -- the site is where the hand must be.
GRASPABLE = (("valve", "valve_wheel", "valve_grip"),
             ("steering_wheel", "steering_wheel", "steering_grip"),
             ("door_handle", "door_handle", "door_handle_grip"),
             ("plug", "plug", "plug_grip"),
             ("drill", "drill", "drill_grip"))
HANDS = ("l", "r")
#: The plug station's two sockets (world x, y of each centre; their floor is the table top).
PLUG_SOCKETS = {"a": (0.62, -4.70), "b": (0.62, -4.88)}
PLUG_TABLE_TOP = 0.98
#: The wall station (``drc_wall``): the drill standing on its table (world position of its
#: grip, the middle of its handle; the bit points along world x), the drywall's face (world
#: x) and the circle marked on it (world centre, radius): the pilot cuts it out.
DRILL_GRIP = (0.50, -7.10, 1.06)
DRILL_TABLE_TOP = 0.98
WALL_FACE_X = 0.85
WALL_THICKNESS = 0.015
WALL_CIRCLE_CENTRE = (WALL_FACE_X, -7.28, 1.24)
WALL_CIRCLE_RADIUS = 0.08
#: The command a pilot sends at a station to tell its task module where the part is (its
#: pose in the pelvis frame, as perception would measure it): one copy of the scene's numbers
#: for tests, benchmarks and the PI's task widgets (every number the command takes: a widget
#: shows a field for each, and an optional one left at 0 put the car's pedal at the pelvis).
PILOT_POSES = {"valve": "valvedatasent 0.66 0.25 0.08 0 0 0 0.15",
               "car": "steeringwheeldatasent 0.55 0.1 0.08 0 -1.0472 0 0.18 0.69 -0.11 -0.63",
               "door": "doordatasent 0.50 0.01 0.03 0 0 0 0.09 0.6",
               "plug": "plugdatasent 0.62 0.30 0.0 0 0 0 0 -0.18",
               "wall": "walldatasent 0.50 0.40 -0.06 0 0 0 0.85 0.22 0.12 0.08"}
#: The rough-ground course (station ``terrain``, issue 32): a platform a 5-cm step up from
#: the floor across the robot's way (world x where it begins and ends, its height), a 10-degree
#: ramp in the lane to the robot's right (world y of that lane, x where it leaves the floor,
#: its length up, its slope; station ``ramp`` stands before it) and debris blocks in the lane to its left (world x, y, yaw and
#: half sizes of each).
TERRAIN_STEP = (-5.68, -4.88, 0.05)
TERRAIN_RAMP = (-1.2, -5.6, 0.6, 0.1745)
#: The walking commands that take the robot from station ``terrain`` over the step: to the
#: kerb (toes 4 cm from it), up, along to the far edge, down (bench/bench_walking.py).
TERRAIN_COURSE = ("go_straight 0.12", "step_up 0.05", "go_straight 0.48", "step_down 0.05")
TERRAIN_DEBRIS = ((-5.55, 1.15, 0.3, 0.05, 0.03, 0.02), (-5.30, 1.30, -0.6, 0.08, 0.02, 0.015),
                  (-5.05, 1.05, 1.1, 0.04, 0.04, 0.03), (-4.80, 1.25, 0.2, 0.10, 0.015, 0.01))
#: The debris field (issue 66): light boards scattered on the floor in a lane of their own
#: (world y), as the DRC's debris course had them -- laths 4 cm wide, 2 cm thick and 60 cm
#: long (pine, 0.25 kg), free to be kicked aside; three lie across the way, nearly square to
#: it, two beside it.  Each: world x, y offset from the lane, yaw (0: square across the
#: way), half sizes along the board (its length), across it, and up.
DEBRIS_FIELD_LANE = 2.4
DEBRIS_BOARDS = ((-5.50, 0.00, 0.03), (-4.85, 0.03, -0.02), (-4.20, -0.02, 0.04),
                 (-5.20, 0.42, 1.45), (-4.50, -0.45, 1.62))
DEBRIS_BOARD_HALF = (0.30, 0.02, 0.01)
DEBRIS_BOARD_DENSITY = 520.0     # kg/m3: pine
#: Where the robot can start: station -> (x, y, yaw) of the pelvis in the world, standing on
#: the floor -- or on ground as high as :data:`STATION_GROUND` says (``ramp_top``: on the
#: ramp's landing, facing down the ramp, the toes 10 cm from the landing's edge).  ``debris``
#: faces down the debris lane, a 4-cm block 0.45 m ahead in the right foot's way;
#: ``kerb_side`` stands beside the step, its side edge (y = 0.5) under the left foot's lane.
STATIONS = {"valve": (0.0, 0.0, 0.0), "car": (0.0, -2.5, 0.0), "door": (0.34, 2.25, 0.0),
            "door_far": (-0.16, 2.25, 0.0), "yard": (-3.0, 0.0, 0.0), "plug": (0.0, -5.0, 0.0),
            "wall": (0.0, -7.5, 0.0), "terrain": (-6.0, 0.0, 0.0),
            "ramp": (-6.0, -1.2, 0.0),
            "debris": (-6.0, 1.2, 0.0), "kerb_side": (-6.0, 0.42, 0.0),
            "debris_field": (-6.0, DEBRIS_FIELD_LANE, 0.0),
            "ramp_top": (TERRAIN_RAMP[1] + TERRAIN_RAMP[2] * math.cos(TERRAIN_RAMP[3]) + 0.26,
                         TERRAIN_RAMP[0], math.pi)}
#: The height (m) of the ground a station stands on, where it is not the floor.
STATION_GROUND = {"ramp_top": TERRAIN_RAMP[2] * math.sin(TERRAIN_RAMP[3])}
#: The robot sits in the car, as Walk-Man drove at the DRC (the team put it in the vehicle
#: and skipped the egress): thighs level on the seat, shanks upright, soles flat on the car's
#: floor -- the seat, not a balance controller, carries it while the right foot is on the
#: pedal.  Every other station stands in the home posture.
SEATED_POSTURE = {f"{side}{joint}": angle for side in "LR"
                  for joint, angle in (("HipSag", -1.57), ("KneeSag", 1.57), ("AnkSag", 0.0))}
STATION_POSTURE = {"car": SEATED_POSTURE}


def task_harness(station: str) -> str:
    """The harness a task module runs in at ``station`` (tests, benchmarks): none seated in
    the car, where the seat carries the robot; locked standing (walking has its own)."""
    return "off" if station in STATION_POSTURE else "locked"

#: The car seat's top (m above the ground), where the thighs rest: the soles hang 1 cm over
#: the car's floor, so the seat, not the legs, carries the robot
#: (walkman.hal.sim.MujocoPlant.place).
CAR_SEAT_TOP = 0.47
#: Vertical stiffness (N/m) of the harness spring and its share of the robot's weight when
#: the feet touch the floor (trolley mode).
HARNESS_STIFFNESS = 3000.0
HARNESS_SHARE = 0.3


def _v(values) -> str:
    return " ".join(f"{value:.6g}" for value in values)


def _geom(geom: Geom, name: str) -> str:
    rgba = _v(geom.rgba)
    if geom.kind == "box":
        return (f'<geom name="{name}" type="box" size="{_v(geom.size)}" pos="{_v(geom.pos)}" '
                f'rgba="{rgba}"/>')
    radius, half = geom.size
    axis = "xyz".index(geom.axis)
    start, end = list(geom.pos), list(geom.pos)
    start[axis] -= half
    end[axis] += half
    return (f'<geom name="{name}" type="capsule" size="{radius:g}" fromto="{_v(start)} {_v(end)}" '
            f'rgba="{rgba}"/>')


def _body(robot: Robot, link_name: str, pos, indent: int, out: List[str], free: bool) -> None:
    link = robot.links[link_name]
    pad = "  " * indent
    out.append(f'{pad}<body name="{link_name}" pos="{_v(pos)}" childclass="robot">')
    if free:
        out.append(f'{pad}  <freejoint name="base"/>')
    ixx, iyy, izz = link.inertia()
    out.append(f'{pad}  <inertial pos="{_v(link.com)}" mass="{link.mass:g}" '
               f'diaginertia="{ixx:.6g} {iyy:.6g} {izz:.6g}"/>')
    for index, geom in enumerate(link.geoms):
        text = _geom(geom, f"{link_name}_geom{index}")
        if link_name.endswith("_fingers"):  # grasps are welds (walkman/hal/sim.py): no contact
            text = text.replace("<geom ", '<geom contype="0" conaffinity="0" ', 1)
        out.append(f"{pad}  {text}")
    for sensor in robot.sensors:
        if sensor.link == link_name:
            out.append(f'{pad}  <site name="{sensor.name}" pos="{_v(sensor.pos)}" size="0.01"/>')
            if sensor.kind == "camera":
                # MuJoCo cameras look along -z with +y up: turn that to +x forward, +z up.
                out.append(f'{pad}  <camera name="{sensor.name}" pos="{_v(sensor.pos)}" '
                           f'xyaxes="0 -1 0 0 0 1" fovy="60"/>')
    if link_name.endswith("_hand"):
        out.append(f'{pad}  <site name="{link_name}_grip" pos="0 0 -0.1" size="0.012" '
                   f'rgba="0 1 0 0.5"/>')
    for joint in sorted(robot.children(link_name), key=lambda j: j.child):
        out.append(f'{pad}  <body name="{joint.child}_joint_frame" pos="{_v(joint.origin)}">')
        out.append(f'{pad}    <joint name="{joint.name}" type="hinge" axis="{_v(joint.axis)}" '
                   f'range="{joint.lower:g} {joint.upper:g}" armature="0.05" damping="2" '
                   f'limited="true"/>')
        _body(robot, joint.child, (0, 0, 0), indent + 2, out, free=False)
        out.append(f"{pad}  </body>")
    out.append(f"{pad}</body>")


def robot_body(robot: Robot, base_pos=(0.0, 0.0, STANDING_PELVIS_HEIGHT)) -> List[str]:
    out: List[str] = []
    _body(robot, robot.base, base_pos, 2, out, free=True)
    return out


def actuators(robot: Robot) -> List[str]:
    out = ["  <actuator>"]
    for name in robot.joint_names:
        joint = robot.joint(name)
        out.append(f'    <general name="{name}" joint="{name}" gaintype="fixed" biastype="affine" '
                   f'gainprm="{joint.stiffness:g}" biasprm="0 -{joint.stiffness:g} -{joint.damping:g}" '
                   f'forcerange="-{joint.effort:g} {joint.effort:g}" forcelimited="true" '
                   f'ctrlrange="{joint.lower:g} {joint.upper:g}" ctrllimited="true"/>')
    out.append("  </actuator>")
    return out


def sensors(robot: Robot) -> List[str]:
    out = ["  <sensor>"]
    for sensor in robot.sensors:
        if sensor.kind == "ft":
            out.append(f'    <force name="{sensor.name}_force" site="{sensor.name}"/>')
            out.append(f'    <torque name="{sensor.name}_torque" site="{sensor.name}"/>')
        elif sensor.kind == "imu":
            out.append(f'    <framequat name="imu_orientation" objtype="site" objname="{sensor.name}"/>')
            out.append(f'    <gyro name="imu_gyro" site="{sensor.name}"/>')
            out.append(f'    <accelerometer name="imu_accelerometer" site="{sensor.name}"/>')
    out.append("  </sensor>")
    return out


def scene_bodies() -> List[str]:
    """The DRC props, articulated."""
    return """    <!-- valve: a hand wheel on a wall in front of the robot -->
    <body name="valve_wall" pos="0.78 0 1.0">
      <geom name="valve_wall" type="box" size="0.05 0.8 1.0" rgba="0.8 0.8 0.75 1"/>
      <body name="valve_wheel" pos="-0.12 0.25 0.2" sleep="never">
        <joint name="valve" type="hinge" axis="1 0 0" damping="0.5" frictionloss="0.5"/>
        <geom name="valve_rim" type="cylinder" size="0.15 0.012" euler="0 1.5708 0" rgba="0.8 0.1 0.1 1"/>
        <geom name="valve_hub" type="cylinder" size="0.025 0.06" euler="0 1.5708 0" pos="0.06 0 0" rgba="0.3 0.3 0.3 1"/>
        <site name="valve_grip" pos="0 0 0.15" size="0.015" rgba="1 1 0 0.6"/>
      </body>
    </body>
    <!-- the car: a seat with a backrest, the steering wheel before the chest, the throttle
         pedal before the right foot -->
    <body name="car" pos="0 -2.5 0">
      <geom name="car_floor" type="box" size="0.6 0.5 0.005" pos="0.3 0 0.005" rgba="0.4 0.4 0.45 1"/>
      <geom name="car_seat" type="box" size="0.23 0.25 0.1" pos="0.05 0 0.37" rgba="0.25 0.25 0.3 1"/>
      <geom name="car_backrest" type="box" size="0.03 0.25 0.15" pos="-0.16 0 0.70" rgba="0.25 0.25 0.3 1"/>
      <geom name="car_dash" type="box" size="0.05 0.4 0.3" pos="0.9 0 0.8" rgba="0.3 0.3 0.35 1"/>
      <body name="steering_column" pos="0.55 0.1 0.80" euler="0 -1.0472 0">
        <geom name="steering_shaft" type="cylinder" size="0.02 0.15" pos="0 0 -0.15" rgba="0.2 0.2 0.2 1"/>
        <body name="steering_wheel" sleep="never">
          <joint name="steering" type="hinge" axis="0 0 1" range="-6.28 6.28" damping="0.8" frictionloss="1.5"/>
          <geom name="steering_rim" type="cylinder" size="0.18 0.015" rgba="0.1 0.1 0.1 1"/>
          <site name="steering_grip" pos="0 0.18 0" size="0.015" rgba="1 1 0 0.6"/>
        </body>
      </body>
      <body name="throttle_pedal" pos="0.60 -0.11 0.08" sleep="never">
        <joint name="throttle" type="hinge" axis="0 1 0" range="0 0.35" stiffness="60" springref="0" damping="2"/>
        <geom name="throttle_pad" type="box" size="0.09 0.06 0.008" pos="0.09 0 0" euler="0 -0.349 0" rgba="0.1 0.1 0.1 1"/>
      </body>
    </body>
    <!-- door with a latched lever handle, to the robot's left; it opens away from the robot -->
    <body name="door_frame" pos="0.9 2.5 1.1">
      <geom name="door_post_a" type="box" size="0.05 0.05 1.1" pos="0 -0.4 0" rgba="0.6 0.5 0.4 1"/>
      <geom name="door_post_b" type="box" size="0.05 0.05 1.1" pos="0 0.4 0" rgba="0.6 0.5 0.4 1"/>
      <body name="door" pos="0 0.36 0" sleep="never">
        <joint name="door" type="hinge" axis="0 0 1" range="-0.02 1.7" damping="3" frictionloss="1"/>
        <geom name="door_panel" type="box" size="0.02 0.35 1.0" pos="0 -0.35 0" rgba="0.7 0.55 0.35 1"/>
        <body name="door_handle" pos="-0.06 -0.6 0.05">
          <joint name="door_handle" type="hinge" axis="1 0 0" range="-0.9 0.02" stiffness="8" springref="0" damping="0.2"/>
          <geom name="door_handle_lever" type="capsule" size="0.015" fromto="0 0 0 0 0.12 0" rgba="0.8 0.8 0.2 1"/>
          <site name="door_handle_grip" pos="0 0.09 0" size="0.015" rgba="1 1 0 0.6"/>
        </body>
      </body>
    </body>""".splitlines() + plug_bodies() + wall_bodies() + terrain_bodies() + \
        debris_field_bodies()


#: The plug's body: a 5x5x8 cm block (half sizes) with a handle bar along y on a post.
PLUG_HALF = (0.025, 0.025, 0.04)
PLUG_HANDLE_UP = 0.06      # m from the block's top to the handle's axis
#: The sockets: open boxes 9 cm inside, 6 cm deep: 2 cm of play each side of the plug, what
#: a real socket's chamfer gives a hand that places it to 1 cm.
SOCKET_INNER, SOCKET_WALL, SOCKET_DEPTH = 0.045, 0.008, 0.06


def plug_in_socket(position: Sequence[float], socket: str) -> bool:
    """Whether the plug's block (world ``x, y, z`` of its centre) stands in ``socket``: on the
    table, its centre within the play the square walls leave on each axis (2 mm more for the
    contacts' give).  Per axis, not by distance: a plug in a corner is in (CI of 1cd947a
    failed one 1.6 cm off on both axes, 2.2 cm from the centre)."""
    x, y, z = position[:3]
    centre_x, centre_y = PLUG_SOCKETS[socket]
    play = SOCKET_INNER - PLUG_HALF[0] + 0.002
    return bool(abs(x - centre_x) < play and abs(y - centre_y) < play
                and abs(z - (PLUG_TABLE_TOP + PLUG_HALF[2])) < 0.01)


def plug_bodies() -> List[str]:
    """The surprise task's table, its two sockets, and the plug standing in socket a."""
    (xa, ya), (_, yb) = PLUG_SOCKETS["a"], PLUG_SOCKETS["b"]
    top, inner, wall, depth = PLUG_TABLE_TOP, SOCKET_INNER, SOCKET_WALL, SOCKET_DEPTH
    out = ["    <!-- the surprise task: pull the plug from socket a, push it into socket b -->",
           f'    <body name="plug_table" pos="{xa:g} {(ya + yb) / 2:g} {top / 2:g}">',
           f'      <geom name="plug_table_top" type="box" size="0.15 0.22 {top / 2:g}" '
           f'rgba="0.55 0.45 0.35 1"/>',
           "    </body>"]
    for name, (x, y) in PLUG_SOCKETS.items():
        out.append(f'    <body name="socket_{name}" pos="{x:g} {y:g} {top:g}">')
        half = inner + wall / 2
        for index, (dx, dy, sx, sy) in enumerate(((half, 0, wall / 2, half + wall / 2),
                                                  (-half, 0, wall / 2, half + wall / 2),
                                                  (0, half, half + wall / 2, wall / 2),
                                                  (0, -half, half + wall / 2, wall / 2))):
            out.append(f'      <geom name="socket_{name}_wall{index}" type="box" '
                       f'size="{sx:g} {sy:g} {depth / 2:g}" pos="{dx:g} {dy:g} {depth / 2:g}" '
                       f'rgba="0.2 0.2 0.25 1"/>')
        out.append("    </body>")
    hx, hy, hz = PLUG_HALF
    out += [f'    <body name="plug" pos="{xa:g} {ya:g} {top + hz + 0.001:g}" sleep="never">',
            '      <freejoint name="plug"/>',
            # Props do not touch each other (contype 2, conaffinity 1); the plug must touch
            # the table and the sockets as well as the robot.
            f'      <geom name="plug_block" type="box" size="{hx:g} {hy:g} {hz:g}" mass="0.3" '
            f'friction="0.6" contype="3" conaffinity="3" rgba="0.1 0.3 0.8 1"/>',
            # The handle stands on a post, high enough that the hand holding it stays above
            # the socket's walls while the plug goes in.
            f'      <geom name="plug_post" type="capsule" size="0.01" '
            f'fromto="0 0 {hz:g} 0 0 {hz + PLUG_HANDLE_UP:g}" mass="0.03" contype="3" '
            f'conaffinity="3" rgba="0.9 0.9 0.9 1"/>',
            f'      <geom name="plug_handle" type="capsule" size="0.012" '
            f'fromto="0 {-hy - 0.005:g} {hz + PLUG_HANDLE_UP:g} 0 {hy + 0.005:g} '
            f'{hz + PLUG_HANDLE_UP:g}" mass="0.05" contype="3" conaffinity="3" '
            f'rgba="0.9 0.9 0.9 1"/>',
            f'      <site name="plug_grip" pos="0 0 {hz + PLUG_HANDLE_UP:g}" size="0.015" '
            f'rgba="1 1 0 0.6"/>',
            "    </body>"]
    return out


#: The drill, in its own frame (origin at the grip, the middle of the handle; x along the
#: bit): where the bit's tip is.  A hand that holds the drill by its grip squeezes the
#: trigger by closing further (walkman/hal/sim.py's ``DRILL_TRIGGER``).
DRILL_TIP = (0.254, 0.0, 0.07)
DRILL_FOOT = 0.08          # m from the grip down to the bottom of the battery it stands on


def wall_bodies() -> List[str]:
    """The wall task: a table with the drill standing on it, a drywall panel with a circle."""
    gx, gy, gz = DRILL_GRIP
    tx, ty, tz = DRILL_TIP
    cx, cy, cz = WALL_CIRCLE_CENTRE
    top, face, half_thick = DRILL_TABLE_TOP, WALL_FACE_X, WALL_THICKNESS / 2
    return [
        "    <!-- the wall task: the drill on its table, the drywall with a circle to cut out -->",
        f'    <body name="drill_table" pos="{gx:g} {gy:g} {top / 2:g}">',
        f'      <geom name="drill_table_top" type="box" size="0.12 0.15 {top / 2:g}" '
        f'rgba="0.55 0.45 0.35 1"/>',
        "    </body>",
        f'    <body name="drywall" pos="{face + half_thick:g} {cy + 0.1:g} 0.8">',
        f'      <geom name="drywall_panel" type="box" size="{half_thick:g} 0.4 0.8" '
        f'rgba="0.92 0.92 0.88 1"/>',
        # The circle drawn on the panel (no contact): a dark ring on the face.
        f'      <geom name="wall_circle_ring" type="cylinder" contype="0" conaffinity="0" '
        f'size="{WALL_CIRCLE_RADIUS + 0.004:g} 0.0005" euler="0 1.5708 0" '
        f'pos="{-half_thick - 0.001:g} {cy - (cy + 0.1):g} {cz - 0.8:g}" rgba="0.1 0.1 0.1 1"/>',
        f'      <geom name="wall_circle_inside" type="cylinder" contype="0" conaffinity="0" '
        f'size="{WALL_CIRCLE_RADIUS - 0.004:g} 0.0005" euler="0 1.5708 0" '
        f'pos="{-half_thick - 0.0015:g} {cy - (cy + 0.1):g} {cz - 0.8:g}" '
        f'rgba="0.92 0.92 0.88 1"/>',
        f'      <site name="wall_circle" pos="{-half_thick:g} {cy - (cy + 0.1):g} {cz - 0.8:g}" '
        f'size="0.01" rgba="1 0 0 0.6"/>',
        "    </body>",
        f'    <body name="drill" pos="{gx:g} {gy:g} {top + DRILL_FOOT + 0.001:g}" '
        f'sleep="never">',
        '      <freejoint name="drill"/>',
        # The drill touches the table and the robot (contype 3); its bit touches nothing:
        # the drywall's cut is judged from the bit's path (walkman/hal/drywall.py).
        '      <geom name="drill_handle" type="box" size="0.015 0.02 0.05" mass="0.3" '
        'friction="0.8" contype="3" conaffinity="3" rgba="0.9 0.5 0.1 1"/>',
        f'      <geom name="drill_battery" type="box" size="0.035 0.03 0.015" '
        f'pos="0 0 {-DRILL_FOOT + 0.015:g}" mass="0.4" friction="0.8" contype="3" '
        f'conaffinity="3" rgba="0.2 0.2 0.2 1"/>',
        f'      <geom name="drill_motor" type="box" size="0.09 0.025 0.025" '
        f'pos="0.06 0 {tz:g}" mass="0.5" contype="3" conaffinity="3" rgba="0.9 0.5 0.1 1"/>',
        f'      <geom name="drill_bit" type="capsule" size="0.004" '
        f'fromto="0.15 0 {tz:g} {tx - 0.004:g} 0 {tz:g}" mass="0.02" contype="0" '
        f'conaffinity="0" rgba="0.7 0.7 0.75 1"/>',
        '      <site name="drill_grip" pos="0 0 0" size="0.015" rgba="1 1 0 0.6"/>',
        f'      <site name="drill_tip" pos="{tx:g} {ty:g} {tz:g}" size="0.005" '
        f'rgba="1 0 0 0.8"/>',
        "    </body>"]


def terrain_bodies() -> List[str]:
    """The rough-ground course: the step, the ramp, the debris (static: the world's)."""
    start, end, height = TERRAIN_STEP
    lane, foot, length, slope = TERRAIN_RAMP
    rise = length * math.sin(slope)
    grey = 'rgba="0.55 0.5 0.45 1"'
    out = ["    <!-- rough ground: a step across the way, a ramp to the right, debris left -->",
           f'    <geom name="terrain_step" type="box" size="{(end - start) / 2:g} 0.5 '
           f'{height / 2:g}" pos="{(start + end) / 2:g} 0 {height / 2:g}" {grey}/>',
           # the ramp: a slab tilted about y, its top edge on the floor at ``foot``; a
           # landing as high as the ramp's top behind it
           f'    <geom name="terrain_ramp" type="box" size="{length / 2:g} 0.5 0.02" '
           f'pos="{foot + length / 2 * math.cos(slope) + 0.02 * math.sin(slope):.5g} {lane:g} '
           f'{length / 2 * math.sin(slope) - 0.02 * math.cos(slope):.5g}" '
           f'euler="0 {-slope:.5g} 0" {grey}/>',
           f'    <geom name="terrain_landing" type="box" size="0.4 0.5 {rise / 2:.5g}" '
           f'pos="{foot + length * math.cos(slope) + 0.4:.5g} {lane:g} {rise / 2:.5g}" {grey}/>']
    for index, (x, y, yaw, hx, hy, hz) in enumerate(TERRAIN_DEBRIS):
        out.append(f'    <geom name="terrain_debris{index}" type="box" size="{hx:g} {hy:g} '
                   f'{hz:g}" pos="{x:g} {y:g} {hz:g}" euler="0 0 {yaw:g}" '
                   f'rgba="0.45 0.35 0.25 1"/>')
    return out


def debris_field_bodies() -> List[str]:
    """The debris field's boards: free bodies lying on the floor (:data:`DEBRIS_BOARDS`)."""
    length, width, thick = DEBRIS_BOARD_HALF
    out = ["    <!-- the debris field: light boards scattered on the floor -->"]
    for index, (x, dy, yaw) in enumerate(DEBRIS_BOARDS):
        # a board's length runs across the way at yaw 0: its box's y half size
        out += [f'    <body name="debris_board{index}" pos="{x:g} {DEBRIS_FIELD_LANE + dy:g} '
                f'{thick:g}" euler="0 0 {yaw:g}" sleep="init">',
                f'      <freejoint name="debris_board{index}"/>',
                f'      <geom name="debris_board{index}" type="box" size="{width:g} {length:g} '
                f'{thick:g}" density="{DEBRIS_BOARD_DENSITY:g}" friction="0.6" contype="3" '
                f'conaffinity="3"\n        rgba="0.76 0.6 0.42 1"/>',
                "    </body>"]
    return out


def harness_body(robot: Robot) -> List[str]:
    """The trolley the pelvis hangs from (see the module docstring)."""
    weight = robot.total_mass * 9.81
    springref = HARNESS_SHARE * weight / HARNESS_STIFFNESS
    return [f'    <body name="harness_trolley" pos="0 0 {STANDING_PELVIS_HEIGHT:g}" '
            f'sleep="never">',
            '      <joint name="harness_x" type="slide" axis="1 0 0" damping="150"/>',
            '      <joint name="harness_y" type="slide" axis="0 1 0" damping="150"/>',
            f'      <joint name="harness_z" type="slide" axis="0 0 1" range="-0.15 0.05" '
            f'stiffness="{HARNESS_STIFFNESS:g}" springref="{springref:.4f}" damping="800"/>',
            '      <joint name="harness_yaw" type="hinge" axis="0 0 1" damping="20"/>',
            '      <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>',
            '    </body>']


def equalities(drc: bool) -> List[str]:
    out = ["  <equality>",
           '    <weld name="harness" body1="pelvis" body2="harness_trolley" solref="0.004 1" '
           'active="true"/>',
           '    <weld name="harness_brake" body1="harness_trolley" solref="0.02 1" active="true"/>']
    if drc:
        out.append('    <joint name="door_latch" joint1="door" active="true"/>')
        for hand in HANDS:
            for part, body, _ in GRASPABLE:
                out.append(f'    <weld name="grasp_{hand}_{part}" body1="{hand}_hand" body2="{body}" '
                           f'solref="0.01 1" active="false"/>')
    out.append("  </equality>")
    return out


def keyframe(robot: Robot) -> List[str]:
    posture = home_posture(robot)
    # qpos layout: free base (7), then joints in MJCF body order (= sorted DFS)
    order = mjcf_joint_order(robot)
    qpos = [0.0, 0.0, STANDING_PELVIS_HEIGHT, 1.0, 0.0, 0.0, 0.0] + [posture[n] for n in order]
    ctrl = [posture[name] for name in robot.joint_names]
    return ["  <keyframe>", f'    <key name="home" qpos="{_v(qpos)}" ctrl="{_v(ctrl)}"/>',
            "  </keyframe>"]


def mjcf_joint_order(robot: Robot) -> List[str]:
    """Robot joints in the order MuJoCo (and Pinocchio) number them."""
    order: List[str] = []

    def visit(link: str) -> None:
        for joint in sorted(robot.children(link), key=lambda j: j.child):
            order.append(joint.name)
            visit(joint.child)
    visit(robot.base)
    return order


SLEEP_FLAG = '<flag sleep="enable"/>'


def to_mjcf(robot: Robot, drc: bool = True, timestep: float = 0.001) -> str:
    lines = ["<!-- Generated by walkman.model.mjcf from walkman.model.description; do not edit. -->",
             f'<mujoco model="{robot.name}{"_drc" if drc else ""}">',
             '  <compiler angle="radian" autolimits="true"/>',
             # MuJoCo's sleeping: a tree at rest is left out of the step until something
             # touches it.  Only the debris field's boards may sleep (they lie still until a
             # foot kicks one: asleep, five boards on the floor cost nothing, awake 50 us a
             # step); every other part of the scene is marked never to.
             f'  <option timestep="{timestep:g}" integrator="implicitfast">'
             f'{SLEEP_FLAG if drc else ""}</option>',
             '  <visual><global offwidth="640" offheight="480"/></visual>',
             # The robot does not collide with itself (contype 1 / conaffinity 2); the
             # floor and the props (contype 2 / conaffinity 1) collide with the robot.
             '  <default><geom friction="1.0 0.02 0.001" condim="3" contype="2" conaffinity="1"/>',
             '    <default class="robot"><geom contype="1" conaffinity="2"/></default></default>',
             "  <worldbody>",
             '    <light name="sun" pos="0 0 4" dir="0 0 -1" diffuse="0.8 0.8 0.8"/>',
             '    <geom name="floor" type="plane" size="10 10 0.1" rgba="0.5 0.55 0.5 1"/>']
    lines += robot_body(robot)
    if drc:
        lines += scene_bodies()
    lines += harness_body(robot)
    lines.append("  </worldbody>")
    lines += actuators(robot)
    lines += sensors(robot)
    if drc:
        # A hand holds the plug and the drill by a weld, as it holds every part: its palm
        # must not push what it carries (the fingers have no contact at all).
        lines += ["  <contact>", *(f'    <exclude body1="{hand}_hand" body2="{part}"/>'
                                  for hand in HANDS for part in ("plug", "drill")),
                  "  </contact>"]
    lines += equalities(drc)
    lines += keyframe(robot)
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(to_mjcf(walkman()), end="")
