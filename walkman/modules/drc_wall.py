"""drc_wall: the DRC wall task -- take the drill, switch it on, cut a circle out of the drywall.

Theory of operation
-------------------
The pilot tells where the drill and the circle are (``walldatasent X Y Z ROLL
PITCH YAW CX CY CZ RADIUS``: the drill's grip -- the middle of its handle --
and its orientation, x along the bit, then the centre of the circle marked on
the wall and its radius, all in the pelvis frame; the wall faces the robot,
square to the pelvis's x axis), then steps through the task with the left hand:
``reach``, ``approach``, ``grasp`` the handle; ``lift`` (straight up off the
table), ``switch_on`` (the hand squeezes the trigger), ``to_wall`` (the bit's
tip in front of the circle's top), ``push_in`` (the tip through the panel),
``cut`` (the tip once round the circle and 15 degrees on: section 2.5's circular trajectory,
quintic in the angle, the drill's orientation held), ``pull_out``,
``switch_off``, ``put_down`` (back over the table, then down to where it
stood), ``ungrasp``, ``move_away``, ``home``.

After the grasp the module moves the bit's tip, not the hand: an
:class:`~walkman.modules.task.Effector` on the hand whose offset is where the tip
sits in the hand's frame (the drill's geometry, ``DRILL_TIP``, at the pose the
grasp welded it), solved with the hand's orientation held -- so a tip that
goes round the circle cuts the circle.  The hand reaches and approaches the
handle with the orientation the IK chose for the approach point when the
pose arrived, and every point of the task (the lift, the wall, the whole
circle at its depth) is checked reachable with that orientation at
``walldatasent``: a circle the hand cannot cut is refused before anything moves,
with the distance it misses by.

The drill itself is the simulator's (:mod:`walkman.hal.sim`): it runs while
the hand holding it squeezes past its trigger point, and the drywall judges the
cut from the tip's path (:mod:`walkman.hal.drywall`).
"""

from __future__ import annotations

import math
from typing import List, Optional

import numpy as np

from walkman.gym.link_loss import LinkLoss
from walkman.model.mjcf import DRILL_TIP
from walkman.modules.drc_valve import rpy_matrix
from walkman.modules.task import (HAND_CLOSED, LEFT_HAND, Effector, GraspTask, grasp_table,
                                  task_statuses)

APPROACH_GAP = 0.045     # m behind the handle when approached (the hand grasps within 8 cm)
REACH_GAP = 0.165        # m behind the handle when reached
LIFT = 0.12              # m the drill rises off its table
STANDOFF = 0.03          # m between the tip and the wall before it goes in
DEPTH = 0.02             # m the tip goes past the wall's face: through a 1.5 cm panel
HAND_TRIGGER = 1.45      # rad: the hand closed on the trigger, past the simulator's DRILL_TRIGGER
TRIGGER_TOLERANCE = 0.03
CUT_SPEED = 1.0          # rad/s, peak angular speed round the circle
CHECKED_ANGLES = 24      # points of the circle checked reachable at walldatasent
RADII = (0.03, 0.15)     # m: the circles this drill and arm can cut
#: rad the cut goes on past where it began: the tip lags the trajectory, and a cut that ends
#: where it began arrives by tolerance before the tip has closed the circle (a fresh-clone
#: run beside another test's worker: the tip came out 5 degrees short, 355 of 360 cut)
OVERLAP = math.radians(15)
INTO_WALL = np.array([1.0, 0.0, 0.0])   # the wall faces the robot
UP = np.array([0.0, 0.0, 1.0])

