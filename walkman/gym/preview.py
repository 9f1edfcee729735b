"""Where a task command will take the robot, worked out before the command leaves the pilot PC.

Theory of operation
-------------------
The pilot PC keeps a *shadow* of a task module: the same class, run by an
:class:`~walkman.gym.offline.OfflineWorld` whose backend is kinematic (the joints
are where the robot last measured them and nothing moves by itself), so every
decision is the module's own code and IK.

* :meth:`Shadow.follow` gives the shadow each command the pilot sent, once the
  robot's module accepted it, at the posture measured then: the shadow's notes
  (the part's pose, where the drill was held) are the module's.
* :meth:`Shadow.preview` takes a command about to be sent and the state the
  robot's module reports, puts the shadow in that state at the measured
  posture, and hands it the command as the module would.  A refusal there
  (a state that does not take it, an unreachable target) is the module's
  refusal, said before anything leaves.  Otherwise the motion it started is
  followed to its end: each Cartesian motion is solved by the module's IK at
  ``PATH_SAMPLES`` points along it, each on from the last one's posture, as the
  module's loop tracks it; joint motions and hand goals are taken as they
  are, and chained motions (``then``) one after the other.  A point the IK
  cannot reach within 1 cm from there is solved again from seeded restarts (a
  local minimum of the tracking posture is not "out of reach"); one that still
  misses refuses the command, saying where -- but for a contact motion (a foot
  pressing a pedal: its goal lies inside what it pushes), which the module ends
  with its trajectory wherever it stopped.  The shadow is put back as it was
  afterwards: a preview never changes what a later one computes.

The result is a posture for the whole body: the 3-D view draws it as a ghost
while the timed button counts down.  A shadow that started after the part's
pose was sent (a PI restarted mid-task) lacks what the module knows: the first
command that needs it puts the shadow *out of step* and its previews are then
unknown -- neither a ghost nor a refusal -- until the pilot sends a pose again.
"""

from __future__ import annotations

import copy
import logging
import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple, Type

import numpy as np

from walkman.gym.offline import OfflineWorld
from walkman.hal.backend import Backend, Imu
from walkman.model.description import walkman
from walkman.modules.task import ACTION_TOLERANCE, TaskModule
from yarp_lite.bottle_text import parse

log = logging.getLogger("walkman.preview")
MAX_PHASES = 16          # chained motions followed before the preview gives up
PATH_SAMPLES = 12        # points of a Cartesian motion solved on the way to its end
#: IK iterations per point: the module's loop gives the stretch between two points many
#: ticks of 20 (walkman.modules.task), the preview two ticks' worth, so a preview costs
#: milliseconds.
SAMPLE_ITERATIONS = 40
#: A point those leave more than 1 cm off is solved again with the solver's whole budget and
#: this many seeded restarts before it is called out of reach, the path going on from there:
#: from the tracking posture alone, a robot crouched at the door (walking paused, the
#: harness off) had its turn and open refused 1.0-1.7 cm short -- a local minimum of the
#: first samples, carried along -- where the module's loop opened the door 53 degrees (one
#: restart was not enough there, two were).  A refusal costs more for it (bench_preview.py:
#: the valve's 3/4 turn refused in 39 ms, 3 ms before); a path within reach costs nothing.
REACH_RESTARTS = 4


class KinematicBackend(Backend):
    """Joints where they are told to be; nothing moves by itself, nothing is sensed."""

    def __init__(self) -> None:
        super().__init__(walkman())
        self.posture = self.reference.copy()

    def set_posture(self, q: Sequence[float]) -> None:
        self.posture = np.asarray(q, dtype=float).copy()
        self.reference = self.posture.copy()

    def step(self) -> None:
        self.time += self.dt

    def positions(self) -> np.ndarray:
        return self.posture.copy()

    def velocities(self) -> np.ndarray:
        return np.zeros(len(self.joint_names))

    def torques(self) -> np.ndarray:
        return np.zeros(len(self.joint_names))

    def temperatures(self) -> np.ndarray:
        return np.full(len(self.joint_names), 25.0)

    def ft(self, sensor: str) -> np.ndarray:
        return np.zeros(6)

    def imu(self) -> Imu:
        return Imu((0.0, 0.0, 0.0), (0.0, 0.0, 9.81), (0.0, 0.0, 0.0))


