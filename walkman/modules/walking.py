"""walking: ``go_straight D``, ``turn A``, ``step_side D`` on its own feet, balanced.

Theory of operation
-------------------
A position-controlled biped walks when its centre of mass (CoM) moves so that
the zero-moment point (ZMP) stays inside the feet.  Four parts, each in its
own module:

* :mod:`walkman.control.footsteps` plans the steps, the swing feet's paths and
  where the ZMP must be (on the stance foot, moving between feet in double
  support), in the *walk frame* fixed on the floor when the module starts;
* :mod:`walkman.control.lipm` turns that ZMP plan into a CoM trajectory by
  Kajita's preview control of the linear inverted pendulum (ICRA 2003);
* :mod:`walkman.control.balance` closes the loop on the fast sensors (the
  ankle F/T sensors and the pelvis IMU, 100 Hz): each ankle turns its foot so
  that the foot's measured centre of pressure comes where it should be
  (Kajita et al.'s damping control, IROS 2010), a PI loop on the IMU's roll and
  pitch tilts the commanded pelvis level (standing still, its integral alone:
  ``standing_still``), and a guard watches the measured
  ZMP's margin to the support polygon and the torso's tilt;
* every tick, the pelvis is placed so that the model's CoM (Pinocchio: the
  legs as commanded, the other joints as measured) is where the preview
  controller wants it, and each foot's pose relative to the pelvis is solved
  by IK over its leg's six joints.  The legs' series-elastic springs give
  under the robot's weight (5 cm of CoM in single support): the command adds
  ``DEFLECTION_SHARE`` of the expected deflection, torque over stiffness, the
  torques being the F/T wrenches through the legs' Jacobians plus their
  weight (standing still, the ankles' share followed slowly: ``commanded``).
  Nothing here reads the joints' own state stream for balance: it
  runs at 500 Hz on a port per chain and reaches a loaded module late (a
  100 ms lag there topples the robot); the F/T and IMU ports stay fresh.

The ground may have steps and ramps (issue 32's rough ground): ``step_up H``
and ``step_down H`` land both feet on ground H higher or lower, ``footsteps``
plays sole poses the pilot placed (pelvis frame, converted to the walk frame
from where the soles are; a footstep's pitch is the ground's), and a walk goes
on as the ground under the standing foot goes (up a ramp's slope); the plan
checks every landing against the legs' reach before a foot lifts, each sole is
pitched like its ground, and the pelvis rises and sinks with the feet's ground.
The module cannot see a kerb's edge: a sole landing on higher ground comes
down heel first and the first touch says whether the heel bears
(:mod:`walkman.control.foothold`); if not -- a ``step_up`` sent from too far
lands the heel over the lower floor -- the pilot is warned and the foot goes
back where it lifted from before the weight goes onto it.  A sole stepping down
that meets ground on its way (a ``step_down`` sent before the kerb's far edge:
the kerb it leaves) stays there and goes back the same way.  Standing idle, every half
second, and before a walk sets out, the soles' pitch is measured (the IMU and the legs'
joints), and soles resting otherwise than planned -- creeping down a ramp onto the bend at
its foot, on the simulator's soft contacts -- are seated as they rest (``seat_standing``,
``seat_soles``): planned from the slope's pitch, the swing foot came down in a frame turned
about the standing sole and missed the floor, and a robot standing there had its CoM
drift back over its heels, the model's frame turned about the soles with them.

On start the knees bend (the pelvis sinks ``CROUCH``) so that steps are within
reach and the pendulum's height is constant while walking.  The pilot's
``pause`` ends the walk soon with both feet down, side by side (a foot in the
air lands; if the feet are apart one closing step brings them together: the
ZMP keeps the walk's rhythm, since turning the CoM back mid-swing would throw
the robot sideways) and ``resume`` plays the rest.  While paused the module
keeps the robot standing balanced (``run_paused``: the attitude and
deflection loops, on the legs only), so the HAL frees the waist for another
module (the paper's door sequence) and a free-standing robot does not lean
onto its toes under an arm's reach.  ``stop`` first comes to rest the same way,
and so does a link to the pilot lost for 5 s (the module's link-loss policy,
:mod:`walkman.gym.link_loss`): the pilot's ``resume`` plays the rest.
When the guard trips (ZMP too close to the edge of the feet, or the torso
tilted too far) the module says so on its warning port, drops the rest of the
walk and stands.  The status carries the odometry of the steps taken (x, y in
metres, yaw in radians) and the balance figures: the measured ZMP's margin to
the support polygon's edge (m, nan with no foot on the floor) and the torso's
tilt (rad), twice a second and at every landing (not while paused: the pilot
then sees ``paused``).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from walkman.control.balance import (AnkleCompliance, AttitudeLoop, BalanceGuard, Sole,
                                     combined_zmp, foot_zmp, rotation_rpy, support_margin,
                                     to_local)
from walkman.control.foothold import STRIKE_ABOVE, DescentCheck, FootholdCheck
from walkman.control.footsteps import SIDES, Planar, Step, WalkPlan, compose, inverse
from walkman.control.lipm import PreviewAxis, preview_gains
from walkman.control.trajectory import quintic
from walkman.gym.link_loss import LinkLoss
from walkman.model.description import home_posture
from walkman.modules.task import TaskModule, task_statuses

log = logging.getLogger(__name__)

LEGS = {"left": ["LHipLat", "LHipYaw", "LHipSag", "LKneeSag", "LAnkSag", "LAnkLat"],
        "right": ["RHipLat", "RHipYaw", "RHipSag", "RKneeSag", "RAnkSag", "RAnkLat"]}
WAIST = ["WaistLat", "WaistSag", "WaistYaw"]
FRAMES = {"left": "l_foot", "right": "r_foot"}
SENSORS = {"left": "l_leg_ft", "right": "r_leg_ft"}
SOLE = np.array([0.03, 0.0, -0.10])   # the middle of the sole, in the foot frame
CROUCH = 0.08                          # m the pelvis sinks at start: knees bent, steps reachable
CROUCH_TIME = 1.5                      # s
TICK_IK_ITERATIONS = 20
#: rad: the least knee bend a leg's IK starts from each tick (see Module.unlocked)
KNEE_UNLOCK = 0.1
SETTLED_SPEED = 0.01                   # m/s: the CoM is at rest below this
REPORT_PERIOD = 0.5                    # s between balance reports on the status port
GAPS_KEPT = 300                        # ticks whose gaps a balance guard trip logs (3 s at 100 Hz)
DEFLECTION_SHARE = 0.8                 # of the legs' measured spring deflection made up for
#: s: standing still (:meth:`Module.standing_still`) this long, the ankles' pitch deflection
#: compensation follows the F/T-measured load within ANKLE_FOLLOW s, not 0.05 s
#: (:meth:`Module.commanded`).  Slowed (or held) at once, the ankles lagged the head bending
#: down after the start: the camera's cloud, taken 0.5 s into standing still, made the
#: ramp's foot a 10-cm surface and the camera's footsteps onto the ramp were refused
ANKLE_SETTLE = 1.0
ANKLE_FOLLOW = 0.5
ANKLE_AIM = (0.08, 0.04)               # m: the most a foot's desired CoP is off its sole's centre
#: s the ankles stay compliant after a walk's last motion; standing, they are stiff: a
#: stiff ankle is what holds the robot against a push (compliant, it gives way)
ANKLE_AFTER = 1.0
#: rad: a standing sole resting further than this off the pitch the plan gives it is seated
#: as it rests before a walk sets out (:meth:`Module.seat_soles`).  Soles that crept 4.5 cm
#: across the bend at a ramp's foot rest 2.3 degrees flatter than its slope; on the slope
#: itself, and on plane ground, they rest within 0.4 degrees of the plan
SEAT_MIN = 0.02
#: rad/s the soles turn onto their seats at (:meth:`Module.seat_soles`), the pelvis going over
#: the feet with them.  Soles that crept onto the bend at a ramp's foot for 15 s turn 2.3
#: degrees (the pelvis 4 cm); the smallest ZMP margin of the step to the floor after it was
#: 1.7 cm at 1 deg/s, 2.1 at 0.65, 2.2 at 0.5.  After 30 s (4.8 degrees, the feet's centre
#: of pressure 3 cm from their heels before the turn) the robot rocked on its heels and the
#: guard tripped at 1.45 and 0.92 deg/s; at 0.66 and 0.5 it walked (0.6 and 0.8 cm)
SEAT_RATE = math.radians(0.5)
#: s between a standing robot's looks at how its soles rest (:meth:`Module.seat_standing`):
#: they creep onto a ramp's bend at 0.15-0.2 degrees a second
SEAT_CHECK = 0.5

TABLE = {
    "idle": {"go_straight": "walking", "turn": "turning", "step_side": "side_stepping",
             "step_up": "stepping_up", "step_down": "stepping_down",
             "footsteps": "walking"},
    "walking": {"action_done": "idle"},
    "turning": {"action_done": "idle"},
    "side_stepping": {"action_done": "idle"},
    "stepping_up": {"action_done": "idle"},
    "stepping_down": {"action_done": "idle"},
}
#: ``step_up``/``step_down``'s default reach ahead (m): the left sole's centre lands this far
#: ahead, its heel 7 cm ahead of where the toes were -- the pilot first walks the toes up to
#: the kerb (within 4 cm: the heel then lands 3 cm past it).
STEP_FORWARD = 0.33
#: rad: the most a footstep's sole may roll (the plan pitches soles, never rolls them)
MAX_SOLE_ROLL = 0.05


Pose = Tuple[float, float, float, float, float, float]   # x y z roll pitch yaw


def sole_poses(kinematics, q: np.ndarray) -> Dict[str, Pose]:
    """Each sole's centre as a pose ``(x, y, z, roll, pitch, yaw)`` in the pelvis frame at
    posture ``q``: where the feet are for footsteps (this module, and the PI placing a first
    footstep)."""
    out = {}
    for side, frame in FRAMES.items():
        position, r = kinematics.pose(q, frame)
        x, y, z = position + r @ SOLE
        out[side] = (float(x), float(y), float(z), math.atan2(r[2, 1], r[2, 2]),
                     -math.asin(max(-1.0, min(1.0, r[2, 0]))), math.atan2(r[1, 0], r[0, 0]))
    return out


def sole_ahead(sole: Sequence[float], distance: float, rise: float = 0.0,
               pitch: Optional[float] = None) -> Pose:
    """A footstep ``distance`` m along the heading of ``sole`` (a pose, pelvis frame), ``rise``
    m higher, pitched ``pitch`` (the sole's own if None), level across."""
    x, y, z, _, own_pitch, yaw = (float(v) for v in sole[:6])
    return (x + distance * math.cos(yaw), y + distance * math.sin(yaw), z + rise, 0.0,
            own_pitch if pitch is None else pitch, yaw)


class Module(TaskModule):
    statuses = task_statuses(TABLE)
    table = TABLE
    arguments = {"go_straight": (1, 1, "DISTANCE m"), "turn": (1, 1, "ANGLE rad"),
                 "step_side": (1, 1, "DISTANCE m, left positive"),
                 "step_up": (1, 2, f"HEIGHT m [FORWARD m, default {STEP_FORWARD}]"),
                 "step_down": (1, 2, f"HEIGHT m [FORWARD m, default {STEP_FORWARD}]"),
                 "footsteps": (6, 60, "X Y Z ROLL PITCH YAW of each sole's centre, "
                                      "pelvis frame, m and rad")}
    # Rotating on the spot nearly toppled Walk-Man at the DRC: every step counts down.
    dangerous = frozenset({"go_straight", "turn", "step_side", "step_up", "step_down",
                           "footsteps"})
    # Walking blind is the riskiest thing the robot can do, and standing paused the safest:
    # both feet down, balanced by run_paused.  A dropout under 5 s does not interrupt a walk;
    # a longer blackout (the DRC Finals' lasted up to 30 s) ends it within a step, and the
    # pilot's resume plays the rest once they can see again.
    link_loss = LinkLoss.pause(after=5.0)
    joints = LEGS["left"] + LEGS["right"] + WAIST

    @classmethod
    def describe_status(cls, state: str, values: Sequence[float]) -> str:
        """The odometry and the balance figures (:meth:`status_data`) as a pilot reads them."""
        if len(values) != 5:
            return super().describe_status(state, values)
        x, y, yaw, margin, tilt = values
        balance = "no foot on the floor" if math.isnan(margin) else \
            f"ZMP {margin * 100:.1f} cm inside the feet"
        return (f"walked {x:.2f} m ahead, {y:.2f} m left, turned {math.degrees(yaw):.0f}\u00b0; "
                f"{balance}, torso {math.degrees(tilt):.1f}\u00b0 off vertical")

    def setup(self) -> None:
        q = self.robot.sense_position()
        soles = {side: self.sole(q, side) for side in SIDES}
        middle = (soles["left"] + soles["right"]) / 2
        # The walk frame: on the floor between the soles, x along the pelvis's heading.
        self.plan = WalkPlan({side: (float(soles[side][0] - middle[0]),
                                     float(soles[side][1] - middle[1]), 0.0)
                              for side in SIDES})
        standing = float(-middle[2])          # pelvis above the soles
        # CROUCH below the home posture's height, whatever the start (a module stopped and
        # started again finds the knees already bent)
        home = home_posture(self.kinematics.robot)
        home_q = np.array([home[name] for name in self.robot.joint_names])
        crouched = -float((self.sole(home_q, "left") + self.sole(home_q, "right"))[2]) / 2 - CROUCH
        self.height = (standing, crouched, self.now())
        self.pelvis_xy = -middle[:2]
        self.leg_index = {side: self.ik.joints_of(joints) for side, joints in LEGS.items()}
        self.knee_index = {side: int(self.ik.joints_of([joints[3]])[0])
                           for side, joints in LEGS.items()}
        waist = [self.robot.index[name] for name in WAIST]
        self.reference[waist] = 0.0  # upright
        com = self.kinematics.com(self.reference)
        gains = preview_gains(crouched + float(com[2]))
        start = self.pelvis_xy + com[:2]
        self.plan.settle(start, self.now(), self.now() + CROUCH_TIME)
        self.axes = [PreviewAxis(gains, float(start[axis]), self.now()) for axis in (0, 1)]
        self.attitude = AttitudeLoop()
        self.guard = BalanceGuard()
        self.ankles = {side: AnkleCompliance() for side in SIDES}
        self.sole_shape = Sole()
        self.halted_for_pause = False
        #: the soles being seated (:meth:`seat_soles`): since, until, by how much the
        #: commanded pelvis tilt turns, and the share of it turned so far
        self.seating: Optional[Tuple[float, float, float, float]] = None
        self.last_seat_check = self.now()    # (:meth:`seat_standing`)
        self.foothold: Optional[FootholdCheck] = None   # a sole landing heel first
        self.foothold_step: Optional[Step] = None    # and its step
        self.descent: Optional[DescentCheck] = None  # a sole stepping down
        self.descent_step: Optional[Step] = None     # and its step
        self.legs = np.concatenate(list(self.leg_index.values()))
        self.stiffness = np.array([self.kinematics.robot.joint(self.robot.joint_names[i]).stiffness
                                   for i in self.legs])
        self.deflection = np.zeros(len(self.legs))
        #: the ankles' pitch among the legs' joints: followed slowly standing still (ANKLE_FOLLOW)
        self.ankle_pitch = np.isin(self.legs, [self.robot.index[LEGS[side][4]]
                                               for side in SIDES])
        self.posture = q.copy()   # for the CoM: the legs as commanded, the rest as measured
        self.margin: Optional[float] = None
        #: the ZMP (None: no foot loaded) and the soles' planar poses, the last tick's
        self.support: Tuple[Optional[np.ndarray], Dict[str, Planar]] = (None, {})
        self.wrenches: Dict[str, np.ndarray] = {}
        self.com_velocity = np.zeros(2)
        self.roll_pitch = (0.0, 0.0)
        self.still = False      # standing still this tick (:meth:`standing_still`)
        self.still_since = self.now()      # and since
        self.last_tick = self.last_report = self.now()
        #: (time, seconds since the tick before) of the last ticks: a guard trip's log says
        #: whether the loop itself was late (a stalled loop topples the robot).
        self.tick_gaps: deque = deque(maxlen=GAPS_KEPT)

    def sole(self, q: np.ndarray, side: str) -> np.ndarray:
        return self.kinematics.point(q, FRAMES[side], SOLE)

    def status_data(self) -> List[float]:
        """Odometry (x, y m, yaw rad) and balance: the ZMP's margin (m; nan with no foot
        on the floor) and the torso's tilt (rad)."""
        margin = math.nan if self.margin is None else self.margin
        return [round(float(v), 3) for v in (*self.plan.travelled, margin, self.guard.tilt)]

    # -- commands ----------------------------------------------------------------------

    def _walk_start(self) -> float:
        """Asked while the knees still bend, a walk starts when they are done; on soles that
        rest otherwise than planned, once they are seated (:meth:`seat_soles`; also when
        they are being seated standing, :meth:`seat_standing`)."""
        now = self.now()
        crouched = self.height[2] + CROUCH_TIME
        if now < crouched:
            return crouched
        start = self.seat_soles(now)
        return start if self.seating is None else max(start, self.seating[1])

    def seat_standing(self, now: float, paused: bool) -> None:
        """Standing idle, the soles are looked at every :data:`SEAT_CHECK` and seated as they
        rest as soon as they are :data:`SEAT_MIN` off the plan (:meth:`seat_soles`), not only
        when a walk sets out.

        Why: a sole resting flatter than planned turns the whole robot back about it
        under a pelvis the attitude loop holds level, and the CoM with it -- the model puts
        it over the plan's soles, the world has it behind them by the CoM's height times the
        difference.  On the bend at the ramp's foot (soles creeping 0.15-0.2 degrees a second
        flatter) that was the CoM 3.7 cm behind the soles' centres after 15 s standing, 6.5 cm
        after 25 s, their centres of pressure 9 cm behind (margin 4.1 cm; in the PI, a lagging
        100-Hz loop, the guard tripped standing, both soles on their heels); and seating
        3.9 degrees at once when the walk was asked rocked the robot onto its heels (-0.5 cm).
        Seated as they creep, 1.1 degrees at a time, the CoM stays within 2 cm of the
        soles' centres.  Not while paused: another module's hand then works in a pelvis frame
        held still in the world."""
        if not self.standing_still(now, paused) or self.seating is not None or \
                now - self.last_seat_check < SEAT_CHECK:
            return
        self.last_seat_check = now
        self.seat_soles(now, "standing")

    def standing_still(self, now: float, paused: bool) -> bool:
        """Idle, not paused, the walk's last motion :data:`ANKLE_AFTER` past and the CoM at
        rest: the soles are looked at (:meth:`seat_standing`), and the attitude loop levels
        the pelvis by its integral alone.

        Why the integral alone: standing on the bend at the ramp's foot (each sole bridging
        it, heel on the slope, toes on the floor) with 15-ms ticks, the loop's proportional
        term fed the robot's own sway back: it rocked fore and aft, 0.7 s a swing, the feet's
        centre of pressure from 13 cm behind their centres to 12 cm ahead within 20 s, and
        the guard tripped -- as the PI's runs did, standing (its 100-Hz loop lags).  Without
        it (or at half) the centre of pressure stayed within 5 cm behind; with 10- and 12-ms
        ticks, and on the slope or level ground at 15 ms, the robot stood still either way.
        A walk, a pause (another module's arms moving the CoM) or a push has it back."""
        return not paused and self.fsm.state == "idle" and not self.plan.walking and \
            not self.plan.halted and \
            now >= max(self.plan.end_time(), self.height[2] + CROUCH_TIME) + ANKLE_AFTER and \
            float(np.linalg.norm(self.com_velocity)) < SETTLED_SPEED

    def seat_soles(self, now: float, when: str = "before the walk") -> float:
        """Plan from the soles as they rest (their measured pitch: before a walk, and
        standing) if one is more than :data:`SEAT_MIN` off the plan's; returns when the walk
        may start.

        A sole that rests otherwise than planned -- crept down a ramp onto the bend at its
        foot, toes on the floor and heel on the slope -- holds the legs' frame turned
        under the pelvis, and the attitude loop tilts the commanded pelvis as much to keep
        it level (2.7 degrees, after 15 s standing on the ramp's foot).  The plan's swing
        foot then comes down in a frame turned by that tilt about the standing sole, and
        more as the loop winds on under one leg (7 degrees at the landing: the foot 4 cm
        higher over the standing one than planned, the leg straight, the floor out of its
        reach).  Seated, the soles' planned pitch turns to the measured one at
        :data:`SEAT_RATE` and the commanded tilt with it (:meth:`AttitudeLoop.turn`): the
        legs keep their pitch, and the pelvis, level, goes over the feet as the plan has it."""
        if self.plan.walking:
            return now          # (the plan refuses a second walk)
        pitches = {side: self.sole_pitch(side) for side in SIDES}
        turns = {side: pitches[side] - self.plan.foot_pitch(side, now) for side in SIDES}
        largest = max(abs(turn) for turn in turns.values())
        if largest <= SEAT_MIN:
            return now
        until = now + largest / SEAT_RATE
        log.info("%s: the soles rest pitched %s degrees off the plan: seated in %.1f s %s",
                 self.name,
                 ", ".join(f"{side} {math.degrees(turns[side]):+.1f}" for side in SIDES),
                 until - now, when)
        self.plan.seat(pitches, now, until)
        self.seating = (now, until, sum(turns.values()) / len(SIDES), 0.0)
        return until

    def sole_pitch(self, side: str) -> float:
        """The pitch (rad) a standing sole rests at: the legs as they are (the joints' state,
        their springs' give in it) under the pelvis as the IMU has it.  Read once, the robot
        standing: the lag of the joints' state stream does not matter."""
        _, rotation = self.kinematics.pose(self.robot.sense_position(), FRAMES[side])
        turned = rotation_rpy(*self.roll_pitch, 0.0) @ rotation
        return -math.asin(max(-1.0, min(1.0, float(turned[2, 0]))))

    def _walk(self, dx: float, dy: float, dyaw: float) -> None:
        self.plan.plan(dx, dy, dyaw, self._walk_start())

    def _start_go_straight(self, distance: float) -> None:
        if not 0.01 <= abs(distance) <= 5.0:
            raise ValueError(f"go_straight takes 0.01..5 m (negative: backwards), got {distance}")
        self._walk(distance, 0.0, 0.0)

    def _start_turn(self, angle: float) -> None:
        if not 0.01 <= abs(angle) <= math.pi:
            raise ValueError(f"turn takes 0.01..pi rad (positive: left), got {angle}")
        self._walk(0.0, 0.0, angle)

    def _start_step_side(self, distance: float) -> None:
        if not 0.01 <= abs(distance) <= 1.0:
            raise ValueError(f"step_side takes 0.01..1 m (positive: left), got {distance}")
        self._walk(0.0, distance, 0.0)

    def _start_step_up(self, height: float, forward: float = STEP_FORWARD) -> None:
        if not 0.0 < height:
            raise ValueError(f"step_up takes a height above 0 m (step_down goes down), "
                             f"got {height}")
        self._step(forward, height)

    def _start_step_down(self, height: float, forward: float = STEP_FORWARD) -> None:
        if not 0.0 < height:
            raise ValueError(f"step_down takes a height above 0 m, got {height}")
        self._step(forward, -height)

    def _step(self, forward: float, height: float) -> None:
        if not 0.05 <= forward:
            raise ValueError(f"a step up or down goes at least 0.05 m forward, got {forward}")
        self.plan.step_to(forward, height, self._walk_start())

    def _start_footsteps(self, *values: float) -> None:
        if len(values) % 6:
            raise ValueError(f"footsteps are X Y Z ROLL PITCH YAW each: {len(values)} numbers "
                             f"is not a multiple of 6")
        pelvis, height = self.pelvis_in_walk_frame()
        footsteps = []
        for index in range(0, len(values), 6):
            x, y, z, roll, pitch, yaw = values[index:index + 6]
            if abs(roll) > MAX_SOLE_ROLL:
                raise ValueError(f"footstep {index // 6 + 1}: a sole lands level across "
                                 f"(roll within {MAX_SOLE_ROLL} rad), got roll {roll}")
            # the pelvis stands upright: a pitch in its frame is the ground's
            footsteps.append((*compose(pelvis, (x, y, yaw)), height + z, pitch))
        self.plan.place(footsteps, self._walk_start())

    def pelvis_in_walk_frame(self) -> Tuple[Planar, float]:
        """The pelvis's planar pose and height in the walk frame, from where the soles are in
        each (the legs as commanded, the pelvis taken upright): where a pilot or perception
        measures footsteps from.  From the posture, not the walk's own state, so the
        preview's shadow (walkman.gym.preview), given the measured posture, agrees."""
        soles = sole_poses(self.kinematics, self.reference)
        (lx, ly, lz, _, _, lyaw), (rx, ry, rz, _, _, ryaw) = soles["left"], soles["right"]
        yaw = lyaw + math.atan2(math.sin(ryaw - lyaw), math.cos(ryaw - lyaw)) / 2
        pelvis = compose(self.plan.centre, inverse(((lx + rx) / 2, (ly + ry) / 2, yaw)))
        return pelvis, sum(self.plan.heights.values()) / len(SIDES) - (lz + rz) / 2

    def forget_motions(self) -> None:
        super().forget_motions()
        self.plan.steps, self.plan.set_aside = [], []
        self.foothold = self.foothold_step = None
        self.descent = self.descent_step = None

    # -- every tick ----------------------------------------------------------------------

    def com_reference(self, now: float) -> Tuple[np.ndarray, np.ndarray]:
        """Where the preview controller puts the CoM now: position and velocity (walk frame)."""
        for axis, zmp in zip(self.axes, (lambda t: self.plan.zmp(t)[0],
                                         lambda t: self.plan.zmp(t)[1])):
            axis.advance(now, zmp)
        samples = [axis.sample(now) for axis in self.axes]
        return np.array([s[0] for s in samples]), np.array([s[1] for s in samples])

    def sense_balance(self) -> float:
        """The torso's tilt; the measured ZMP's margin to the support polygon
        (:attr:`margin`), both in the *level frame* (the pelvis frame turned by the IMU's
        roll and pitch: z up).  Only the fast sensors count (F/T, IMU: 100 Hz, a few ports):
        the joints' state streams on a port per chain at 500 Hz and, on a loaded machine,
        reaches a module late (100 ms of lag there and the robot falls), so the feet are
        placed where the legs are commanded -- the deflection compensation puts them
        there."""
        self.sensed = self.robot.sense_position()     # for the slow joints (arms) only
        wrenches = {side: self.robot.sense_ft(SENSORS[side]) for side in SIDES}
        imu = self.robot.sense_imu()
        roll, pitch = (float(imu[0][0]), float(imu[0][1])) if imu else (0.0, 0.0)
        self.roll_pitch = (roll, pitch)
        tilt = math.hypot(roll, pitch)
        self.margin = None
        self.support = (None, {})
        self.wrenches = {side: w for side, w in wrenches.items() if len(w) >= 6}
        if len(self.wrenches) < len(SIDES):
            return tilt
        level = rotation_rpy(roll, pitch, 0.0)
        soles: Dict[str, Planar] = {}
        for side in SIDES:
            position, rotation = self.kinematics.pose(self.reference, FRAMES[side])
            point, turned = level @ (position + rotation @ SOLE), level @ rotation
            soles[side] = (float(point[0]), float(point[1]),
                           math.atan2(turned[1, 0], turned[0, 0]))
        zmp, contacts = combined_zmp({side: (soles[side], wrenches[side]) for side in SIDES},
                                     self.sole_shape)
        if zmp is not None:
            self.margin = support_margin(zmp, soles, contacts, self.sole_shape)
        self.support = (zmp, soles)
        return tilt

    def support_text(self) -> str:
        """Each foot's load and centre of pressure, and the ZMP, in its own sole's frame (cm,
        x toward the toes, y to the left): which edge a balance trip was at."""
        zmp, soles = self.support
        parts = []
        for side in SIDES:
            wrench = self.wrenches.get(side)
            local = None if wrench is None else foot_zmp(wrench, self.sole_shape)
            load = "no reading" if wrench is None else "no contact" if local is None else \
                f"{local[2]:.0f} N, CoP {local[0] * 100:+.1f} {local[1] * 100:+.1f}"
            where = "" if zmp is None else \
                "; ZMP {:+.1f} {:+.1f}".format(*(to_local(soles[side], zmp) * 100))
            parts.append(f"{side}: {load}{where}")
        return "; ".join(parts) + " (cm in each sole's frame)"

    def track(self, paused: bool = False) -> None:
        """One tick of the walk (``paused``: standing for another module, see run_paused)."""
        now = self.now()
        dt = min(max(now - self.last_tick, 0.0), 0.05)
        self.tick_gaps.append((now, now - self.last_tick))
        self.last_tick = now
        plan = self.plan
        if self.pause_requested and not self.halted_for_pause and self.foothold is None:
            plan.halt(now)          # (after a landing's verdict: it may put the foot back)
            self.halted_for_pause = True
        landed = plan.update(now)
        flying = plan.in_air(now)
        if flying is not None and flying.checked_on_landing and plan.timing.foothold_wait and \
                flying is not self.foothold_step:     # it will land heel first
            self.foothold = FootholdCheck(flying.side, flying.land_at, self.sole_shape)
            self.foothold_step = flying
        if (landed or now - self.last_report >= REPORT_PERIOD) and not paused:
            self.report()  # odometry once per step, balance twice a second
            self.last_report = now
        com_ref, velocity = self.com_reference(now)
        self.com_velocity = velocity
        if not plan.walking and not plan.halted and self.fsm.state != "idle" and \
                now >= plan.end_time() and float(np.linalg.norm(velocity)) < SETTLED_SPEED:
            self.event("action_done")
        feet = {side: plan.foot(side, now) for side in SIDES}
        planar = {side: feet[side][0] for side in SIDES}
        yaw = (planar["left"][2] + planar["right"][2]) / 2
        tilt = self.sense_balance()
        self.check_foothold(now)
        self.check_descent(now, flying, feet)
        self.seat_standing(now, paused)
        self.turn_with_seats(now)
        still = self.standing_still(now, paused)
        if still and not self.still:
            self.still_since = now
        self.still = still
        roll, pitch = self.attitude.update(dt, *self.roll_pitch, proportional=not self.still)
        self.guard_check(now, tilt)
        start, end, t0 = self.height
        pelvis_z = start + (end - start) * quintic((now - t0) / CROUCH_TIME) + \
            plan.ground_level(now)   # up and down steps with the feet
        rotation = rotation_rpy(roll, pitch, yaw)
        # The CoM of the posture as it is: the legs as commanded, the rest as measured --
        # but held while paused: another module's hand then works in a pelvis frame that
        # stays put in the world (a door handle in its grip), the legs' springs and the
        # pelvis attitude taking the load.
        if not paused:
            self.posture = self.sensed.copy()
        self.posture[self.legs] = self.reference[self.legs]
        offset = rotation @ self.kinematics.com(self.posture)
        self.pelvis_xy = com_ref - offset[:2]
        pelvis = np.array([self.pelvis_xy[0], self.pelvis_xy[1], pelvis_z])
        tilts = self.comply(dt, now, planar, paused)
        for side, index in self.leg_index.items():
            (x, y, foot_yaw), height = feet[side]
            ground_pitch = plan.foot_pitch(side, now)      # a ramp's, 0 on level ground
            if self.foothold is not None and self.foothold.side == side:   # landing heel first
                forward, up = self.foothold.shift(now, ground_pitch)
                x, y = x + forward * math.cos(foot_yaw), y + forward * math.sin(foot_yaw)
                height += up
                ground_pitch += self.foothold.tilt(now)
            target = rotation.T @ (np.array([x, y, height]) - pelvis)
            foot_roll, foot_pitch = tilts[side]
            result = self.ik.solve(FRAMES[side], target,
                                   rotation.T @ rotation_rpy(foot_roll, foot_pitch + ground_pitch,
                                                             foot_yaw),
                                   self.unlocked(side), LEGS[side], offset=SOLE, restarts=0,
                                   max_iterations=TICK_IK_ITERATIONS)
            self.reference[index] = result.q[index]

    def turn_with_seats(self, now: float) -> None:
        """While the soles turn onto their seats, the commanded pelvis tilt turns as they do
        (the plan's quintic), so that the legs keep their pitch."""
        if self.seating is None:
            return
        since, until, turn, turned = self.seating
        share = quintic((now - since) / (until - since))
        self.attitude.turn(turn * (share - turned))
        self.seating = None if share >= 1.0 else (since, until, turn, share)

    def unlocked(self, side: str) -> np.ndarray:
        """The IK's seed for a leg: the reference, its knee bent by at least
        :data:`KNEE_UNLOCK`.  A straight knee is a singularity the descent cannot leave: bending
        it moves the foot across the leg, not along it, so a foot target that comes closer
        to the hip is met by the hip and ankle and the knee stays pinned at its limit (tried: a
        step down that struck the kerb it left, the foot held on it, then swung back -- the
        knee straight for 0.9 s, the sole dragged over the kerb until the solution jumped to
        a bent knee, 0.9 rad in one tick, and the robot fell).  A target that needs the knee
        straight straightens it again within the tick's iterations."""
        seed = self.reference
        knee = self.knee_index[side]
        if seed[knee] < KNEE_UNLOCK:
            seed = seed.copy()
            seed[knee] = KNEE_UNLOCK
        return seed

    def check_foothold(self, now: float) -> None:
        """Sample the sole landing heel first; at the verdict, if the heel does not bear,
        say so and put the foot back where it lifted from (the rest of the walk dropped)."""
        check = self.foothold
        if check is None:
            return
        wrench = self.wrenches.get(check.side)
        check.sample(now, None if wrench is None else foot_zmp(wrench, self.sole_shape))
        problem = check.decide(now)
        if problem is not None:
            touched = check.touched_after
            log.info("%s: foothold: the %s sole %s; %s", self.name, check.side,
                     "never touched" if touched is None else
                     f"touched {touched:+.3f} s from its landing",
                     problem or "its heel bears")
        if check.bears is False and self.plan.swinging(now) == check.side:
            check.release(now)      # put back: it turns flat in the air
        if check.done(now):
            self.foothold = None
        if problem:
            self.warn(f"foothold: {problem}; putting the foot back where it was, the rest "
                      f"of the walk dropped (walk closer and step again)")
            self.plan.retreat(self.foothold_step, now)

    def check_descent(self, now: float, flying: Optional[Step],
                      feet: Dict[str, Tuple[Planar, float]]) -> None:
        """Watch a sole stepping down: if it meets ground well above where it was going
        (the kerb it leaves), say so; it stays there and goes back where it lifted from
        (the rest of the walk dropped).  A foot already going back is not watched
        (:attr:`Step.returning`)."""
        if flying is None or flying.returning or \
                flying.land_z > flying.start_z - STRIKE_ABOVE:
            self.descent = self.descent_step = None
            return
        if self.descent_step is not flying:
            self.descent = DescentCheck(flying.side, flying.start_z - flying.land_z,
                                        flying.land_at)
            self.descent_step = flying
        assert self.descent is not None
        _, height = feet[flying.side]          # the plan's, this tick
        wrench = self.wrenches.get(flying.side)
        problem = self.descent.sample(now, height - flying.land_z,
                                      None if wrench is None else foot_zmp(wrench,
                                                                           self.sole_shape))
        if problem:
            self.warn(f"foothold: {problem}; putting the foot back where it was, the rest of "
                      f"the walk dropped (walk to the edge and step again)")
            self.plan.strike(flying, now)
            self.descent = self.descent_step = None

    def comply(self, dt: float, now: float, planar: Dict[str, Planar],
               paused: bool = False) -> Dict[str, np.ndarray]:
        """Each foot's compliance tilt: its measured CoP driven to the desired one, the
        planned ZMP on the foot that stands alone, the sole's centre in double support.
        Also while paused: another module's arms and waist then move the CoM, which the
        held pelvis does not follow (see :meth:`track`); the ankles keep it over the feet."""
        swinging = self.plan.swinging(now)
        zmp = [float(v[0]) for v in self.plan.zmp(np.array([now]))]
        # (stiff while the soles turn onto their seats: the robot stands, and a compliant
        # ankle turning a sole that rests on its heel against the bend tipped it back)
        stepping = (self.plan.walking or now < self.plan.end_time() + ANKLE_AFTER) and \
            self.seating is None or paused
        tilts = {}
        for side in SIDES:
            wrench = self.wrenches.get(side)
            landing = self.foothold is not None and self.foothold.side == side
            measured = foot_zmp(wrench, self.sole_shape) if stepping and wrench is not None \
                and side != swinging and not landing else None
            desired = (0.0, 0.0)
            if swinging is not None and side != swinging:
                local = to_local(planar[side], zmp)
                desired = (float(np.clip(local[0], -ANKLE_AIM[0], ANKLE_AIM[0])),
                           float(np.clip(local[1], -ANKLE_AIM[1], ANKLE_AIM[1])))
            tilts[side] = self.ankles[side].update(
                dt, None if measured is None else measured[:2], desired)
        return tilts

    def commanded(self) -> np.ndarray:
        """The reference plus the legs' expected spring deflection (a share of the joint
        torques over the stiffness, filtered): the stance hip carries 150 N*m in single
        support, which bends its series-elastic spring by 0.05 rad -- 5 cm of CoM.  The
        torques are the ankle F/T wrenches through the legs' Jacobians plus the legs'
        weight, at the commanded posture: fresh where the joints' torque stream is not.

        Standing still (:meth:`standing_still`, :data:`ANKLE_SETTLE` s on), the ankles' pitch
        deflection follows the load within :data:`ANKLE_FOLLOW` s, the hips' and knees'
        within 0.05 s as walking.  Why: made up for, an ankle's pitch chases its own wrench
        -- the centre of pressure moves, the ankle's torque with it, the command turns the
        ankle further, the centre of pressure moves on: positive feedback, 80 % a turn.  With
        the wrenches a tick late (10 ms: the PI's, over YARP), a robot standing on the bend
        at the ramp's foot rocked fore and aft on it, the soles' centres of pressure from
        14 cm behind their centres to 14 cm ahead within 7.5 s, and the guard tripped on
        both heels (offline, -0.5 cm; the PI's run, 0.0 cm).  Followed slowly, the loop's
        gain at that swing is a third, the share made up for in the end the same, and the
        robot stands: smallest margin 7.2 cm in 20 s, 7.3 with 10-15-ms ticks and the
        sensors 20 ms late.  Held outright, the camera course's
        start saw the ramp wrong (:data:`ANKLE_SETTLE`); all the legs' joints followed
        within 0.1-0.3 s made the robot on the 5-cm kerb sway 1-2 mm a second, at 0.15 s
        ever wider."""
        tau = self.kinematics.gravity(self.reference)
        for side, wrench in self.wrenches.items():
            tau += self.kinematics.wrench_torques(self.reference, f"{SENSORS[side]}_frame",
                                                  wrench)
        follow = np.full(len(self.legs), min(1.0, self.thread_period / 0.05))
        if self.still and self.now() - self.still_since >= ANKLE_SETTLE:
            follow[self.ankle_pitch] = min(1.0, self.thread_period / ANKLE_FOLLOW)
        self.deflection += follow * (tau[self.legs] / self.stiffness - self.deflection)
        out = self.reference.copy()
        ramp = min(1.0, max(0.0, (self.now() - self.height[2]) / CROUCH_TIME))
        out[self.legs] += ramp * DEFLECTION_SHARE * self.deflection
        return out

    def guard_check(self, now: float, tilt: float) -> None:
        problem = self.guard.update(now, self.margin, tilt)
        if problem is not None:
            when, gap = max(self.tick_gaps, key=lambda tick: tick[1], default=(now, 0.0))
            log.warning("%s: balance guard: %s; the loop's longest tick in the last %.1f s: "
                        "%.0f ms, %.2f s ago; %s", self.name, problem,
                        now - self.tick_gaps[0][0] if self.tick_gaps else 0.0, gap * 1000,
                        now - when, self.support_text())
            if self.plan.walking:
                self.warn(f"balance: {problem}; stopping the walk and standing")
                self.plan.cancel(now)
            else:
                self.warn(f"balance: {problem}")

    def ready_to_pause(self) -> bool:
        return not self.plan.walking and self.now() >= self.plan.end_time() and \
            float(np.linalg.norm(self.com_velocity)) < SETTLED_SPEED

    def run_paused(self) -> None:
        """Paused, the robot stands balanced: the balance loops go on, on the legs only
        (the waist is free for another module: the paper's door sequence)."""
        self.track(paused=True)
        self.robot.move(self.commanded(), joints=LEGS["left"] + LEGS["right"])

    def held_posture(self) -> np.ndarray:
        """Stopped, the robot holds the legs as commanded, springs made up for (the posture
        the joints read would let it sag by the deflection)."""
        return self.commanded()

    def custom_pause(self) -> bool:
        return True  # both feet are down, the CoM at rest: keep the reference as it is

    def custom_resume(self) -> bool:
        self.plan.resume(self.now())   # raises while a step is still in the air
        self.halted_for_pause = False
        return True
