"""``walkman-chaos --soak``: no kills, long piloting through blackouts, /proc sampled.

Theory of operation
-------------------
The pilot works for the soak's length while the link (``--profile degraded``:
9600 bit/s) blacks out for 1-30 s now and then (:func:`system.chaos_figures.blackouts`,
seeded), and every ``--sample-every`` seconds :func:`sample` reads the resident
memory and open files of every process of every program (the program and its
descendants, from /proc) and the size of both bridges' journals.  Each sample
is also a line of ``samples.jsonl``; :func:`system.chaos_figures.soak_figures`
turns them into growth figures.  A program that exits by itself is recorded
and started again, as in the rounds.
"""

from __future__ import annotations

import json
import time
from typing import Dict, List, Optional

from system import chaos_figures as figures
from system.chaos_proc import comm
from system.chaos_run import PILOT, Chaos
from system.processes import descendants, usage


def soak(chaos: Chaos, minutes: float) -> None:
    """Pilot for ``minutes`` with blackouts (when there is a link to cut), sampling."""
    duration = minutes * 60.0
    record, options = chaos.record, chaos.options
    cuts = figures.blackouts(options.seed, duration) if chaos.link else []
    began, next_sample, next_line = time.monotonic(), 0.0, 60.0
    cut: Optional[dict] = None
    with open(chaos.out / "samples.jsonl", "w") as samples:
        while (elapsed := time.monotonic() - began) < duration:
            if cut is None and cuts and elapsed >= cuts[0][0]:
                _, seconds = cuts.pop(0)
                chaos.cut_link("blackout", True)
                cut = {"at": time.time(), "seconds": seconds, "ends": elapsed + seconds}
                record.cuts.append(cut)
                chaos.progress(f"blackout for {seconds:.0f} s")
            if cut is not None and elapsed >= cut["ends"]:
                chaos.cut_link("blackout", False)
                cut["back"] = time.time()
                cut = None
            if elapsed >= next_sample:
                chaos.restart_exited()
                record.samples.append(taken := sample(chaos))
                samples.write(json.dumps(taken) + "\n")
                samples.flush()
                next_sample += options.sample_every
            if elapsed >= next_line:
                next_line += 60.0
                chaos.progress(soak_line(chaos, elapsed, duration))
            chaos.pause(0.5)
            record.soak_s = time.monotonic() - began
        if cut is not None:
            chaos.cut_link("blackout", False)
            cut["back"] = time.time()


def sample(chaos: Chaos) -> dict:
    """Resident KiB and open files of every process of every program; journal bytes."""
    procs: Dict[str, List[int]] = {}
    for pc in chaos.topology.unique_pcs():
        for name, proc in pc.processes.items():
            if name == PILOT:
                continue
            top = proc.popen.pid
            for pid in [top, *descendants(top)]:
                found = usage(pid)
                if found is None:
                    continue
                key = f"{pc.name}:{name}"
                if pid != top:
                    key += f"/{comm(pid)}:{pid}"
                procs[key] = list(found)
    return {"t": time.time(), "procs": procs, "journal": journal_bytes(chaos)}


def journal_bytes(chaos: Chaos) -> Dict[str, Dict[str, int]]:
    """Each bridge's journal: the database and its write-ahead log (which SQLite lets
    grow to about 4 MB before it starts again at its beginning)."""
    sizes = {}
    for side in ("robot", "pilot"):
        path = chaos.topology.pcs[side].root / "state" / "walkman-bridge" / side \
            / "journal.sqlite"
        sizes[side] = {part: file.stat().st_size if file.is_file() else 0
                       for part, file in (("db", path), ("wal", path.with_name(
                           "journal.sqlite-wal")))}
    return sizes


def soak_line(chaos: Chaos, elapsed: float, duration: float) -> str:
    """The soak's progress line, once a minute."""
    record = chaos.record
    soaked = figures.soak_figures(record.samples, chaos.options.sample_every)
    worst = max(soaked["processes"].items(), key=lambda kv: kv[1]["rss_percent"],
                default=(None, None))
    journal = record.samples[-1]["journal"] if record.samples else {}
    grown = (f"most grown {worst[0]} {worst[1]['rss_percent']:+.1f} % RSS"
             if worst[0] else "no samples yet")
    sizes = ", ".join(f"{side} {sum(parts.values()) // 1024} KiB"
                      for side, parts in journal.items())
    return (f"soak {elapsed / 60:.0f}/{duration / 60:.0f} min: "
            f"{len(record.executed)} commands executed, {len(record.cuts)} "
            f"blackouts; {grown}; journals {sizes}")
