"""Does a sole that lands on higher ground bear where the weight will go?  The foothold check (sans-IO).

Theory of operation
-------------------
A step up lands a sole on ground the module cannot see: it is told the
height, not where the kerb's edge is.  A sole whose heel lands over the edge
stands on its front part only; it carries the robot while the ZMP stays ahead
of the edge and tips it backwards as soon as the ZMP passes it (tried: a
``step_up`` sent from the station landed the heel 9 cm short; the robot stood
with the ZMP on the kerb's edge, and fell under the modules' latencies).  The
ankle's F/T sensor cannot tell a flat sole on a kerb's edge from one on flat
ground: a centre of pressure 4 cm behind the sole's centre is both.  What
tells them apart is how the sole first touches: turned toes-up by
:data:`TILT`, a sole comes down on its heel -- on firm ground its centre of
pressure is at the heel's end (13 cm behind the centre on the simulated robot);
over an edge the heel meets nothing and the sole touches down on the edge, its
centre of pressure there.

So a step onto higher ground, or onto a slope
(:attr:`walkman.control.footsteps.Step.checked_on_landing`; of ``step_up``'s two, the
leading one: the other lands beside it, as far past a kerb across the walk), lands heel first: the
sole turns over the last :data:`TURN` seconds of its descent, about its heel
(which comes down where the plan puts the sole), and stays turned until the
verdict.  The verdict is taken from the first :data:`TOUCH` seconds of weight
on the sole (the foot touches down late on the springy legs): their centre of
pressure, weighted by the load, must come within :data:`REACH` of the heel's
end, else the heel does not bear; a sole that has carried no weight
:data:`LATEST` seconds after the plan's landing found no ground.  A sole not touching
:data:`SEEK_AFTER` after its landing reaches on down for the ground (:data:`SEEK_SPEED`, at
most :data:`SEEK_DEPTH`), as a foot feels for a stair in the dark: a heel over the edge is
aimed at the kerb's height, the sole above the edge a few mm higher (toes up), and without
the reach it touched only when the legs' springs happened to sag that far -- 0.28 s after
the landing on a quiet machine, after :data:`LATEST` under load (then "no ground", and the
weight 50 ms from heading onto the new foot: the guard tripped).  The depth reached at the
touch is held, and given back as the sole turns flat.  The reach is for a few mm, not for
a plan whose frame is turned: after 15 s standing at a ramp's foot (the soles crept 4.5 cm
onto the bend on MuJoCo's soft contacts, resting 7.7 degrees for the slope's 10) the step to
the floor found no ground -- the attitude loop had tilted the commanded pelvis 2.7 degrees
to hold it level over soles resting otherwise than planned, 7 degrees off the IMU's at the
landing, and the swing foot came down 4 cm higher over the standing sole than planned, toes
up, the leg straight (knee 0.18 rad at the landing, 0 while reaching), 3 cm above the floor
at :data:`LATEST`: no reach would have found it.  The walking module now seats the soles as
they rest, standing and before a walk sets out (``seat_standing``, ``seat_soles`` of
:class:`walkman.modules.walking.Module`); the same step then touched without reaching
after 15 s standing, and after 25 s 0.23 s after its landing, 4 mm down.  A sole that
bears then turns flat; one that does not stays turned
(:meth:`FootholdCheck.release`) while the walking module puts the foot back
where it lifted from: the weight waits on the standing foot for :data:`WAIT`
after the landing (:attr:`walkman.control.footsteps.Timing.foothold_wait`), so the CoM
has not yet headed for the new one.

Why the touch and not a press once landed: a sole pressed at one end needs
weight on it, so the weight must go part-way onto it first -- and every such
stop threw the trailing foot's swing onto the kerb (tried: the ZMP within 3 mm
of the feet's edge); pressing while the weight shifts on left the robot no way
back (tried: it fell stepping back).

A step *down* -- any step that lands lower than it lifted, off a ramp's slope onto the floor
at its foot too, though that floor lies above the slope continued -- is watched on its way
instead (:class:`DescentCheck`).  Sent
before the feet reach the kerb's far edge, its sole comes down on the kerb it
leaves, 5 cm above where it was going: unwatched, the leg went on pressing it
down -- 1.4 kN on the sole, the robot thrown off its standing foot and fallen.
Watched, a sole that carries weight while the plan still has it more than
:data:`STRIKE_ABOVE` above its landing has met ground early (:data:`STRIKE_FORCE`
for :data:`STRIKE_SAMPLES` ticks in a row: one tick's reading of a swinging foot is no
touch): it stays there, on
the ground it left (the sole lags the plan: the plan had it 3.7 cm lower), the
weight on the standing foot, and goes back where it lifted from
(:meth:`walkman.control.footsteps.WalkPlan.strike`).  A step down that meets
nothing early costs nothing: no tilt, no wait (landing toes first and waiting,
tried before, cost the step down its margin under load: the guard tripped in 2
of 4 runs of the click test beside two CPU burners).

Limits: sagittal only: kerbs and steps cross the walk; a sole half over a side
edge (debris beside a foot) is not checked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Tuple

from walkman.control.balance import Sole
from walkman.control.trajectory import quintic

#: rad the sole is turned to land heel first (the toes 1 cm up)
TILT = 0.04
#: s the sole takes to turn, before the landing and back flat after the verdict
TURN = 0.15
#: s of touch (weight on the sole) the verdict is taken from: the first touch, not the
#: weight shift that follows
TOUCH = 0.04
#: s after the plan's landing by which a sole must have touched: feet land late on the
#: springy legs (0.1 s going up, 0.2 s going down a 5-cm step, measured)
LATEST = 0.35
#: m: the heel bears if the centre of pressure comes this close to the heel's end
REACH = 0.03
#: s after the plan's landing a sole still not touching starts reaching down: soles on firm
#: ground touched by then, or within a few mm (0.06-0.19 s measured, up steps and a ramp)
SEEK_AFTER = 0.12
#: m/s, m: how fast and how far below the plan's landing it reaches
SEEK_SPEED = 0.04
SEEK_DEPTH = 0.015
#: s the weight waits on the standing foot after the landing: the verdict must be in before
#: the CoM heads for the new foot (the preview controller moves it ahead of the ZMP), or
#: there is no way back (tried: waiting 0.3 s the robot fell stepping back, 0.4 s and 0.5 s
#: it stood; each 0.1 s more costs the step course about 0.5 cm of ZMP margin)
WAIT = 0.4
#: m: a sole stepping down that carries weight while the plan has it this far above its
#: landing met ground early.  The sole lags the plan on the way down (coming down a 5-cm
#: step onto the kerb it left, it touched while the plan had it 1.3 cm above the floor:
#: 3.7 cm behind); a sole landing as planned touched only after the plan had it down
#: (measured: carrying no weight until then)
STRIKE_ABOVE = 0.005
#: N, samples: a strike is weight that stays: this much on the sole for this many ticks in
#: a row.  A swing foot read 51-52 N for a tick 0.19 s before landing, its way clear of the
#: edge by 6 cm, under load (fc21 and fc23 of 2026-11-28: the foot was put back for
#: nothing); a sole on the kerb it leaves carried 648 N at once, and 1.4 kN unwatched
STRIKE_FORCE = 150.0
STRIKE_SAMPLES = 2


@dataclass
class FootholdCheck:
    """One sole landing heel first at ``landing`` (the plan's landing time), its centre of
    pressure sampled each tick (:meth:`sample`)."""

    side: str
    landing: float
    sole: Sole = field(default_factory=Sole)
    _samples: List[Tuple[float, float]] = field(default_factory=list, repr=False)
    _touched: Optional[float] = field(default=None, repr=False)
    _decided_at: Optional[float] = field(default=None, repr=False)
    _released_at: Optional[float] = field(default=None, repr=False)
    #: the verdict: None until it is in
    bears: Optional[bool] = field(default=None, init=False)

    def tilt(self, t: float) -> float:
        """The pitch (rad, rpy: negative turns the toes up) added to the sole at ``t``."""
        into = quintic((t - (self.landing - TURN)) / TURN)
        flat_from = self._turns_flat_at
        if flat_from is not None:
            into = min(into, quintic((flat_from + TURN - t) / TURN))
        return -TILT * into

    def release(self, t: float) -> None:
        """A sole that did not bear stays turned (turned flat, it would pivot on the edge it
        rests on and jam the leg: tried, 1.2 kN on it, the robot thrown back) until its foot
        lifts off again: from ``t`` it turns flat."""
        if self._released_at is None:
            self._released_at = t

    def shift(self, t: float, ground_pitch: float = 0.0) -> Tuple[float, float]:
        """How far (forward along the foot's heading, up; m) the sole's centre moves at ``t``
        so that it turns about its heel, which comes down where the plan puts the sole --
        turned about its centre, the heel would strike 5 mm early -- less the depth it
        reaches down for the ground (:meth:`reach`)."""
        tilt = self.tilt(t)
        heel = -self.sole.half_length
        dx, dz = heel - heel * math.cos(tilt), heel * math.sin(tilt)   # in the sole's frame
        return (dx * math.cos(ground_pitch) + dz * math.sin(ground_pitch),
                -dx * math.sin(ground_pitch) + dz * math.cos(ground_pitch) - self.reach(t))

    def reach(self, t: float) -> float:
        """m the sole is below the plan's landing at ``t``, feeling for the ground: from
        :data:`SEEK_AFTER` untouched, down at :data:`SEEK_SPEED` to :data:`SEEK_DEPTH`, held
        from the touch (or the verdict), given back as the sole turns flat."""
        until = self._touched if self._touched is not None else self._decided_at
        seeking = (t if until is None else min(t, until)) - self.landing - SEEK_AFTER
        depth = min(max(seeking, 0.0) * SEEK_SPEED, SEEK_DEPTH)
        return depth * self.tilt(t) / -TILT

    def sample(self, t: float, pressure: Optional[Tuple[float, float, float]]) -> None:
        """The sole's measured (px, py, fz) at ``t`` -- from
        :func:`walkman.control.balance.foot_zmp`, None when it carries no weight."""
        if pressure is None or self._decided_at is not None or t < self.landing - TURN:
            return
        if self._touched is None:
            self._touched = t
        self._samples.append((float(pressure[0]), float(pressure[2])))

    def decide(self, t: float) -> Optional[str]:
        """The verdict (:meth:`verdict`) once: after :data:`TOUCH` of touch, or at
        :data:`LATEST` after the landing if the sole never touched; None before and after."""
        if self._decided_at is not None:
            return None
        touched = self._touched is not None and t >= self._touched + TOUCH
        if not touched and t < self.landing + LATEST:
            return None
        self._decided_at = t
        problem = self.verdict()
        self.bears = not problem
        return problem

    def done(self, t: float) -> bool:
        """Decided, and the sole flat again."""
        flat_from = self._turns_flat_at
        return flat_from is not None and t >= flat_from + TURN

    @property
    def _turns_flat_at(self) -> Optional[float]:
        """When the sole starts turning flat: at the verdict if it bears, once released if
        not; None before."""
        return self._released_at if self.bears is False else self._decided_at

    @property
    def touched_after(self) -> Optional[float]:
        """s from the plan's landing to the sole's first touch (< 0: early); None untouched."""
        return None if self._touched is None else self._touched - self.landing

    def verdict(self) -> str:
        """'' if the sole bears at its heel; else why not, as a pilot reads it."""
        if not self._samples:
            return (f"the {self.side} sole found no ground: it carried no weight "
                    f"{LATEST:.2f} s after it should have landed")
        reached = sum(x * f for x, f in self._samples) / sum(f for _, f in self._samples)
        short = self.sole.half_length + reached
        if short <= REACH:
            return ""
        where = "behind" if reached < 0 else "ahead of"
        return (f"the {self.side} sole landed on its heel but bore {abs(reached) * 100:.0f} "
                f"cm {where} its centre, {short * 100:.0f} cm from its heel (at most "
                f"{REACH * 100:.0f}): its heel is over an edge")


@dataclass
class DescentCheck:
    """One sole stepping down ``drop`` m, due to land at ``landing`` (the plan's time),
    watched from its lift-off: it must not carry weight before it is near its landing
    (:data:`STRIKE_ABOVE`)."""

    side: str
    drop: float
    landing: float
    #: the sole has been seen carrying no weight since it lifted (before that, the weight
    #: still leaving it is no touch)
    _free: bool = field(default=False, repr=False)
    #: ticks in a row it has carried :data:`STRIKE_FORCE` early
    _pressed: int = field(default=0, repr=False)

    def sample(self, t: float, above_landing: float,
               pressure: Optional[Tuple[float, float, float]]) -> Optional[str]:
        """At ``t``, the plan's sole height above its landing (m) and the sole's measured
        (px, py, fz) -- None when it carries no weight; returns why it struck, once, or
        None."""
        if pressure is None:
            self._free, self._pressed = True, 0
            return None
        if not self._free or above_landing <= STRIKE_ABOVE or pressure[2] < STRIKE_FORCE:
            self._pressed = 0
            return None
        self._pressed += 1
        if self._pressed < STRIKE_SAMPLES:
            return None
        self._free, self._pressed = False, 0      # said once
        return (f"the {self.side} sole met ground on its way {self.drop * 100:.0f} cm down, "
                f"{self.landing - t:.2f} s before it should have landed ({pressure[2]:.0f} N "
                f"on it): the ground it leaves goes on under it")