TABLE = grasp_table("walldatasent", {
    "grasped": {"lift": "lifting", "ungrasp": "ungrasping"},
    "lifting": {"action_done": "lifted"},
    "lifted": {"switch_on": "switching_on", "put_down": "putting_down"},
    "switching_on": {"hand_done": "drill_on"},
    "drill_on": {"to_wall": "moving_to_wall", "switch_off": "switching_off"},
    "moving_to_wall": {"action_done": "at_wall"},
    "at_wall": {"push_in": "pushing_in", "switch_off": "switching_off"},
    "pushing_in": {"action_done": "drilled_in"},
    "drilled_in": {"cut": "cutting", "pull_out": "pulling_out"},
    "cutting": {"action_done": "cut_done"},
    "cut_done": {"pull_out": "pulling_out", "cut": "cutting"},
    "pulling_out": {"action_done": "at_wall"},
    "switching_off": {"hand_done": "drill_off"},
    "drill_off": {"put_down": "putting_down", "switch_on": "switching_on"},
    "putting_down": {"action_done": "on_table"},
    "on_table": {"ungrasp": "ungrasping", "lift": "lifting"},
})

#: The whole task as a pilot steps it once the pose is sent: each command and the state it
#: ends in (the README's walk-through, the tests and the benchmark all follow it).
TASK_STEPS = (("reach", "reached"), ("approach", "approached"), ("grasp", "grasped"),
              ("lift", "lifted"), ("switch_on", "drill_on"), ("to_wall", "at_wall"),
              ("push_in", "drilled_in"), ("cut", "cut_done"), ("pull_out", "at_wall"),
              ("switch_off", "drill_off"), ("put_down", "on_table"),
              ("ungrasp", "ungrasped"), ("move_away", "moved_away"), ("home", "idle"))


