"""One robot description: URDF (Pinocchio) and MJCF (MuJoCo) agree, FACTS.md limits hold."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from walkman.model import MJCF_PATH, SCENE_PATH, URDF_PATH
from walkman.model.description import home_posture, walkman
from walkman.model.generate import render
from walkman.model.mjcf import mjcf_joint_order

# From FACTS.md (rad).
FACTS_LIMITS = {
    "WaistLat": (-0.6109, 0.6109), "WaistSag": (-0.3491, 1.3963), "WaistYaw": (-2.8449, 2.8449),
    "NeckYawj": (-0.6109, 0.6109), "NeckPitchj": (-0.2618, 1.0472),
    "LShSag": (-2.8798, 2.7925), "LShLat": (0.0873, 3.8572), "LShYaw": (-2.8449, 2.8449),
    "LElbj": (-2.9671, 0.5934), "LForearmPlate": (-2.529, 2.529), "LWrj1": (-1.48, 1.48),
    "LWrj2": (-1.48, 1.48), "RShLat": (-3.8572, -0.1222),
    "LHipLat": (-0.6978, 0.8722), "LHipYaw": (-0.8722, 1.57), "LHipSag": (-2.0933, 1.0467),
    "LKneeSag": (0.0, 2.4422), "LAnkSag": (-1.3956, 0.6978), "LAnkLat": (-0.785, 0.785),
    "RHipLat": (-0.8722, 0.6978), "RHipYaw": (-1.57, 0.8722),
}
EFFORT_220 = ["LHipLat", "LHipSag", "LKneeSag", "LAnkSag", "WaistSag"]
EFFORT_60 = ["LElbj", "LForearmPlate", "LWrj1", "LWrj2"]


@pytest.fixture(scope="module")
def robot():
    return walkman()


def test_committed_model_files_are_up_to_date():
    for name, text in render().items():
        path = URDF_PATH.parent / name
        assert path.read_text() == text, f"{name} is stale: run python -m walkman.model.generate"


def test_33_joints_31_body_plus_2_hands(robot):
    names = robot.joint_names
    assert len(names) == 33 and len(set(names)) == 33
    assert names[-2:] == ["l_handj", "r_handj"]
    assert 100 < robot.total_mass < 140


def test_limits_and_efforts_follow_facts(robot):
    for name, (low, high) in FACTS_LIMITS.items():
        joint = robot.joint(name)
        assert (joint.lower, joint.upper) == (low, high), name
    for name in EFFORT_220:
        assert robot.joint(name).effort == 220.0
    for name in EFFORT_60:
        assert robot.joint(name).effort == 60.0


def test_pinocchio_and_mujoco_agree_on_names_order_and_limits(robot):
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    pin_names = [model.names[i] for i in range(1, model.njoints)]
    mj = mujoco.MjModel.from_xml_path(str(MJCF_PATH))
    mj_names = [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(1, mj.njnt)]
    # After the robot's joints come the support harness's (its trolley), not the robot's.
    assert mj_names[len(pin_names):] == ["harness_x", "harness_y", "harness_z", "harness_yaw"]
    assert pin_names == mj_names[:len(pin_names)] == mjcf_joint_order(robot)
    for index, name in enumerate(pin_names):
        joint = mj.joint(name)
        assert tuple(joint.range) == pytest.approx((robot.joint(name).lower, robot.joint(name).upper))
        assert model.lowerPositionLimit[index] == pytest.approx(robot.joint(name).lower)
        assert model.upperPositionLimit[index] == pytest.approx(robot.joint(name).upper)
        assert model.effortLimit[index] == pytest.approx(robot.joint(name).effort)


def test_same_kinematics_in_both(robot):
    """The head camera frame is at the same place in Pinocchio and MuJoCo, posture by posture."""
    model = pin.buildModelFromUrdf(str(URDF_PATH))
    data = model.createData()
    mj = mujoco.MjModel.from_xml_path(str(MJCF_PATH))
    mjd = mujoco.MjData(mj)
    posture = home_posture(robot)
    posture.update({"NeckYawj": 0.4, "NeckPitchj": 0.5, "WaistYaw": 0.3, "LElbj": -1.0})
    order = mjcf_joint_order(robot)
    q = [posture[name] for name in order]
    pin.framesForwardKinematics(model, data, pin.utils.np.array(q))
    mjd.qpos[7:7 + len(q)] = q  # then the harness trolley's joints
    mjd.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
    mujoco.mj_forward(mj, mjd)
    for frame, site in (("multisense_frame", "multisense"), ("l_arm_ft_frame", "l_arm_ft"),
                        ("r_leg_ft_frame", "r_leg_ft")):
        pin_pos = data.oMf[model.getFrameId(frame)].translation
        mj_pos = mjd.site(site).xpos
        assert pin_pos == pytest.approx(mj_pos, abs=1e-6), frame


def test_scene_has_the_drc_props_and_sensors():
    mj = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    for joint in ("valve", "steering", "throttle", "door", "door_handle"):
        assert mj.joint(joint) is not None
    assert mj.camera("multisense") is not None
    for sensor in ("l_arm_ft_force", "r_leg_ft_torque", "imu_gyro", "imu_orientation"):
        assert mj.sensor(sensor) is not None
    assert mj.equality("harness") is not None and mj.equality("grasp_l_valve") is not None
    assert mj.nu == 33


def test_home_posture_is_inside_limits(robot):
    for name, value in home_posture(robot).items():
        joint = robot.joint(name)
        assert joint.lower <= value <= joint.upper, name


def test_the_joints_that_carry_the_robot_are_damped_enough_to_walk(robot):
    """The legs: SUPPORT_DAMPING in the model, the MJCF actuators and the sim servos (the
    arms and the waist keep the 60 the manipulation tasks were tuned with)."""
    from walkman.hal.sim import SimBackend
    from walkman.model.description import SUPPORT_DAMPING

    backend = SimBackend(harness="off")
    mj = backend.plant.m
    for joint in robot.joints:
        carries = joint.chain in ("left_leg", "right_leg")
        assert joint.damping == (SUPPORT_DAMPING if carries else 60.0), joint.name
        actuator = mj.actuator(joint.name)
        assert actuator.biasprm[2] == pytest.approx(-joint.damping), joint.name


def test_a_push_moves_the_free_robot_and_bad_pushes_are_refused():
    from walkman.hal.sim import SimBackend

    backend = SimBackend(harness="off", station="yard")
    for _ in range(200):
        backend.step()
    with pytest.raises(ValueError, match="three finite numbers"):
        backend.push((1.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="more than 500 N\\*s"):
        backend.push((0.0, 600.0, 0.0))
    with pytest.raises(ValueError, match="lasts 0.001..1 s"):
        backend.push((0.0, 10.0, 0.0), duration=5.0)
    body = backend.plant.m.body("pelvis").id
    backend.push((0.0, 30.0, 0.0))
    for _ in range(110):   # the push lasts 0.1 s
        backend.step()
    assert backend.plant.d.cvel[body][4] > 0.1       # the pelvis moves sideways (+y)
    assert not backend.plant.d.xfrc_applied.any()    # and the push is over


#: A sole (the robot's foot box, its friction and condim) carrying the robot's weight on the
#: terrain's 10-degree slope, in MuJoCo at the scene's time step.
_SOLE_ON_A_SLOPE = """
<mujoco>
  <option timestep="0.001" integrator="implicitfast"/>
  <default><geom friction="1.0 0.02 0.001" condim="3"/></default>
  <worldbody>
    <geom name="slope" type="plane" size="2 2 0.1" euler="0 -10 0"/>
    <body name="sole" pos="0 0 0.03" euler="0 -10 0">
      <freejoint/>
      <geom type="box" size="0.13 0.07 0.025" mass="100"/>
    </body>
  </worldbody>
