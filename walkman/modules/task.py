"""What every DRC manipulation module shares: FSM-driven motions tracked by IK.

Theory of operation
-------------------
A task module is the paper's hybrid controller (section 2.5): a table-driven
state machine (:mod:`walkman.control.fsm`) whose transitions start motions,
and a control loop that tracks the current motion every tick.

* A pilot command is checked in this order, and a refusal changes nothing:
  is it one of the module's commands, does the current state accept it, are
  its arguments the right count of finite numbers (a pose command --
  ``...datasent`` -- may name the frame it is given in first, e.g.
  ``valvedatasent Waist 0.6 ...``; it is moved to the pelvis frame at the
  robot's current posture, and a frame the model lacks is refused), does ``_start_<command>``
  accept them (it raises ``ValueError`` saying why, e.g. an unreachable
  target).  Only then does the state machine move.
* A motion is a Cartesian trajectory of one end-effector point
  (:class:`CartesianTrajectory`, quintic law) solved by damped-least-squares
  IK every tick over the module's joints, or a joint-space trajectory.  It
  fires ``action_done`` when it has ended and the sensed point is within
  1 cm of its goal (FACTS.md); a hand closing or opening fires ``hand_done``.
  The joints are compliant (series-elastic), so a loaded limb sags a little
  below its reference: once the trajectory has ended, the IK target creeps by
  the remaining error (an integral term) until the sensed point arrives.
  A command may chain several motions (:meth:`TaskModule.then`, e.g. press,
  hold, release): ``action_done`` fires after the last.
* The module streams its reference for all its joints every tick, so it holds
  the robot where it is between motions -- and the HAL knows which joints
  are this module's (see :mod:`walkman.hal.arbitration`).
* Pause holds the sensed posture; resume finishes a straight motion from
  where the robot is.

Subclasses give the table, the command arguments, the joints, and a
``_start_<command>`` method per pilot command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
import pinocchio as pin

from walkman.control.fsm import StateMachine
from walkman.control.ik import InverseKinematics
from walkman.control.trajectory import CartesianTrajectory, JointTrajectory, duration_for
from walkman.gym.thread import ControlThread

ACTION_TOLERANCE = 0.01   # m, FACTS.md: action_done under 1 cm
HAND_TOLERANCE = 0.3      # rad: a hand within this of its goal is done
TICK_IK_ITERATIONS = 20  # per control tick: the target moved a little since the last one
OVERDUE_S = 2.0           # s after a trajectory's end before saying it is stuck
SETTLE_GAIN = 0.02        # share of the remaining error added to the IK target per tick
HAND_CLOSED, HAND_OPEN = 1.2, 0.0
LEFT_ARM = ["LShSag", "LShLat", "LShYaw", "LElbj", "LForearmPlate", "LWrj1", "LWrj2"]
WAIST = ["WaistLat", "WaistSag", "WaistYaw"]
LEFT_HAND = "l_handj"
GRIP = np.array([0.0, 0.0, -0.1])  # the grip point in the hand frame (models: l_hand_grip)


@dataclass
class Effector:
    """A point the module moves: a frame of the model plus an offset in it (the grip)."""

    frame: str
    offset: np.ndarray
    joints: Sequence[str]     # the joints IK may use to move it


#: Events a task module fires itself; every other event of its table is a pilot command.
OWN_EVENTS = frozenset({"action_done", "hand_done"})


def pilot_commands(table: Mapping[str, Mapping[str, str]]) -> List[str]:
    """The pilot's commands of a state table, in the task's order: by where the state each
    leads to comes in the table (``reach`` before ``grasp`` before ``home``)."""
    order = {state: index for index, state in enumerate(table)}
    first: Dict[str, int] = {}
    for moves in table.values():
        for event, target in moves.items():
            if event not in OWN_EVENTS:
                first[event] = min(first.get(event, len(order)), order.get(target, len(order)))
    return sorted(first, key=lambda event: first[event])


def task_statuses(table: Mapping[str, Mapping[str, str]]) -> List[str]:
    """A task's status list: its states, in table order, then ``refused``."""
    return list(table) + ["refused"]


