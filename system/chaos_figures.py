"""The chaos run's schedule and figures, as pure functions over what was recorded.

Theory of operation
-------------------
Nothing here touches a process: :func:`schedule` turns a seed into the faults
of every round, :func:`blackouts` into a soak's link cuts, and the rest turns
the records of :mod:`system.chaos_record` into the figures of
:mod:`system.chaos_report`:

* ``sent``: what the gateway logged as written to the module's command port,
  ``(N, seq)`` in the order it wrote them -- a write the bridge acknowledged
  once the command was in its journal, so from then on the bridge owes its
  delivery, or an ending the pilot can see (expired, cancelled);
* ``executed``: the witness module's own log, one sequence number per command
  run, in the order it ran them, with when it started and the lifetime it
  arrived with;
* ``ended``: the commands that ended without running, and how (``expired``,
  ``cancelled``, ``interrupted``: the module's process died holding it and its next
  process said so), from the pilot's view of their lives and the programs' logs;
* ``statuses``: every ``/M/status`` message the pilot received, with its time.

A command is *lost* when it was sent, never executed, and did not end as
expired, cancelled or interrupted; *duplicated* when it ran more than once, *out of order*
when it ran after a command sent later had already run.  A command that ran
without ever being logged as sent is counted apart (*unacknowledged*): the
gateway was killed between the write and its log line, and neither the pilot
nor the figures can say more.  A command that ran is *late* when it started
after its deadline (:func:`deadlines`) and a *cancelled one that ran* when the
pilot had been told it was taken back: both must never happen.
"""

from __future__ import annotations

import math
import random
import statistics
from dataclasses import dataclass, field
from typing import Callable, Collection, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

LINK = "link"
#: How a process dies: the whole program (its group and children) gets SIGKILL.
KILL = "kill -9"
#: How the link is cut: ``ip link down`` (the senders see it) or 100 % loss (they do not).
LINK_CUTS = ("flap", "blackout")
PROCESS_DOWN = (0.5, 3.0)    # s a killed program stays dead before its launcher restarts it
LINK_DOWN = (1.0, 15.0)      # s a link cut lasts: around the bridges' 5 s link timeout
LEAD = (0.0, 2.0)            # s of normal work before the fault, so it hits any phase


@dataclass(frozen=True)
class Fault:
    """One round's fault: what is killed (or the link), when and for how long."""

    round: int
    victim: str      # "<pc>:<program>" as the topology names it, or "link"
    lead: float      # s of normal operation first
    down: float      # s until the program is started again / the link is back
    how: str         # KILL, "flap" or "blackout"


def schedule(seed: int, rounds: int, victims: Sequence[str]) -> List[Fault]:
    """The faults of ``rounds`` rounds; the same seed gives the same faults."""
    if not victims:
        raise ValueError("no victims to choose from")
    rng = random.Random(seed)
    faults = []
    for number in range(1, rounds + 1):
        victim = rng.choice(list(victims))
        lead = round(rng.uniform(*LEAD), 2)
        if victim == LINK:
            faults.append(Fault(number, victim, lead, round(rng.uniform(*LINK_DOWN), 2),
                                rng.choice(LINK_CUTS)))
        else:
            faults.append(Fault(number, victim, lead, round(rng.uniform(*PROCESS_DOWN), 2),
                                KILL))
    return faults


def blackouts(seed: int, duration: float, gap: Tuple[float, float] = (30.0, 120.0),
              length: Tuple[float, float] = (1.0, 30.0)) -> List[Tuple[float, float]]:
    """A soak's link cuts as ``(start, seconds)`` offsets, DARPA style: 1-30 s, now and then."""
    rng = random.Random(seed)
    cuts, at = [], 0.0
    while True:
        at += rng.uniform(*gap)
        seconds = rng.uniform(*length)
        if at + seconds >= duration:
            return cuts
        cuts.append((round(at, 2), round(seconds, 2)))
        at += seconds


# -- commands ---------------------------------------------------------------------------------


EXPIRED, CANCELLED, INTERRUPTED = "expired", "cancelled", "interrupted"
#: Seconds a command's wall-clock age may exceed its validity when it starts: the hops its
#: lifetime does not count (the gateway's write into the pilot bridge, the wire between the
#: bridges, the robot bridge's write into the module: milliseconds, 0.13 s on a degraded
#: radio).  The pilot's send time is read after the gateway answered, which errs the other way.
DEADLINE_SLACK = 0.5


