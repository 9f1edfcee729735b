"""Lockstep: modules that join the robot's clock hold its physics until they handled their tick.

Theory of operation
-------------------
A module that only *follows* the robot's clock sees whatever state arrives when its loop
wakes: on a loaded machine the physics runs on while the module is late, and a run is never
the same twice.  A module that *joins* it holds the physics at each of its ticks until it has
handled that tick's state, so it sees exactly the states it would see at real time, however
loaded the machine is, and a run is a function of its inputs (as WB-Toolbox's
SimulatorSynchronizer does with Gazebo's ``stepSimulationAndWait``, for any number of
modules).

The wire, module -> HAL, on ``NAME/lockstep:i`` beside the clock ``NAME`` (one streaming
connection per module, so its messages arrive in the order sent)::

    join OWNER DUE                  hold the physics at the first state round whose robot
                                    time is DUE or later
    tick OWNER SEQ DUE (CHAIN...)   the round SEQ is handled; this tick's commands went to
                                    each CHAIN, each carrying (seq SEQ), a chain named once
                                    per command sent there; hold again at DUE
    leave OWNER                     do not hold the physics any more

A ``tick`` can overtake the commands it speaks of (they travel on each chain's
``command:i``), so a member also holds the physics until as many commands carrying ``SEQ``
have arrived from it on each chain as the tick named: the physics applies every command of a
tick in the step after it.

Nothing deadlocks.  The physics waits between steps, never inside one, and never longer than
``timeout`` seconds of wall time for a member: one that stalls or died leaves the barrier
with a log line, and the robot goes on without it as it does for any stalled loop (its joints
hold their last reference, then are released).  Its next ``tick`` makes it a member again.
While the physics is held the HAL keeps repeating its last state (:class:`LockstepGate`'s
``heartbeat``), so no client takes a held robot for a dead one.

:class:`Barrier` is the decision alone (messages and times in, who holds out);
:class:`LockstepGate` is the thread-safe wait around it.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple, Union

from walkman.hal.protocol import HalProtocolError
from yarp_lite.bottle import Bottle
from yarp_lite.bursts import Burst

log = logging.getLogger("walkman.hal.lockstep")

#: Robot times closer than this (s) are the same round (a module adds its period to a round's
#: time in floating point).
SAME_TIME = 1e-6
#: A member that has not handled its round after this long (wall s) leaves the barrier.
DEFAULT_TIMEOUT = 2.0
#: While held, the HAL repeats its last state this often (wall s): clients call a robot dead
#: after 0.5 s without one (:data:`walkman.hal.robot.STALE_AFTER`).
HEARTBEAT_S = 0.1
#: The longest the physics thread sleeps at once while held (wall s).
WAIT_SLICE_S = 0.05


def port_name(clock: str) -> str:
    """Where the members of the clock ``clock`` send their messages."""
    return f"{clock}/lockstep:i"


# -- the wire ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Join:
    owner: str
    due: float


@dataclass(frozen=True)
class Tick:
    owner: str
    seq: int
    due: float
    chains: Tuple[str, ...]


@dataclass(frozen=True)
class Leave:
    owner: str


Message = Union[Join, Tick, Leave]


def encode(message: Message) -> Bottle:
    if isinstance(message, Join):
        return Bottle(["join", message.owner, float(message.due)])
    if isinstance(message, Tick):
        return Bottle(["tick", message.owner, int(message.seq), float(message.due),
                       Bottle(list(message.chains))])
    return Bottle(["leave", message.owner])


def _time(value: object, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value < 0:
        raise HalProtocolError(f"lockstep: {what} must be a robot time (s, >= 0), got {value!r}")
    return float(value)


def decode(bottle: Bottle) -> Message:
    """A member's message; :class:`HalProtocolError` naming what is wrong otherwise."""
    values = list(bottle)
    verb = values[0] if values else None
    shapes = {"join": 3, "tick": 5, "leave": 2}
    if not isinstance(verb, str) or verb not in shapes:
        raise HalProtocolError(f"lockstep: unknown message {verb!r} (join, tick or leave)")
    if len(values) != shapes[verb]:
        raise HalProtocolError(f"lockstep: {verb} takes {shapes[verb] - 1} values, "
                               f"got {len(values) - 1}")
    owner = values[1]
    if not isinstance(owner, str) or not owner.startswith("/"):
        raise HalProtocolError(f"lockstep: {verb}'s owner must be a port prefix like "
                               f"/walking, got {owner!r}")
    if verb == "leave":
        return Leave(owner)
    if verb == "join":
        return Join(owner, _time(values[2], "join's due time"))
    seq, chains = values[2], values[4]
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise HalProtocolError(f"lockstep: tick's round must be a state count (int >= 0), "
                               f"got {seq!r}")
    if not isinstance(chains, Bottle) or not all(isinstance(c, str) for c in chains):
        raise HalProtocolError(f"lockstep: tick's chains must be a list of chain names, "
                               f"got {chains!r}")
    return Tick(owner, seq, _time(values[3], "tick's due time"), tuple(chains))


# -- the decision ---------------------------------------------------------------------------

@dataclass
class Member:
    owner: str
    due: float                                     # robot time of the round it handles next
    #: chain -> (the seq this member's last tick's commands there carry, how many), for the
    #: chains where not all have arrived yet
    awaited: Dict[str, Tuple[int, int]] = field(default_factory=dict)