def finite_numbers(args: Sequence) -> List[float]:
    values = []
    for value in args:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value):
            raise ValueError(f"'{value}' is not a finite number")
        values.append(float(value))
    return values


#: Frame names pilots used on the original robot, and the model's link they mean.
FRAME_ALIASES = {"Waist": "pelvis", "waist": "pelvis", "base_link": "pelvis"}


class TaskModule(ControlThread):
    #: state -> {event -> next state}; events are the commands and action_done/hand_done.
    table: Mapping[str, Mapping[str, str]] = {}
    initial = "idle"
    #: every joint the module commands (and so holds while it runs).
    joints: Sequence[str] = ()
    #: Correct the compliant joints' sag while a motion runs, not only once it has ended,
    #: and keep what was learnt from one motion of the same effector to the next: for a
    #: tool held out whose whole path matters (a drill's cut), not only where it ends.
    compensate_sag = False

    @property
    def commands(self) -> List[str]:
        """The pilot's commands: every event of the table but the module's own."""
        return pilot_commands(self.table)

    # -- set-up ------------------------------------------------------------------------

    def custom_init(self) -> bool:
        self.fsm = StateMachine(self.table, self.initial, self.name)
        self.ik = InverseKinematics(self.kinematics)
        self.rest = self.robot.sense_position()
        self.reference = self.rest.copy()
        self.trajectory = CartesianTrajectory()
        self.effector: Optional[Effector] = None
        self.joint_motion: Optional[Tuple[np.ndarray, JointTrajectory]] = None
        self.full_pose = False
        self.arcing = self.contact = False
        self.goal: Optional[np.ndarray] = None
        self.goal_rotation = np.eye(3)
        self.correction = np.zeros(3)
        self.hand_goals: Dict[int, Tuple[float, float]] = {}   # joint -> (goal, tolerance)
        self.phases: List[Callable[[], None]] = []
        self.waiting_until: Optional[float] = None
        self._said_overdue = False
        self.setup()
        self.report()
        return True

    def setup(self) -> None:
        """Module-specific initialisation (after the robot is known)."""

    # -- the pilot's commands -------------------------------------------------------------

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is not None:
            self.handle(command.name, command.args)
        self.track()
        self.robot.move(self.commanded(), joints=self.joints)

    def commanded(self) -> np.ndarray:
        """What is sent to the robot: the reference (a module may add to it, e.g. to make
        up for the joints' compliance)."""
        return self.reference

    def handle(self, name: str, args: Sequence) -> None:
        if name not in self.commands:
            self.warn(f"unknown command '{name}' (commands: {', '.join(self.commands)})")
            return
        if not self.fsm.accepts(name):
            self.warning_interface.warn(self.fsm.fire(name).reason)  # refused: state stays
            return
        try:
            if name.endswith("datasent") and args and isinstance(args[0], str):
                args = self.in_pelvis_frame(str(args[0]), finite_numbers(args[1:]))
            values = finite_numbers(args)
            fewest, most, usage = self.arguments.get(name, (0, 0, ""))
            if not fewest <= len(values) <= most:
                wanted = f"{fewest}" if fewest == most else f"{fewest}..{most}"
                raise ValueError(f"takes {wanted} numbers{f' ({usage})' if usage else ''}, "
                                 f"got {len(values)}")
            getattr(self, f"_start_{name}")(*values)
        except ValueError as exc:
            self.warn(f"{name} refused: {exc}")
            return
        self.fsm.fire(name)
        self.report()

    def warn(self, text: str) -> None:
        self.warning_interface.warn(f"{self.name}: {text}")

    def in_pelvis_frame(self, frame: str, values: List[float]) -> List[float]:
        """``X Y Z ROLL PITCH YAW ...`` given in ``frame``, expressed in the pelvis frame."""
        link = FRAME_ALIASES.get(frame, frame)
        if not self.kinematics.model.existFrame(link):
            raise ValueError(f"no frame '{frame}' in the model (try pelvis, torso, head, "
                             f"multisense_frame, l_hand...)")
        if len(values) < 6:
            raise ValueError(f"a pose in frame {frame} is X Y Z ROLL PITCH YAW, got "
                             f"{len(values)} numbers")
        origin, rotation = self.kinematics.pose(self.robot.sense_position(), link)
        position = origin + rotation @ np.array(values[:3])
        orientation = pin.rpy.matrixToRpy(rotation @ pin.rpy.rpyToMatrix(*values[3:6]))
        return [*map(float, position), *map(float, orientation), *values[6:]]

    def refuse(self, reason: str, *data: float) -> None:
        """Say ``refused`` (with data) and raise: the command changes nothing."""
        self.status_interface.set_status("refused", *map(float, data))
        raise ValueError(reason)

    def report(self) -> None:
        self.status_interface.set_status(self.fsm.state, *self.status_data())

    def status_data(self) -> List[float]:
        return []

    # -- starting motions -------------------------------------------------------------------

    def pose(self, effector: Effector) -> Tuple[np.ndarray, np.ndarray]:
        """Where the effector's point is now (sensed), and the frame's rotation."""
        position, rotation = self.kinematics.pose(self.robot.sense_position(), effector.frame)
        return position + rotation @ effector.offset, rotation

    def reachable(self, effector: Effector, position: np.ndarray,
                  rotation: Optional[np.ndarray] = None, what: str = "target",
                  seed: Optional[np.ndarray] = None) -> np.ndarray:
        """The posture reaching ``position``; refuses (ValueError) with the miss distance.

        ``seed``: go on from this posture as the tracking loop does (no random restarts),
        to check a path point by point; by default any posture that reaches will do."""
        result = self.ik.solve(effector.frame, position, rotation,
                               self.robot.sense_position() if seed is None else seed,
                               effector.joints, offset=effector.offset,
                               restarts=6 if seed is None else 0, rest=self.rest)
        if not result.reached:
            self.refuse(f"the {effector.frame} cannot reach the {what} "
                        f"{np.round(position, 3).tolist()} (misses by "
                        f"{result.position_error * 100:.1f} cm)", *position)
        return result.q

    def line_to(self, effector: Effector, goal: np.ndarray, speed: float,
                rotation: Optional[np.ndarray] = None, contact: bool = False) -> None:
        """Move the effector's point straight to ``goal`` (and the frame to ``rotation``).

        ``contact``: the goal is inside something the effector pushes (a pedal),
        so the motion ends with its trajectory, wherever the push stopped.
        """
        start, start_rotation = self.pose(effector)
        goal_rotation = start_rotation if rotation is None else rotation
        distance = float(np.linalg.norm(goal - start))
        self.trajectory.set_linear((start, start_rotation), (goal, goal_rotation),
                                   duration_for(distance, speed, 1.0), self.now())
        self._begin(effector, goal, full_pose=rotation is not None)
        self.arcing, self.contact = False, contact

    def arc(self, effector: Effector, center: np.ndarray, axis: np.ndarray, angle: float,
            angular_speed: float, turn_orientation: bool = True,
            start: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> None:
        """Turn the effector about ``axis`` through ``center`` by ``angle`` (rad); with
        ``turn_orientation`` False its point goes round and its frame keeps its rotation.
        ``start``: the pose the arc starts from, if not where the effector is (the point the
        last motion aimed at, when a few millimetres of sag would shrink the circle)."""
        self.trajectory.set_circular(start or self.pose(effector), center, axis, angle,
                                     duration_for(angle, angular_speed, 1.0), self.now(),
                                     turn_orientation=turn_orientation)
        self._begin(effector, self.trajectory.goal()[0], full_pose=True)
        self.arcing, self.contact = True, False

    def _begin(self, effector: Effector, goal: np.ndarray, full_pose: bool) -> None:
        if not (self.compensate_sag and effector is self.effector):
            self.correction = np.zeros(3)
        self.effector, self.goal, self.full_pose = effector, goal, full_pose
        self.goal_rotation = self.trajectory.goal()[1]
        self.joint_motion = None
        self._said_overdue = False

    def forget_motions(self) -> None:
        """Drop every motion under way and to come: the preview's shadow
        (:mod:`walkman.gym.preview`), told where the robot is and in which state, never runs
        its motions, so none may be left over for the next command it is handed."""
        self.trajectory.reset()
        self.joint_motion, self.waiting_until = None, None
        self.hand_goals.clear()
        self.phases.clear()

    def joints_to(self, names: Sequence[str], goal: Sequence[float], speed: float,
                  minimum: float = 1.0) -> None:
        """Move ``names`` to ``goal`` (rad) in joint space, quintic in time."""
        self.trajectory.reset()
        index = np.array([self.robot.index[name] for name in names])
        now = self.robot.sense_position()[index]
        goal = np.asarray(goal, dtype=float)
        distance = float(np.max(np.abs(goal - now))) if len(index) else 0.0
        self.joint_motion = (index, JointTrajectory(now, goal, duration_for(distance, speed,
                                                                            minimum),
                                                    self.now()))

    def home(self, names: Sequence[str], speed: float = 0.5) -> None:
        """Back to the posture the module started in."""
        index = [self.robot.index[name] for name in names]
        self.joints_to(names, self.rest[index], speed)

    def then(self, *steps: Callable[[], None]) -> None:
        """Motions to start, in order, when the current one ends (before ``action_done``)."""
        self.phases.extend(steps)

    def hold_for(self, seconds: float) -> None:
        """A motion that keeps the reference for ``seconds``."""
        self.trajectory.reset()
        self.joint_motion = None
        self.waiting_until = self.now() + seconds

    def _finished(self) -> None:
        if self.phases:
            self.phases.pop(0)()
        else:
            self.event("action_done")

    def set_hand(self, hand: str, value: float, tolerance: float = HAND_TOLERANCE) -> None:
        """Close or open a hand to ``value`` (rad): ``hand_done`` once it is within
        ``tolerance`` (the soft hand stops on what it grasps, so the default is loose)."""
        self.hand_goals[self.robot.index[hand]] = (value, tolerance)

    # -- every tick ---------------------------------------------------------------------------

    def track(self) -> None:
        now = self.now()
        if self.waiting_until is not None:
            if now >= self.waiting_until:
                self.waiting_until = None
                self._finished()
        elif self.trajectory.active and self.effector is not None:
            effector = self.effector
            position, rotation = self.trajectory.at(now)
            result = self.ik.solve(effector.frame, position + self.correction,
                                   rotation if self.full_pose else None,
                                   self.reference, effector.joints, offset=effector.offset,
                                   restarts=0, rest=self.rest,
                                   max_iterations=TICK_IK_ITERATIONS)
            moved = self.ik.joints_of(effector.joints)
            self.reference[moved] = result.q[moved]
            if self.compensate_sag and not self.trajectory.done(now):
                lag = position - self.pose(effector)[0]
                self.correction = np.clip(self.correction + SETTLE_GAIN * lag, -0.05, 0.05)
            if self.trajectory.done(now) and self.contact:
                self.trajectory.reset()
                self._finished()
            elif self.trajectory.done(now):
                remaining = self.goal - self.pose(effector)[0]
                error = float(np.linalg.norm(remaining))
                self.correction = np.clip(self.correction + SETTLE_GAIN * remaining, -0.05, 0.05)
                if error < ACTION_TOLERANCE:
                    self.trajectory.reset()
                    self._finished()
                elif now - self.trajectory.t0 > self.trajectory.duration + OVERDUE_S and \
                        not self._said_overdue:
                    self._said_overdue = True
                    sensed = np.round(self.goal - remaining, 3).tolist()
                    self.warn(f"{self.fsm.state}: the {effector.frame} stays "
                              f"{error * 100:.1f} cm from its goal "
                              f"{np.round(self.goal, 3).tolist()} (at {sensed}, IK "
                              f"{result.position_error * 100:.1f} cm); still trying")
        elif self.joint_motion is not None:
            index, motion = self.joint_motion
            self.reference[index] = motion.at(now)
            if motion.done(now):
                self.joint_motion = None
                self._finished()
        for hand, (goal, tolerance) in list(self.hand_goals.items()):
            self.reference[hand] = goal
            if abs(self.robot.sense_position()[hand] - goal) < tolerance:
                del self.hand_goals[hand]
                self.event("hand_done")

    def event(self, event: str) -> None:
        self.fsm.fire(event)
        self.report()

    # -- lifecycle -------------------------------------------------------------------------------

    def custom_pause(self) -> bool:
        self.reference = self.robot.sense_position()  # hold where we are
        return True

    def custom_resume(self) -> bool:
        if self.trajectory.active and self.effector is not None:
            if self.arcing:  # an arc paused halfway: the pilot decides what next
                self.warn("a turn paused halfway ends here; send it again for the rest")
                self.trajectory.reset()
                self.phases.clear()
                self.event("action_done")
            else:  # finish the straight motion from where the effector is now
                self.line_to(self.effector, self.goal, self.speed_after_resume,
                             self.goal_rotation if self.full_pose else None)
        elif self.waiting_until is not None:
            self.waiting_until = self.now() + 0.2
        elif self.joint_motion is not None:
            index, motion = self.joint_motion
            names = [self.robot.joint_names[i] for i in index]
            self.joints_to(names, motion.goal, 0.5)
        return True

    speed_after_resume = 0.1  # m/s


def grasp_table(datasent: str, grasped: Mapping[str, Mapping[str, str]]) -> Dict[str, Dict[str, str]]:
    """The state table of a left-hand task: the part's pose (``datasent``), reach,
    approach, grasp, then the task's own ``grasped`` rows, ungrasp, move_away, home."""
    table: Dict[str, Dict[str, str]] = {
        "idle": {datasent: "ready"},
        "ready": {datasent: "ready", "reach": "reaching", "home": "homing"},
        "reaching": {"action_done": "reached"},
        "reached": {"approach": "approaching", "move_away": "moving_away", "home": "homing"},
        "approaching": {"action_done": "approached"},
        "approached": {"grasp": "grasping", "move_away": "moving_away"},
        "grasping": {"hand_done": "grasped"},
    }
    table.update({state: dict(moves) for state, moves in grasped.items()})
    table.update({
        "ungrasping": {"hand_done": "ungrasped"},
        "ungrasped": {"move_away": "moving_away", "grasp": "grasping"},
        "moving_away": {"action_done": "moved_away"},
        "moved_away": {"home": "homing", datasent: "ready", "reach": "reaching"},
        "homing": {"action_done": "idle"},
    })
    return table


class GraspTask(TaskModule):
    """A task done with the left hand on a part: reach, approach, grasp, ... ungrasp.

    ``_start_<...>datasent`` fills :attr:`target` with at least ``reach`` and
    ``approach`` points (pelvis frame), checked reachable by :meth:`aim`.
    """

    joints = LEFT_ARM + WAIST + [LEFT_HAND]
    speed = 0.15  # m/s, peak Cartesian speed

    def setup(self) -> None:
        self.hand = Effector("l_hand", GRIP, LEFT_ARM + WAIST)
        self.target: Optional[dict] = None

    def aim(self, target: dict, part: str) -> None:
        """Take ``target`` once its reach and approach points are reachable (else refuse)."""
        for point in ("reach", "approach"):
            self.reachable(self.hand, target[point], what=f"{part}'s {point} point")
        self.target = target

    def _start_reach(self) -> None:
        self.line_to(self.hand, self.target["reach"], self.speed)

    def _start_approach(self) -> None:
        self.line_to(self.hand, self.target["approach"], self.speed)

    def _start_grasp(self) -> None:
        self.set_hand(LEFT_HAND, HAND_CLOSED)

    def _start_ungrasp(self) -> None:
        self.set_hand(LEFT_HAND, HAND_OPEN)

    def back_away(self, gap: float) -> None:
        """The open hand straight back ``gap`` m along the target's ``forward`` axis, from
        wherever it let the part go."""
        position, _ = self.pose(self.hand)
        self.line_to(self.hand, position - gap * self.target["forward"], self.speed)

    def _start_home(self) -> None:
        self.home(LEFT_ARM + WAIST)