@dataclass
class Commands:
    """What happened to the numbered commands; every list holds gateway sequence numbers."""

    sent: int = 0
    accepted: int = 0
    executed: int = 0
    lost: List[int] = field(default_factory=list)
    duplicated: List[int] = field(default_factory=list)
    out_of_order: List[int] = field(default_factory=list)
    unacknowledged: List[int] = field(default_factory=list)
    #: pilot numbers that ran under two sequence numbers: the pilot tried again after a call
    #: that failed without saying whether it went through (not the system's doing)
    retried_twice: List[int] = field(default_factory=list)
    #: sent, not run, and accounted for: refused as too old, or taken back by the pilot
    expired: List[int] = field(default_factory=list)
    cancelled: List[int] = field(default_factory=list)
    #: sent, not run, and told: the module's process died holding it (killed with it)
    interrupted: List[int] = field(default_factory=list)


def commands(sent: Sequence[Tuple[int, int]], accepted: Sequence[int],
             executed: Sequence[int], ended: Mapping[int, str] = {}) -> Commands:
    """Lost, duplicated and out-of-order commands from ``(N, seq)`` sent, seqs executed and
    how the others ended (``ended``: seq -> :data:`EXPIRED`, :data:`CANCELLED` or
    :data:`INTERRUPTED`)."""
    order = {seq: index for index, (_, seq) in enumerate(sent)}
    number = {seq: n for n, seq in sent}
    out = Commands(sent=len(order), accepted=len(accepted), executed=len(executed))
    ran: Dict[int, int] = {}
    latest = -1
    for seq in executed:
        ran[seq] = ran.get(seq, 0) + 1
        if ran[seq] > 1:
            out.duplicated.append(seq)
            continue
        if seq not in order:
            out.unacknowledged.append(seq)
            continue
        if order[seq] < latest:
            out.out_of_order.append(seq)
        latest = max(latest, order[seq])
    for _, seq in sent:
        if seq in ran:
            continue
        how = ended.get(seq)
        {EXPIRED: out.expired, CANCELLED: out.cancelled,
         INTERRUPTED: out.interrupted}.get(how, out.lost).append(seq)
    runs_of: Dict[int, int] = {}
    for seq in ran:
        if seq in number:
            runs_of[number[seq]] = runs_of.get(number[seq], 0) + 1
    out.retried_twice = sorted(n for n, count in runs_of.items() if count > 1)
    return out


def endings(expired: Collection[int], cancelled: Collection[int],
            interrupted: Collection[int] = ()) -> Dict[int, str]:
    """seq -> how it ended without running; a cancel the bridge confirmed wins (a command
    it took back never reached the module that could have called it expired)."""
    ended = {seq: INTERRUPTED for seq in interrupted}
    ended.update({seq: EXPIRED for seq in expired})
    ended.update({seq: CANCELLED for seq in cancelled})
    return ended


@dataclass
class Deadlines:
    """Whether the commands that ran were still allowed to."""

    #: executed commands that had a validity of their own (short-lived ones)
    checked: int = 0
    #: started after their deadline: arrived already too old, started later than the pilot's
    #: send time + validity (+ :data:`DEADLINE_SLACK`), or said expired yet ran
    late: List[int] = field(default_factory=list)
    #: ran although the pilot was told they had been taken back
    cancelled_ran: List[int] = field(default_factory=list)
    #: the least time any checked command had left when it started (negative: late)
    closest_s: Optional[float] = None


def deadlines(executions: Sequence, asked: Mapping[int, Tuple[float, float]],
              ended: Mapping[int, str], slack: float = DEADLINE_SLACK) -> Deadlines:
    """Check every execution (``seq``, ``at``, ``age``, ``validity``, ``arrived_expired``:
    :class:`walkman.modules.witness.Execution`) against its deadline and its ending.

    ``asked``: seq -> (the pilot's send time, the validity it asked for; 0: none), both
    on the wall clock the witness also reads (one machine, or hosts sharing its kernel).
    """
    out = Deadlines()
    for execution in executions:
        seq = execution.seq
        if ended.get(seq) == CANCELLED:
            out.cancelled_ran.append(seq)
        sent_at, validity = asked.get(seq, (None, 0.0))
        late = execution.arrived_expired or ended.get(seq) == EXPIRED
        if validity and sent_at is not None and execution.at is not None:
            out.checked += 1
            left = sent_at + validity - execution.at
            out.closest_s = left if out.closest_s is None else min(out.closest_s, left)
            late = late or left < -slack
        if late:
            out.late.append(seq)
    return out


