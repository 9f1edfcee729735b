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
* a car seat with a steering wheel and a throttle pedal (to the robot's right);
* a door with a lever handle (to the robot's left);
* a ``harness``: a weld from the pelvis to the world, on by default, that
  holds the robot up while it manipulates (the support harness is part of the
  scene and named as such; walking loosens it);
* grasp welds between each hand and each graspable part, off until the HAL
  closes a hand next to the part (see ``walkman/hal/sim.py``).
"""

from __future__ import annotations

from typing import List

from walkman.model.description import (STANDING_PELVIS_HEIGHT, Geom, Robot, home_posture,
                                       walkman)

#: Parts a hand can grasp: (name, body, site) -- the site is where the hand must be.
GRASPABLE = (("valve", "valve_wheel", "valve_grip"),
             ("steering_wheel", "steering_wheel", "steering_grip"),
             ("door_handle", "door_handle", "door_handle_grip"))
HANDS = ("l", "r")


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
        out.append(f"{pad}  {_geom(geom, f'{link_name}_geom{index}')}")
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
                   f'gainprm="{joint.stiffness:g}" biasprm="0 -{joint.stiffness:g} -60" '
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
      <body name="valve_wheel" pos="-0.12 0.25 0.2">
        <joint name="valve" type="hinge" axis="1 0 0" damping="0.5" frictionloss="0.5"/>
        <geom name="valve_rim" type="cylinder" size="0.15 0.012" euler="0 90 0" rgba="0.8 0.1 0.1 1"/>
        <geom name="valve_hub" type="cylinder" size="0.025 0.06" euler="0 90 0" pos="0.06 0 0" rgba="0.3 0.3 0.3 1"/>
        <site name="valve_grip" pos="0 0 0.15" size="0.015" rgba="1 1 0 0.6"/>
      </body>
    </body>
    <!-- car: seat, steering wheel and throttle pedal, to the robot's right -->
    <body name="car" pos="0 -2.5 0">
      <geom name="car_floor" type="box" size="0.8 0.6 0.02" pos="0.3 0 0.25" rgba="0.4 0.4 0.45 1"/>
      <geom name="car_seat" type="box" size="0.25 0.3 0.06" pos="0 0 0.55" rgba="0.2 0.2 0.6 1"/>
      <body name="steering_column" pos="0.55 0.1 1.05" euler="0 -60 0">
        <body name="steering_wheel">
          <joint name="steering" type="hinge" axis="0 0 1" range="-6.28 6.28" damping="0.8"/>
          <geom name="steering_rim" type="cylinder" size="0.18 0.015" rgba="0.1 0.1 0.1 1"/>
          <site name="steering_grip" pos="0 0.18 0" size="0.015" rgba="1 1 0 0.6"/>
        </body>
      </body>
      <body name="throttle_pedal" pos="0.8 -0.12 0.35">
        <joint name="throttle" type="hinge" axis="0 1 0" range="0 0.5" stiffness="30" damping="1"/>
        <geom name="throttle_pad" type="box" size="0.06 0.04 0.01" pos="0 0 0.06" euler="0 -30 0" rgba="0.1 0.1 0.1 1"/>
      </body>
    </body>
    <!-- door with a lever handle, to the robot's left -->
    <body name="door_frame" pos="0.9 2.5 1.1">
      <geom name="door_post_a" type="box" size="0.05 0.05 1.1" pos="0 -0.5 0" rgba="0.6 0.5 0.4 1"/>
      <geom name="door_post_b" type="box" size="0.05 0.05 1.1" pos="0 0.5 0" rgba="0.6 0.5 0.4 1"/>
      <body name="door" pos="0 0.45 0">
        <joint name="door" type="hinge" axis="0 0 1" range="-1.7 0.05" damping="3" frictionloss="1"/>
        <geom name="door_panel" type="box" size="0.02 0.44 1.0" pos="0 -0.44 0" rgba="0.7 0.55 0.35 1"/>
        <body name="door_handle" pos="-0.06 -0.8 0">
          <joint name="door_handle" type="hinge" axis="1 0 0" range="-0.05 0.9" stiffness="8" damping="0.2"/>
          <geom name="door_handle_lever" type="capsule" size="0.015" fromto="0 0 0 0 0.12 0" rgba="0.8 0.8 0.2 1"/>
          <site name="door_handle_grip" pos="0 0.09 0" size="0.015" rgba="1 1 0 0.6"/>
        </body>
      </body>
    </body>""".splitlines()


def equalities(drc: bool) -> List[str]:
    out = ["  <equality>",
           '    <weld name="harness" body1="pelvis" solref="0.02 1" active="true"/>']
    if drc:
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


def to_mjcf(robot: Robot, drc: bool = True, timestep: float = 0.001) -> str:
    lines = ["<!-- Generated by walkman.model.mjcf from walkman.model.description; do not edit. -->",
             f'<mujoco model="{robot.name}{"_drc" if drc else ""}">',
             '  <compiler angle="radian" autolimits="true"/>',
             f'  <option timestep="{timestep:g}" integrator="implicitfast"/>',
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
    lines.append("  </worldbody>")
    lines += actuators(robot)
    lines += sensors(robot)
    lines += equalities(drc)
    lines += keyframe(robot)
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(to_mjcf(walkman()), end="")