@dataclass
class Preview:
    """A command's outcome on the pilot PC: the posture it ends in, or why it would be
    refused; how long working it out took."""

    command: str
    posture: Optional[np.ndarray]
    refusal: str
    seconds: float
    #: False when the shadow could not work it out (it is out of step with the module, e.g.
    #: the part's pose was sent before this PC followed): no verdict either way.
    known: bool = True
    #: False when the command starts no motion the shadow can follow (a walk: its steps are
    #: balance, not IK): the posture is where the robot is, nothing to show as a ghost.
    moves: bool = True

    @property
    def refused(self) -> bool:
        return self.known and self.posture is None


class OutOfStep(Exception):
    """The shadow lacks what the module knows (a command arrived it never saw the pose for)."""


class Shadow:
    """A task module's double on the pilot PC (see the module's docstring)."""

    def __init__(self, module_class: Type[TaskModule], name: str) -> None:
        self.backend = KinematicBackend()
        self.world = OfflineWorld(self.backend)
        self.module = self.world.add(module_class, name)
        self.name = name
        if not self.module.switch("start"):
            raise RuntimeError(f"the shadow of {name} did not start: {self.module.warnings}")
        self.thread: TaskModule = self.module.thread  # type: ignore[assignment]
        self.joint_names = list(self.backend.joint_names)
        self.home = self.backend.posture.copy()   # the model's standing posture
        #: whether the shadow knows what the module knows: from its start, lost when a command
        #: needs what it never saw (this PC started after the pose was sent), back at a pose
        self.in_step = True
        self.out_of_step = ""      # where and why it last fell out of step

    # -- following the robot ---------------------------------------------------------------

    def follow(self, text: str, state: str, posture: Sequence[float]) -> None:
        """The robot's module took ``text`` in ``state`` at ``posture``: take it too."""
        try:
            refusals = self._start(text, state, posture)
        except OutOfStep as exc:
            if self.in_step:
                self.out_of_step = f"at {text!r} in {state}: {exc}"
                log.warning("preview of %s: out of step %s; no previews until a pose is sent "
                            "again", self.name, self.out_of_step)
            self.in_step = False
            return
        if refusals and self.in_step:
            log.warning("preview of %s: the shadow refused %r in %s, which the module took "
                        "(%s)", self.name, text, state, refusals[-1])
        words = text.split()
        if words and words[0].endswith("datasent") and not refusals:
            self.in_step = True

    def _start(self, text: str, state: str, posture: Sequence[float]) -> List[str]:
        """Hand ``text`` to the shadow in ``state`` at ``posture``; its warnings (refusals)."""
        self.backend.set_posture(posture)
        thread = self.thread
        thread.reference = np.asarray(posture, dtype=float).copy()
        thread.forget_motions()             # the shadow never runs its motions: none is left
        if state in self.thread.table:
            self.thread.fsm.state = state
        said = len(self.module.warnings)
        bottle = parse(text)
        if not bottle or not isinstance(bottle[0], str):
            return [f"'{text}' is not a command"]
        try:
            self.thread.handle(bottle[0], list(bottle[1:]))
        except Exception as exc:  # noqa: BLE001 -- the module's code met a state it never set
            raise OutOfStep(f"{type(exc).__name__}: {exc}") from exc
        return list(self.module.warnings[said:])

    # -- previewing -------------------------------------------------------------------------

    def preview(self, text: str, state: str, posture: Sequence[float]) -> Preview:
        """Where ``text`` sent now would take the robot (or why the module would refuse it)."""
        began = time.perf_counter()
        if not self.in_step:
            return Preview(text, None, "this PC has not seen the task's pose (send it again "
                           "for a preview)", 0.0, known=False)
        saved = self._snapshot()
        try:
            refusals = self._start(text, state, posture)
            if refusals:
                return Preview(text, None, refusals[-1], time.perf_counter() - began)
            moves = self._moves()
            end, reason = self._follow_to_end(np.asarray(posture, dtype=float))
            return Preview(text, end, reason, time.perf_counter() - began, moves=moves)
        except OutOfStep as exc:
            return Preview(text, None, f"the preview could not follow the module ({exc})",
                           time.perf_counter() - began, known=False)
        finally:
            self._restore(saved)

    def _moves(self) -> bool:
        """The command just handed to the shadow started a motion it can follow."""
        thread = self.thread
        return bool((thread.trajectory.active and thread.effector is not None)
                    or thread.joint_motion is not None or thread.hand_goals or thread.phases)

    def _follow_to_end(self, q: np.ndarray) -> Tuple[Optional[np.ndarray], str]:
        """The posture the started motion and the ones chained to it end in, from ``q``; or
        ``None`` and where the path leaves the IK's reach."""
        thread = self.thread
        for _ in range(MAX_PHASES):
            q = q.copy()
            if thread.trajectory.active and thread.effector is not None:
                reason = self._follow_path(q)
                if reason:
                    return None, reason
                thread.trajectory.reset()
            elif thread.joint_motion is not None:
                index, motion = thread.joint_motion
                q[index] = motion.goal
                thread.joint_motion = None
            thread.waiting_until = None
            for hand, (goal, _) in thread.hand_goals.items():
                q[hand] = goal
            thread.hand_goals.clear()
            if not thread.phases:
                return q, ""
            self.backend.set_posture(q)
            thread.phases.pop(0)()
        return None, f"{self.name}: more than {MAX_PHASES} chained motions"

    def _follow_path(self, q: np.ndarray) -> str:
        """Move ``q`` (in place) along the effector's trajectory as the module's loop tracks
        it: each point's posture on from the last one's; a point missed from there is solved
        again from seeded restarts, and only a point those miss too refuses (a turn that
        passes where the hand cannot go would stall there on the robot).  The module's loop
        has no restarts: a path the restarts get through and its tracking would not is
        accepted, and the ghost goes on from the restart's posture.  A contact motion is judged
        by its end alone: on the way it presses into what it pushes (a pedal), where no
        posture reaches, and the module ends with its trajectory wherever it stopped.
        Returns where the path leaves the IK's reach, or ''."""
        thread = self.thread
        effector, trajectory = thread.effector, thread.trajectory
        moved = thread.ik.joints_of(effector.joints)
        samples = [PATH_SAMPLES] if thread.contact else range(1, PATH_SAMPLES + 1)
        for sample in samples:
            position, rotation = trajectory.at(
                trajectory.t0 + trajectory.duration * sample / PATH_SAMPLES)
            target = rotation if thread.full_pose else None
            result = thread.ik.solve(effector.frame, position, target, q, effector.joints,
                                     offset=effector.offset, restarts=0, rest=thread.rest,
                                     max_iterations=SAMPLE_ITERATIONS)
            if not thread.contact and result.position_error > ACTION_TOLERANCE:
                # out of reach, or only a local minimum of the tracking posture?
                result = thread.ik.solve(effector.frame, position, target, q,
                                         effector.joints, offset=effector.offset,
                                         restarts=REACH_RESTARTS, rest=thread.rest)
            q[moved] = result.q[moved]
            if not thread.contact and result.position_error > ACTION_TOLERANCE:
                where = "at the end" if sample == PATH_SAMPLES else \
                    f"{100 * sample // PATH_SAMPLES} % of the way"
                return (f"{self.name}: the {effector.frame} cannot reach "
                        f"{np.round(position, 3).tolist()} {where} (misses by "
                        f"{result.position_error * 100:.1f} cm)")
        return ""

    def _snapshot(self) -> Dict[str, object]:
        """The module's attributes, containers copied (a motion mutates them in place)."""
        saved = {}
        for key, value in self.thread.__dict__.items():
            if isinstance(value, (dict, list)):
                saved[key] = copy.copy(value)
            elif isinstance(value, np.ndarray):
                saved[key] = value.copy()
            else:
                saved[key] = value
        saved["__fsm_state"] = self.thread.fsm.state
        return saved

    def _restore(self, saved: Dict[str, object]) -> None:
        state = saved.pop("__fsm_state")
        self.thread.__dict__.clear()
        self.thread.__dict__.update(saved)
        self.thread.fsm.state = state
        self.thread.trajectory.reset()
