"""What a module does when the link to the pilot dies: its declared policy, and when it acts.

Theory of operation
-------------------
A module class declares ``link_loss`` (:class:`LinkLoss`):

* ``LinkLoss.CONTINUE`` (the default, as the DRC team ran): the module goes on
  with what the pilot last asked.  Its motions are bounded anyway (a turn of
  the valve, a press of the throttle for T s), and a pilot back after a
  blackout finds it where it would have been;
* ``LinkLoss.pause(after=N)``: a *running* module is paused once the link has
  been down N s -- the same ``pause`` as a pilot's, with its safe pause
  (walking lands its foot) and ``run_paused`` (walking keeps its balance);
* ``LinkLoss.stop(after=N)``: a running or paused module is stopped once the
  link has been down N s -- again a pilot's ``stop``, ending with the robot
  held.

Neither ever drops the robot: what is left is what a pilot's switch leaves,
and the HAL holds the last reference of a silent module.  The policy never
resumes or restarts a module when the link returns: the pilot, who has seen
nothing meanwhile, decides; the module only says that the link is back.

"Down" is what :class:`nodekit.link_watch.LinkWatch` says of the robot bridge's
status: the bridge said so, or it went quiet after having spoken.  In the lab
there is no bridge, the link stays ``unknown``, and no policy ever fires.  N
counts from the later of the moment the link was known down (the bridge says
so after :data:`~nodekit.link_watch.SILENT_DOWN` s of silence) and the moment the
module entered the state the policy acts on, so a module started during an
outage (from the robot itself) gets its N s too.

:class:`LinkLossDecider` is pure: the link's state, the lifecycle state and the
time in, at most one :class:`Verdict` out; the runner carries it out through
its :class:`~walkman.gym.transitions.Lifecycle`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import ClassVar, Dict, FrozenSet, Optional, Tuple

from nodekit.link_watch import DOWN, LinkState
from walkman.gym.lifecycle import State, Switch


class LossAction(str, Enum):
    CONTINUE = "continue"
    PAUSE = "pause"
    STOP = "stop"


#: The switch each action makes, and the states it is made from.
_SWITCH: Dict[LossAction, Switch] = {LossAction.PAUSE: Switch.PAUSE,
                                     LossAction.STOP: Switch.STOP}
_ACTS_ON: Dict[LossAction, FrozenSet[State]] = {
    LossAction.CONTINUE: frozenset(),
    LossAction.PAUSE: frozenset({State.RUNNING}),
    LossAction.STOP: frozenset({State.RUNNING, State.PAUSED}),
}
#: The state each action leaves, and the pilot's switch that undoes it.
_LEAVES: Dict[LossAction, Tuple[State, str]] = {LossAction.PAUSE: (State.PAUSED, "resumes"),
                                                LossAction.STOP: (State.STOPPED, "starts")}


@dataclass(frozen=True)
class LinkLoss:
    """A module's link-loss policy (module docstring); declare it in the class."""

    action: LossAction = LossAction.CONTINUE
    after: float = 0.0    # seconds the link must have been down

    CONTINUE: ClassVar["LinkLoss"]

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "action", LossAction(self.action))
        except ValueError:
            raise ValueError(f"link_loss: {self.action!r} is not one of "
                             f"{', '.join(a.value for a in LossAction)}") from None
        after = self.after
        if isinstance(after, bool) or not isinstance(after, (int, float)) or \
                not (math.isfinite(after) and after >= 0):
            raise ValueError(f"link_loss: 'after' must be a finite number of seconds >= 0, "
                             f"got {self.after!r}")

    @classmethod
    def pause(cls, after: float) -> "LinkLoss":
        return cls(LossAction.PAUSE, float(after))

    @classmethod
    def stop(cls, after: float) -> "LinkLoss":
        return cls(LossAction.STOP, float(after))

    def __str__(self) -> str:
        if self.action is LossAction.CONTINUE:
            return "continue"
        return f"{self.action.value} after {self.after:g} s"


LinkLoss.CONTINUE = LinkLoss()


def link_loss_of(module_class: object) -> LinkLoss:
    """The policy a module class declares (``link_loss``); a wrong declaration is refused
    here, when the module loads, not in the middle of a blackout."""
    policy = getattr(module_class, "link_loss", LinkLoss.CONTINUE)
    if not isinstance(policy, LinkLoss):
        raise TypeError(f"{getattr(module_class, '__name__', module_class)}.link_loss must be "
                        f"a LinkLoss (LinkLoss.CONTINUE, LinkLoss.pause(after=5.0), "
                        f"LinkLoss.stop(after=...)), got {policy!r}")
    return policy


@dataclass(frozen=True)
class Verdict:
    """What the runner does: make ``switch`` (then say ``warning`` if it took effect), or
    only say ``warning`` (``switch`` None)."""

    warning: str
    switch: Optional[Switch] = None


class LinkLossDecider:
    """Applies one module's :class:`LinkLoss` to the link and the lifecycle, step by step."""

    def __init__(self, name: str, policy: LinkLoss) -> None:
        self.name, self.policy = name, policy
        self._state: Optional[State] = None
        #: (link down since, state since) of the last switch proposed: once per outage and state.
        self._proposed: Optional[Tuple[float, float]] = None
        #: When the policy acted in the current outage (for "the link is back").
        self._acted_at: Optional[float] = None

    def step(self, link: LinkState, state: State, state_since: float,
             now: float) -> Optional[Verdict]:
        """The link and the lifecycle (in ``state`` since ``state_since``) as they are
        ``now``, all on one clock; what to do, if anything."""
        self._state = state
        if link.state != DOWN:
            return self._link_back(now)
        if state not in _ACTS_ON[self.policy.action]:
            return None
        key = (link.since, state_since)
        if self._proposed == key or now - max(key) < self.policy.after:
            return None
        self._proposed, self._acted_at = key, now
        action = self.policy.action
        return Verdict(f"{self.name}: {_LEAVES[action][0].value}: no link to the pilot for "
                       f"{now - link.since:.0f} s (link-loss policy)", _SWITCH[action])

    def _link_back(self, now: float) -> Optional[Verdict]:
        if self._acted_at is None:
            return None
        ago, self._acted_at = now - self._acted_at, None
        left, undo = _LEAVES[self.policy.action]
        if self._state != left:   # someone on the robot's side changed it meanwhile
            return Verdict(f"{self.name}: the link to the pilot is back")
        return Verdict(f"{self.name}: the link to the pilot is back; the link-loss policy "
                       f"{left.value} the module {ago:.0f} s ago and it stays {left.value} "
                       f"until the pilot {undo} it")