class Barrier:
    """Who holds the physics at a round (see the module's docstring).  Not thread-safe."""

    def __init__(self) -> None:
        self.members: Dict[str, Member] = {}
        #: (owner, chain) -> the newest seq its commands carried, and how many carried it
        self._arrived: Dict[Tuple[str, str], Tuple[int, int]] = {}

    def receive(self, message: Message) -> Optional[str]:
        """Take a member's message; what it changed, for the log (None: nothing to say)."""
        owner = message.owner
        if isinstance(message, Leave):
            return f"{owner} left" if self.members.pop(owner, None) else None
        if isinstance(message, Join):
            self.members[owner] = Member(owner, message.due)
            return f"{owner} joined (holds the physics from robot time {message.due:.3f} s)"
        member = self.members.get(owner)
        said = None
        if member is None:
            member = self.members[owner] = Member(owner, message.due)
            said = f"{owner} is back (a tick after it left the barrier)"
        member.due = message.due
        member.awaited = {}
        for chain in set(message.chains):
            wanted = (message.seq, message.chains.count(chain))
            if not self._satisfied(self._arrived.get((owner, chain), (-1, 0)), wanted):
                member.awaited[chain] = wanted
        return said

    @staticmethod
    def _satisfied(arrived: Tuple[int, int], wanted: Tuple[int, int]) -> bool:
        """Commands ``arrived`` (newest seq, how many) cover ``wanted`` (seq, how many)."""
        return arrived[0] > wanted[0] or (arrived[0] == wanted[0] and arrived[1] >= wanted[1])

    def commanded(self, owner: str, chain: str, seq: int) -> bool:
        """A command from ``owner`` carrying ``seq`` arrived on ``chain``; True if a member
        was waiting for it."""
        key = (owner, chain)
        newest, count = self._arrived.get(key, (-1, 0))
        if seq > newest:
            self._arrived[key] = (seq, 1)
        elif seq == newest:
            self._arrived[key] = (seq, count + 1)
        member = self.members.get(owner)
        wanted = member.awaited.get(chain) if member is not None else None
        if wanted is not None and self._satisfied(self._arrived[key], wanted):
            del member.awaited[chain]
            return True
        return False

    def holding(self, round_time: float) -> List[str]:
        """The members that hold the physics at the round of robot time ``round_time``."""
        return sorted(m.owner for m in self.members.values()
                      if round_time >= m.due - SAME_TIME or m.awaited)

    def drop(self, owners: List[str]) -> None:
        for owner in owners:
            self.members.pop(owner, None)


# -- the wait -------------------------------------------------------------------------------

class LockstepGate:
    """The barrier for the physics thread and the ports' threads (see the module's docstring)."""

    def __init__(self, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.timeout = timeout
        self.barrier = Barrier()
        self._cond = threading.Condition()
        self._bad = Burst()
        self.held_s = 0.0        # wall seconds the physics spent held, in all
        self.dropped = 0         # members that left by the timeout

    @property
    def members(self) -> List[str]:
        with self._cond:
            return sorted(self.barrier.members)

    def receive(self, bottle: Bottle) -> None:
        """A member's message (``NAME/lockstep:i``'s reader): a malformed one is refused with
        a log line, and changes nothing."""
        try:
            message = decode(bottle)
        except HalProtocolError as exc:
            if self._bad.record():
                log.warning("HAL: refused on the lockstep port (#%d of this burst): %s",
                            self._bad.count, exc)
            return
        with self._cond:
            said = self.barrier.receive(message)
            self._cond.notify_all()
        if said:
            log.info("HAL: lockstep: %s", said)

    def commanded(self, owner: str, chain: str, seq: Optional[int]) -> None:
        """A chain took a command (its port's reader, after the chain stored it)."""
        if seq is None:
            return
        with self._cond:
            if self.barrier.commanded(owner, chain, seq):
                self._cond.notify_all()

    def hold(self, round_time: float, running: Callable[[], bool],
             heartbeat: Callable[[], None] = lambda: None) -> None:
        """The physics thread, after publishing the round of robot time ``round_time``: wait
        until no member holds it, a member times out, or ``running`` says stop."""
        if not self.barrier.members:   # no one joined: no lock taken, 500 times a second
            return
        start = time.monotonic()
        beat = start + HEARTBEAT_S
        with self._cond:
            while running():
                holders = self.barrier.holding(round_time)
                if not holders:
                    break
                now = time.monotonic()
                if now - start >= self.timeout:
                    self.barrier.drop(holders)
                    self.dropped += len(holders)
                    log.warning("HAL: lockstep: %s did not handle the round at robot time "
                                "%.3f s within %g s; %s the barrier, and the robot goes on "
                                "without it (a stalled loop)", ", ".join(holders), round_time,
                                self.timeout, "it leaves" if len(holders) == 1 else "they leave")
                    break
                if now >= beat:
                    self._cond.release()
                    try:
                        heartbeat()     # outside the lock: publishing must not block members
                    finally:
                        self._cond.acquire()
                    beat = now + HEARTBEAT_S
                    continue
                self._cond.wait(min(WAIT_SLICE_S, beat - now))
        self.held_s += time.monotonic() - start

    def refuse_reset(self) -> Optional[str]:
        """Why ``resetSimulationTime`` is refused now (None: it is not)."""
        members = self.members
        if members:
            return (f"modules are in lockstep with the robot ({', '.join(members)}); they tick "
                    "on the physics' time, which a reset does not move: /clock would go back "
                    "under them and disagree with their clocks")
        return None

    def close(self) -> None:
        with self._cond:
            self.barrier.members.clear()
            self._cond.notify_all()