class Module(GraspTask):
    statuses = task_statuses(TABLE)
    status_format = {"*": "circle at ({0:.2f}, {1:.2f}, {2:.2f}) m, radius {3:.2f} m"}
    table = TABLE
    arguments = {"walldatasent": (10, 10, "X Y Z ROLL PITCH YAW CX CY CZ RADIUS")}
    dangerous = frozenset({"push_in", "cut"})
    # Every motion ends by itself with the hand still, the tip out of the wall or going
    # round the circle it was sent round.
    link_loss = LinkLoss.CONTINUE
    compensate_sag = True

    def setup(self) -> None:
        super().setup()
        self.tool: Optional[Effector] = None

    def status_data(self) -> List[float]:
        if self.target is None:
            return []
        return [*map(float, self.target["centre"]), float(self.target["radius"])]

    # -- the pose -----------------------------------------------------------------------------

    def _start_walldatasent(self, x, y, z, roll, pitch, yaw, cx, cy, cz, radius) -> None:
        if not RADII[0] <= radius <= RADII[1]:
            raise ValueError(f"the circle's radius is {RADII[0]:g}..{RADII[1]:g} m, "
                             f"got {radius:g}")
        rotation = rpy_matrix(roll, pitch, yaw)
        grip, centre = np.array([x, y, z]), np.array([cx, cy, cz])
        forward = rotation[:, 0]               # the hand comes along the drill's bit axis
        tip = grip + rotation @ np.array(DRILL_TIP)
        if float((centre - tip) @ INTO_WALL) < STANDOFF:
            raise ValueError(f"the wall ({cx:g} m ahead) must be more than {STANDOFF:g} m "
                             f"beyond the drill's tip on its table ({tip[0]:.2f} m)")
        target = {"grip": grip, "forward": forward, "centre": centre, "radius": radius,
                  "approach": grip - APPROACH_GAP * forward,
                  "reach": grip - REACH_GAP * forward}
        approach = self.reachable(self.hand, target["approach"], what="drill's approach point")
        # The hand keeps the orientation the IK gives it at the approach point from here on:
        # the grasp welds the drill to it, so the drill stays as it stood on the table.
        origin, hand_rotation = self.kinematics.pose(approach, self.hand.frame)
        target["rotation"] = hand_rotation
        tool = Effector(self.hand.frame, hand_rotation.T @ (tip - origin), self.hand.joints)
        top = centre + radius * UP
        target.update({"lifted": tip + LIFT * UP, "standoff": top - STANDOFF * INTO_WALL,
                       "in": top + DEPTH * INTO_WALL})
        self.reachable(self.hand, target["reach"], hand_rotation, what="drill's reach point")
        for point in ("lifted", "standoff"):
            self.reachable(tool, target[point], hand_rotation, what=f"tip's {point} point")
        # The circle as the cut tracks it: on from each point's posture to the next's.
        posture = self.reachable(tool, target["in"], hand_rotation, what="tip's in point")
        right = np.cross(INTO_WALL, UP)   # -y: the robot's right, where the cut goes first
        for index in range(1, CHECKED_ANGLES + 1):
            angle = 2 * math.pi * index / CHECKED_ANGLES
            point = centre + DEPTH * INTO_WALL + radius * (math.cos(angle) * UP +
                                                           math.sin(angle) * right)
            posture = self.reachable(tool, point, hand_rotation, seed=posture,
                                     what=f"circle at {math.degrees(angle):.0f} degrees")
        target["tip"] = tip
        self.target = target

    # -- the hand on the handle ------------------------------------------------------------------

    def _start_reach(self) -> None:
        self.line_to(self.hand, self.target["reach"], self.speed, self.target["rotation"])

    def _start_approach(self) -> None:
        self.line_to(self.hand, self.target["approach"], self.speed, self.target["rotation"])

    def _start_grasp(self) -> None:
        super()._start_grasp()
        self.tool = None            # the weld takes the drill wherever the hand holds it

    def _held_tool(self) -> Effector:
        """The tip as a point of the hand: where the drill stood when the grasp welded it
        (the pilot's pose), in the hand's frame as the hand is now."""
        if self.tool is None:
            origin, rotation = self.kinematics.pose(self.robot.sense_position(), self.hand.frame)
            self.tool = Effector(self.hand.frame, rotation.T @ (self.target["tip"] - origin),
                                 self.hand.joints)
            self.target["held"] = self.pose(self.tool)[0]
        return self.tool

    # -- the drill --------------------------------------------------------------------------------

    def _tip_to(self, goal: np.ndarray, speed: float) -> None:
        self.line_to(self._held_tool(), goal, speed, self.target["rotation"])

    def _start_lift(self) -> None:
        tool = self._held_tool()
        self._tip_to(self.pose(tool)[0] + LIFT * UP, self.speed)

    def _start_switch_on(self) -> None:
        self.set_hand(LEFT_HAND, HAND_TRIGGER, TRIGGER_TOLERANCE)

    def _start_switch_off(self) -> None:
        self.set_hand(LEFT_HAND, HAND_CLOSED, TRIGGER_TOLERANCE)

    def _start_to_wall(self) -> None:
        self._tip_to(self.target["standoff"], self.speed)

    def _start_push_in(self) -> None:
        self._tip_to(self.target["in"], self.speed / 4)

    def _start_cut(self) -> None:
        """Once round the circle from its top and :data:`OVERLAP` on, at the depth the tip
        went in, clockwise as the robot sees the wall (about the axis into it), the drill's
        orientation held."""
        centre = self.target["centre"] + DEPTH * INTO_WALL
        self.arc(self._held_tool(), centre, INTO_WALL, 2 * math.pi + OVERLAP, CUT_SPEED,
                 turn_orientation=False, start=(self.target["in"], self.target["rotation"]))

    def _start_pull_out(self) -> None:
        position, _ = self.pose(self._held_tool())
        self._tip_to(position - (STANDOFF + DEPTH) * INTO_WALL, self.speed / 4)

    def _start_put_down(self) -> None:
        """Over where the drill stood, then straight down to it: it stands as it stood."""
        held = self.target["held"]
        self._tip_to(held + LIFT * UP, self.speed)
        self.then(lambda: self._tip_to(held, self.speed / 2))

    def _start_move_away(self) -> None:
        self.back_away(REACH_GAP)

