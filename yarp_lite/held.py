"""Messages an output port keeps for readers that connect later: pure bookkeeping.

Theory of operation
-------------------
A YARP output port with no reader drops what it writes.  For a stream where
only the newest value matters (a status, a joint state) that is right; for a
message that says something once -- a GYM module's receipts and warnings -- a
reader that connects a moment later (a robot bridge restarted after a crash)
has lost it for good.

A port told to hold (:meth:`yarp_lite.port.Port.hold_for_late_readers`) keeps
its last ``count`` messages, none older than ``max_age`` seconds, each with
the names of the readers that took it.  When it makes an output connection to
``/r`` it first sends ``/r`` the held messages ``/r`` has not taken, oldest
first, then whatever is written after.  So:

* a message written while no reader was connected reaches the first reader
  that connects within ``max_age``;
* a reader back under its old name (a restarted process) gets what it missed,
  not what its predecessor took: no duplicates for a reader that keeps what it
  acknowledges (the bridge's journal commits before it acknowledges);
* a new reader (a ``yarp read`` opened to look) gets the recent history, as a
  latched ROS topic gives a new subscriber its last message.

"Taken" means the connection's send returned: the reader acknowledged it on
``tcp``; on ``udp``, which promises nothing more, the datagram left.

The port does the locking: :meth:`HeldMessages.written` runs together with the
write's snapshot of the outputs, :meth:`HeldMessages.owed` together with adding
the new output, under the port's lock, so each message either goes to a new
connection live or is handed over to it, never both and never neither.

Real YARP ports hold nothing; a yarp_lite port holds nothing unless asked.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Deque, List, Set

from yarp_lite.carriers import Payload
from yarp_lite.errors import LocalProtocolError


@dataclass(frozen=True)
class HoldPolicy:
    """How much a port keeps: the last ``count`` messages, none older than ``max_age`` s."""

    count: int
    max_age: float

    def __post_init__(self) -> None:
        if self.count < 1 or not self.max_age > 0:
            raise LocalProtocolError(f"a port holds at least one message for a positive time, "
                                     f"not count={self.count} max_age={self.max_age}")


@dataclass(eq=False)
class Held:
    """One message written, as it went on the wire, and who has taken it."""

    command: str            # "D" or "D <envelope>"
    payload: Payload
    written: float          # the clock's time when it was written
    taken_by: Set[str] = field(default_factory=set)


class HeldMessages:
    """The recent messages of one output port and the readers that took each."""

    def __init__(self, policy: HoldPolicy, clock: Callable[[], float] = time.monotonic) -> None:
        self.policy = policy
        self.clock = clock
        self._held: Deque[Held] = deque()
        #: messages that left the hold (too old, or pushed out) with no reader ever taking them
        self.never_taken = 0
        #: messages handed over to a reader that connected after they were written
        self.handed_over = 0

    def __len__(self) -> int:
        return len(self._held)

    def written(self, command: str, payload: Payload) -> Held:
        """A message was written (before it is sent to the outputs there are)."""
        self._forget_old()
        held = Held(command, payload, self.clock())
        self._held.append(held)
        while len(self._held) > self.policy.count:
            self._forget(self._held.popleft())
        return held

    def taken(self, held: Held, reader: str) -> None:
        """``reader`` has the message (its send to that reader returned)."""
        held.taken_by.add(reader)

    def owed(self, reader: str) -> List[Held]:
        """What a new connection to ``reader`` must be sent first: the held messages it
        has not taken, oldest first."""
        self._forget_old()
        return [held for held in self._held if reader not in held.taken_by]

    def handed(self, held: Held, reader: str) -> None:
        """An owed message was sent to ``reader`` on its new connection."""
        self.taken(held, reader)
        self.handed_over += 1

    def _forget_old(self) -> None:
        oldest = self.clock() - self.policy.max_age
        while self._held and self._held[0].written < oldest:
            self._forget(self._held.popleft())

    def _forget(self, held: Held) -> None:
        if not held.taken_by:
            self.never_taken += 1


__all__ = ["Held", "HeldMessages", "HoldPolicy"]
