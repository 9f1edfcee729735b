"""A pilot command's life, as every pilot station sees it: one small state machine.

Theory of operation
-------------------
::

    sent --> queued --> delivered --> accepted --> interrupted (why)
      |        |            |     \\-> refused (why)
      |        |            +------> expired
      |        |            \\------> interrupted (why)
      |        \\--> cancelled
      \\--------------------------> (any later state)

Each place that holds a command says what it knows, in a *receipt*
``seq state [reason]``: the gateway that it left (``sent``, or ``queued``
when the link is down), the pilot bridge that a cancel took it out of its
queue (``cancelled``), the robot bridge that it wrote it to the module's port
(``delivered``), the module that it took it (``accepted``) or would not
(``refused``, ``expired``, with the reason), or the module's next process that
the one before it died holding it (``interrupted``: never run again, and maybe
begun if it had been accepted; :mod:`walkman.gym.inbox_journal`).  Receipts cross the link on
their own reliable flow (``/M/receipt:o``), so they are never lost, but
what different places say may still arrive out of order (the module's
``accepted`` before the robot bridge's ``delivered``): a state only moves
*forward* (:data:`RANK`), a terminal state (:data:`TERMINAL`) never changes, and a receipt
that would move a command back is ignored, not an error.

Pure: receipts in, the new state (or None) out.  The gateway keeps one
:class:`CommandLife` per command it has heard of.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum
from typing import Dict, List, Optional, Sequence, Tuple

from yarp_lite.bottle import Bottle


class CommandState(str, Enum):
    SENT = "sent"
    QUEUED = "queued"
    DELIVERED = "delivered"
    ACCEPTED = "accepted"
    REFUSED = "refused"
    EXPIRED = "expired"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"


#: How far along each state is: a command only moves to a higher rank.
RANK: Dict[CommandState, int] = {
    CommandState.SENT: 0, CommandState.QUEUED: 1, CommandState.DELIVERED: 2,
    CommandState.ACCEPTED: 3, CommandState.REFUSED: 3, CommandState.EXPIRED: 3,
    CommandState.CANCELLED: 3, CommandState.INTERRUPTED: 4,
}
#: States after which nothing more is said: ``accepted`` is not one, its module's process
#: may still die before the tick that took it ends (``interrupted``).
TERMINAL = frozenset({CommandState.REFUSED, CommandState.EXPIRED, CommandState.CANCELLED,
                      CommandState.INTERRUPTED})


class ReceiptError(ValueError):
    """A receipt Bottle is malformed; the text says how."""


@dataclass(frozen=True)
class Receipt:
    seq: int
    state: CommandState
    reason: str = ""


def encode_receipt(receipt: Receipt) -> Bottle:
    """``seq state [reason]``."""
    return Bottle([receipt.seq, receipt.state.value, *([receipt.reason] if receipt.reason
                                                       else [])])


def decode_receipt(bottle: Sequence) -> Receipt:
    if len(bottle) not in (2, 3) or isinstance(bottle[0], bool) or \
            not isinstance(bottle[0], int) or not isinstance(bottle[1], str):
        raise ReceiptError(f"a receipt is seq state [reason], got {Bottle(list(bottle))}")
    try:
        state = CommandState(str(bottle[1]))
    except ValueError:
        raise ReceiptError(f"unknown command state {bottle[1]!r} (one of "
                           f"{', '.join(s.value for s in CommandState)})") from None
    reason = bottle[2] if len(bottle) == 3 else ""
    if not isinstance(reason, str):
        raise ReceiptError(f"a receipt's reason is text, got {reason!r}")
    return Receipt(int(bottle[0]), state, str(reason))


@dataclass(frozen=True)
class CommandLife:
    """What a station knows of one command."""

    module: str
    port: str            # "switch" or "command"
    seq: int
    text: str            # as the pilot typed it
    sender: str = ""
    station: int = 0
    state: CommandState = CommandState.SENT
    reason: str = ""

    def moved(self, state: CommandState, reason: str = "") -> Optional["CommandLife"]:
        """This command after ``state`` was said of it; None when that changes nothing
        (a state it has passed already, or it has ended)."""
        if self.state in TERMINAL or RANK[state] <= RANK[self.state]:
            return None
        return replace(self, state=state, reason=reason)


def describe(life: CommandLife) -> str:
    """One line for a pilot's log: "`turn 1.57` (seq 42) to drc_valve: expired: ..."."""
    why = f": {life.reason}" if life.reason else ""
    return f"`{life.text}` (seq {life.seq}) to {life.module}: {life.state.value}{why}"


def key_of(life: CommandLife) -> Tuple[str, int]:
    return life.module, life.seq


class Ledger:
    """Every command a station has heard of, with its latest state; bounded.

    Each method returns the lives whose state changed (to publish), in order.
    """

    def __init__(self, limit: int = 2000) -> None:
        self.limit = limit
        self._lives: Dict[Tuple[str, int], CommandLife] = {}
        #: Receipts that came before their command was recorded as sent: a module on the
        #: same machine can answer before the gateway's send returns (the lab topology).
        self._early: Dict[Tuple[str, int], List[Receipt]] = {}

    def get(self, module: str, seq: int) -> Optional[CommandLife]:
        return self._lives.get((module, seq))

    def sent(self, life: CommandLife, link_down: bool = False) -> List[CommandLife]:
        """A command left a gateway (ours or another station's)."""
        if (life.module, life.seq) in self._lives:
            return []    # heard of it already (our own, echoed by another station)
        if link_down:
            life = replace(life, state=CommandState.QUEUED, reason="the link is down")
        self._lives[key_of(life)] = life
        while len(self._lives) > self.limit:
            del self._lives[next(iter(self._lives))]
        changed = [life]
        for receipt in self._early.pop(key_of(life), []):
            changed += self.receipt(life.module, receipt)
        return changed

    def receipt(self, module: str, receipt: Receipt) -> List[CommandLife]:
        """What a place that held the command said of it."""
        life = self._lives.get((module, receipt.seq))
        if life is None:
            self._early.setdefault((module, receipt.seq), []).append(receipt)
            while len(self._early) > self.limit:
                del self._early[next(iter(self._early))]
            return []
        moved = life.moved(receipt.state, receipt.reason)
        if moved is None:
            return []
        self._lives[key_of(moved)] = moved
        return [moved]

    def link_down(self) -> List[CommandLife]:
        """The link went down: what had only been sent now waits for it."""
        changed = []
        for life in list(self._lives.values()):
            if life.state is CommandState.SENT:
                moved = replace(life, state=CommandState.QUEUED, reason="the link is down")
                self._lives[key_of(moved)] = moved
                changed.append(moved)
        return changed

    def waiting(self, module: str) -> List[CommandLife]:
        """The module's commands not yet delivered (what a cancel could still catch)."""
        return [life for life in self._lives.values() if life.module == module and
                RANK[life.state] < RANK[CommandState.DELIVERED]]