</mujoco>
"""


def _creep(contact: str) -> float:
    """How fast (mm/s) the loaded sole slides down the slope, settled, on ``contact``."""
    from walkman.hal.sim import use_contact

    model = mujoco.MjModel.from_xml_string(_SOLE_ON_A_SLOPE)
    use_contact(model, contact)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 500)                  # settled on the slope
    start = data.body("sole").xpos.copy()
    mujoco.mj_step(model, data, 2000)
    return float(np.linalg.norm(data.body("sole").xpos - start)) / 2.0 * 1000


def test_a_loaded_sole_creeps_down_a_slope_on_soft_contact_and_holds_on_firm():
    """Why the two contact models (walkman.hal.sim.CONTACT_MODELS): well inside the friction
    cone (tan 10 degrees = 0.18 of friction 1), MuJoCo's default soft friction lets a
    sole slide as it holds, as the robot's soles do down the ramp (5 mm/s standing there,
    the controller's own motion on top); firm holds it."""
    soft, firm = _creep("soft"), _creep("firm")
    assert soft > 0.5, soft          # mm/s (0.9 measured): 3 cm a minute, where a sole holds
    assert firm < soft / 4, (soft, firm)                    # 0.15 measured


def test_a_loaded_sole_holds_on_a_slope_with_the_no_slip_solver():
    """``grip``: soft's cones with MuJoCo's no-slip iterations hold the sole (0.0002 mm/s
    measured), where soft alone lets it slide 0.9 mm/s."""
    assert _creep("grip") < _creep("soft") / 100


