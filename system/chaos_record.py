"""What a chaos run observed, and the readers of the programs' own words about commands.

Theory of operation
-------------------
A run's evidence about every numbered command comes from four places, each
read here and nowhere else:

* the **pilot's** JSON lines (:mod:`system.chaos_pilot`): statuses, the
  commands the gateway accepted (N, seq, the validity asked, whether it is to
  be cancelled), the gateway's answers to cancels, and each command's states
  from ``/pilot/command_states`` -- taken into a :class:`Record` as they come;
* the **witness's** log (:mod:`walkman.modules.witness`): what ran, when, and
  with what lifetime;
* the **gateways'** logs: ``sent to /counter/command:i: (count N) seq``, what
  every incarnation wrote to the witness's port (:func:`sent_commands`);
* the **pilot bridge's** and the **witness's** logs: a cancel the bridge made
  (``cancelled counter's command seq before it left``) and a command the
  module refused as expired (``` `count N` expired after ...```).  They outlive
  a gateway or a roscore killed in between, whose topic then never told the
  pilot (:func:`cancelled_by_bridge`, :func:`expired_at_module`).

Pure: lines in, facts out.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Dict, Iterable, List, Optional, Sequence, Set, Tuple

from system.chaos_figures import Fault
from walkman.modules.witness import Execution

#: The witness's module name in the bridge configuration, its port prefix and its commands.
WITNESS_MODULE = "counter"
SENT = re.compile(rf"gateway: sent to /{WITNESS_MODULE}/command:i: \(count (\S+)\) (\d+)")
CANCELLED = re.compile(rf"cancelled {WITNESS_MODULE}'s command (\d+) before it left")
EXPIRED = re.compile(r"`count (\S+)` expired after")


@dataclass
class RoundResult:
    fault: Fault
    pid: Optional[int] = None
    killed_at: float = 0.0
    back_at: float = 0.0
    up_s: Optional[float] = None        # the restarted program's ready line
    seen_s: Optional[float] = None      # every module's news on the pilot side
    usable_s: Optional[float] = None    # every module running, a new command executed
    seen_by_module: Dict[str, float] = field(default_factory=dict)
    problem: str = ""
    finished: bool = False              # False: interrupted in the middle


@dataclass
class Record:
    """Everything the run observed, appended as it happens."""

    statuses: Dict[str, List[dict]] = field(default_factory=dict)   # module -> pilot's view
    accepted: List[dict] = field(default_factory=list)   # n, seq, t, validity, cancel
    pilot_errors: List[dict] = field(default_factory=list)           # refused / failed calls
    switches: List[dict] = field(default_factory=list)
    cancels: List[dict] = field(default_factory=list)    # the gateway's answers to cancels
    states: Dict[int, str] = field(default_factory=dict)  # seq -> last state the pilot heard
    drained: bool = False                                 # the pilot sends no more
    executed: List[int] = field(default_factory=list)     # seqs, in the order they ran
    executions: List[Execution] = field(default_factory=list)
    rounds: List[RoundResult] = field(default_factory=list)
    exits: List[dict] = field(default_factory=list)                  # programs that died alone
    samples: List[dict] = field(default_factory=list)                # soak: /proc and journals
    cuts: List[dict] = field(default_factory=list)                   # soak: blackouts
    soak_s: float = 0.0                                              # soak: time played

    def take_pilot_event(self, event: dict) -> None:
        """One of the pilot's JSON lines, decoded."""
        kind = event.pop("ev")
        if kind == "status":
            self.statuses.setdefault(event["module"], []).append(event)
        elif kind == "sent":
            self.accepted.append(event)
        elif kind in ("refused", "failed"):
            self.pilot_errors.append({"ev": kind, **event})
        elif kind == "switch":
            self.switches.append(event)
        elif kind == "cancel":
            self.cancels.append(event)
        elif kind == "state":
            self.states[int(event["seq"])] = event["state"]
        elif kind == "drained":
            self.drained = True

    def take_execution(self, execution: Execution) -> None:
        self.executions.append(execution)
        if execution.seq is not None:
            self.executed.append(execution.seq)

    def cancelled(self) -> Set[int]:
        """Seqs the gateway said it cancelled, or whose state the pilot heard was cancelled."""
        said = {int(seq) for c in self.cancels for seq in c.get("cancelled", [])}
        return said | {seq for seq, state in self.states.items() if state == "cancelled"}

    def expired(self) -> Set[int]:
        return {seq for seq, state in self.states.items() if state == "expired"}

    def interrupted(self) -> Set[int]:
        """Seqs the pilot heard the module's next process say its dead one held."""
        return {seq for seq, state in self.states.items() if state == "interrupted"}


def sent_commands(lines: Iterable[str]) -> List[Tuple[int, int]]:
    """``(N, seq)`` a gateway logged writing to the witness's port, in its order."""
    return [(int(float(m.group(1))), int(m.group(2))) for m in map(SENT.search, lines) if m]


def cancelled_by_bridge(lines: Iterable[str]) -> Set[int]:
    """Seqs the pilot bridge logged taking back before any frame carried them."""
    return {int(m.group(1)) for m in map(CANCELLED.search, lines) if m}


def expired_at_module(lines: Iterable[str]) -> List[int]:
    """The N of every ``count N`` the witness refused as expired (its log names no seq)."""
    return [int(float(m.group(1))) for m in map(EXPIRED.search, lines) if m]


def seqs_of_numbers(numbers: Iterable[int], sent: Sequence[Tuple[int, int]],
                    ran: Set[int]) -> Set[int]:
    """The seqs behind ``numbers``: for each N, the one seq sent with it that did not run
    (an N sent twice after a failed call, with both not run, is left out: ambiguous)."""
    out = set()
    for number in set(numbers):
        candidates = [seq for n, seq in sent if n == number and seq not in ran]
        if len(candidates) == 1:
            out.add(candidates[0])
    return out
