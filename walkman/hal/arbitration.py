"""Who may command which joint: the HAL's arbitration between modules.

Theory of operation
-------------------
The EtherCAT master of the paper took references from every module at once;
at the DRC the walking and door modules used the same joints and the pilots
had to pause one before running the other (paper, section 3.3).  Here the HAL
enforces it.  Every command names its owner (the module whose port sent it);
each joint remembers its holder and when the holder last commanded it.  A
holder silent for ``release_after`` seconds (paused, stopped, crashed) lets
its joints go.  What happens when another owner wants a held joint is the
configured policy:

``refuse``    (default) the first holder keeps the joint; the newcomer's
              references for it are dropped, its other joints are applied.
``priority``  the owner with the higher priority (ini ``[arbitration]``
              ``priority walking 1 drc_door 2``) takes the joint over; a lower
              one is refused while the higher one holds it.  Unlisted owners
              have priority 0; equal priorities behave as ``refuse``.
``share``     everything is applied (last command wins), as the original
              master did; still warned about, once per pair.

Every refusal or takeover yields a :class:`Conflict` for the HAL to log and
publish, at most once per (owner, holder) pair every ``warn_every`` seconds.
Pure logic with the clock passed in, so it is tested without a HAL.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

POLICIES = ("refuse", "priority", "share")


@dataclass(frozen=True)
class Conflict:
    owner: str          # who sent the command
    holder: str         # who held the joints
    joints: Tuple[str, ...]
    action: str         # "refused", "took over" or "shared"

    def text(self) -> str:
        joints = ", ".join(self.joints)
        if self.action == "refused":
            return (f"HAL: {self.owner} may not command {joints}: held by {self.holder} "
                    f"(pause or stop {self.holder} first)")
        if self.action == "took over":
            return f"HAL: {self.owner} took {joints} over from {self.holder} (higher priority)"
        return f"HAL: {self.owner} and {self.holder} both command {joints} (policy share)"


@dataclass
class Decision:
    allowed: List[int] = field(default_factory=list)
    conflicts: List[Conflict] = field(default_factory=list)


def owner_of(source: str) -> str:
    """The module behind a command port: ``/drc_door/robot/left_arm/command:o`` -> ``/drc_door``;
    a YARP remote_controlboard's ``<local>/command:o`` and ``<local>/rpc:o`` -> ``<local>``."""
    head, marker, _ = source.partition("/robot/")
    if marker and head:
        return head
    for suffix in ("/command:o", "/rpc:o"):
        if source.endswith(suffix) and len(source) > len(suffix):
            return source[:-len(suffix)]
    return source


class JointArbiter:
    def __init__(self, joint_names: Sequence[str], policy: str = "refuse",
                 priorities: Optional[Mapping[str, int]] = None, release_after: float = 0.5,
                 warn_every: float = 5.0) -> None:
        if policy not in POLICIES:
            raise ValueError(f"arbitration policy must be one of {', '.join(POLICIES)}, "
                             f"got {policy!r}")
        if not release_after > 0:
            raise ValueError(f"release_after must be positive, got {release_after}")
        self.joint_names = list(joint_names)
        self.policy = policy
        self.priorities = {name.strip("/"): int(value) for name, value in (priorities or {}).items()}
        self.release_after = release_after
        self.warn_every = warn_every
        self.holder: List[Optional[str]] = [None] * len(self.joint_names)
        self.last_seen: List[float] = [0.0] * len(self.joint_names)
        self._warned: Dict[Tuple[str, str, str], float] = {}
        self.refused = 0

    def priority(self, owner: str) -> int:
        return self.priorities.get(owner.strip("/"), 0)

    def holders(self, now: float) -> Dict[str, str]:
        """Joint -> holder, for the joints held right now."""
        return {name: holder for name, holder, seen in
                zip(self.joint_names, self.holder, self.last_seen)
                if holder is not None and now - seen <= self.release_after}

    def filter(self, owner: str, joints: Sequence[int], now: float) -> Decision:
        """Which of ``joints`` (whole-body indices) ``owner`` may command now."""
        decision = Decision()
        refused: Dict[Tuple[str, str], List[str]] = {}
        for joint in joints:
            holder = self.holder[joint]
            free = holder is None or holder == owner or \
                now - self.last_seen[joint] > self.release_after
            if not free:
                assert holder is not None
                if self.policy == "share":
                    refused.setdefault((holder, "shared"), []).append(self.joint_names[joint])
                elif self.policy == "priority" and self.priority(owner) > self.priority(holder):
                    refused.setdefault((holder, "took over"), []).append(self.joint_names[joint])
                else:
                    refused.setdefault((holder, "refused"), []).append(self.joint_names[joint])
                    self.refused += 1
                    continue
            self.holder[joint] = owner
            self.last_seen[joint] = now
            decision.allowed.append(joint)
        for (holder, action), names in refused.items():
            key = (owner, holder, action)
            if now - self._warned.get(key, -1e9) >= self.warn_every:
                self._warned[key] = now
                decision.conflicts.append(Conflict(owner, holder, tuple(names), action))
        return decision