def test_an_unknown_contact_model_is_refused_before_the_scene_loads():
    from walkman.hal.sim import SimBackend

    with pytest.raises(ValueError, match="unknown contact model 'icy': one of soft, firm, grip"):
        SimBackend(contact="icy")


def test_the_robot_sits_in_the_car_seat_without_the_harness():
    """The car's station seats the robot (thighs on the seat, soles just over the car's
    floor) and the seat holds it: three simulated seconds later it is where it sat."""
    from walkman.hal.sim import SimBackend
    from walkman.model.mjcf import CAR_SEAT_TOP, SEATED_POSTURE

    backend = SimBackend(harness="off", station="car")
    plant = backend.plant
    assert plant.lowest_point(("l_thigh", "r_thigh")) == pytest.approx(CAR_SEAT_TOP, abs=1e-6)
    assert 0.005 < plant.lowest_point() - 0.01 < 0.02       # the car's floor's top is at 1 cm
    for joint, angle in SEATED_POSTURE.items():
        assert backend.reference[backend.index[joint]] == pytest.approx(angle)
    seated = plant.base_pose()
    for _ in range(3000):
        backend.step()
    assert plant.base_pose() == pytest.approx(seated, abs=0.005)
    w, x, y, _ = plant.d.qpos[plant.base + 3:plant.base + 7]
    assert 1.0 - 2.0 * (x * x + y * y) > math.cos(0.02)            # upright within 0.02 rad


@pytest.mark.parametrize("offset, inside", [((0.0, 0.0), True), ((0.019, -0.019), True),
                                            ((0.0, 0.09), False)])
def test_a_plug_dropped_into_socket_b_is_in_it_even_in_a_corner(offset, inside):
    """``plug_in_socket`` is judged by the world: the plug dropped at the socket's centre, in
    its corner (2.7 cm from the centre, more than the play the walls leave on one axis), or on
    the table beside the socket, and settled."""
    from walkman.model.mjcf import PLUG_HALF, PLUG_SOCKETS, PLUG_TABLE_TOP, plug_in_socket

    mj = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    data = mujoco.MjData(mj)
    address = mj.joint("plug").qposadr[0]
    x, y = PLUG_SOCKETS["b"]
    data.qpos[address:address + 3] = (x + offset[0], y + offset[1],
                                      PLUG_TABLE_TOP + PLUG_HALF[2] + 0.005)
    data.qpos[address + 3:address + 7] = (1, 0, 0, 0)
    mujoco.mj_forward(mj, data)
    for _ in range(int(1.0 / mj.opt.timestep)):
        mujoco.mj_step(mj, data)
    settled = data.xpos[mj.body("plug").id]
    assert settled[2] == pytest.approx(PLUG_TABLE_TOP + PLUG_HALF[2], abs=0.005), settled
    assert plug_in_socket(settled, "b") is inside, settled