# -- recovery ---------------------------------------------------------------------------------


def first_fresh(statuses: Sequence[dict], module: str, back: float) -> Optional[float]:
    """When the pilot first had news of ``module`` after ``back`` (the fault's end).

    News is a status other than the last one received before ``back``: a gateway
    or roscore coming back publishes its latched last status again, which tells
    nothing new.  Statuses carry a sequence number that moves every 0.5 s.
    """
    before = [(s["seq"], s["state"]) for s in statuses
              if s["module"] == module and s["t"] < back]
    last = before[-1] if before else None
    for status in statuses:
        if status["module"] == module and status["t"] >= back and \
                (status["seq"], status["state"]) != last:
            return status["t"]
    return None


def percentile(values: Sequence[float], share: float) -> Optional[float]:
    """The nearest-rank percentile (``share`` in 0..1): a value that was measured."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


# -- soak -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Growth:
    start: float     # median over the window after the warm-up
    end: float       # median over the last window
    percent: float


def growth(samples: Sequence[Tuple[float, float]], warm_up: float,
           statistic: Callable[[Iterable[float]], float] = statistics.median
           ) -> Optional[Growth]:
    """How much a sampled value grew from after ``warm_up`` s to the end of the samples.

    ``statistic`` (median, or min for a floor) over windows of a tenth of the
    span (three samples at least), so one garbage collection or one open
    connection at the wrong moment does not count.
    """
    if not samples:
        return None
    first_t = samples[0][0]
    settled = [(t, v) for t, v in samples if t - first_t >= warm_up] or list(samples)
    width = max(3, len(settled) // 10)
    start = statistic([v for _, v in settled[:width]])
    end = statistic([v for _, v in settled[-width:]])
    percent = 100.0 * (end - start) / start if start else (0.0 if end == start else math.inf)
    return Growth(start, end, percent)


#: slack for a journal's page-granular growth (SQLite grows its files by pages and WAL frames)
JOURNAL_SLACK = 256 * 1024


def bounded(samples: Sequence[Tuple[float, float]]) -> bool:
    """Whether a size stopped growing: the second half's peak is within 10 % (plus
    :data:`JOURNAL_SLACK`) of the first half's.  A leak keeps setting new peaks."""
    if len(samples) < 4:
        return True
    half = len(samples) // 2
    first = max(v for _, v in samples[:half])
    second = max(v for _, v in samples[half:])
    return second <= first * 1.1 + JOURNAL_SLACK


def soak_figures(samples: Sequence[dict], every: float) -> dict:
    """Growth of RSS and open files per process, journal sizes, from a soak's samples
    (``{"t", "procs": {key: [rss KiB, files]}, "journal": {side: {"db", "wal"}}}``)."""
    if not samples:
        return {"processes": {}, "journal": {}}
    span = samples[-1]["t"] - samples[0]["t"]
    warm_up = min(120.0, 0.2 * span)
    series: Dict[str, List[Tuple[float, List[int]]]] = {}
    for sample in samples:
        for key, values in sample["procs"].items():
            series.setdefault(key, []).append((sample["t"], values))
    processes = {}
    for key, points in sorted(series.items()):
        rss = growth([(t, v[0]) for t, v in points], warm_up)
        # the floor: a name server's count goes 5, 6, 5 with each query; a leak raises it
        fds = growth([(t, v[1]) for t, v in points], warm_up, statistic=min)
        processes[key] = {"rss_kib": [rss.start, rss.end], "rss_percent": rss.percent,
                          "files": [fds.start, fds.end], "files_percent": fds.percent,
                          "samples": len(points)}
    journal = {}
    for side in ("robot", "pilot"):
        parts = [s["journal"][side] for s in samples]
        sizes = [(s["t"], sum(part.values())) for s, part in zip(samples, parts)]
        journal[side] = {"first": sizes[0][1], "max": max(v for _, v in sizes),
                         "last": sizes[-1][1], "max_db": max(p["db"] for p in parts),
                         "max_wal": max(p["wal"] for p in parts),
                         "bounded": bounded(sizes)}
    return {"processes": processes, "journal": journal, "span_s": span, "every_s": every}
