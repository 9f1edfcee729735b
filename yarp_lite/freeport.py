"""Picking TCP port numbers for servers started by launchers, tests and benchmarks.

Theory of operation
-------------------
Numbers come from below the kernel's ephemeral range (32768 and up on Linux):
there, an outgoing connection can take a number between the check and the
moment a server (or the ports it hands numbers to) binds it.

A name server hands out the numbers after its own (``socket + 2`` upward, as
yarpserver does) without checking them, and the programs that will bind them
may start much later.  So a run given out here is remembered and never given
out again, even while it still looks free -- and remembered for the whole
machine, not one process: two test runs (or pytest-xdist workers, or a bench
beside a suite) each checking only their own memory handed the same unbound
run to two name servers.  The memory is one small file (``registry_path()``),
read and rewritten under ``flock``; each run is stored with the process that
was given it (pid and its kernel start time, so a reused pid does not keep a
dead process's runs), and runs of processes that have ended are dropped on
every read.
"""

from __future__ import annotations

import fcntl
import json
import os
import random
import socket
import tempfile
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Tuple

_cursor: Dict[Tuple[int, int], int] = {}   # region -> where the next search starts
_lock = threading.Lock()

#: Single numbers (bridge links, one-off servers) come from the bottom of the range and runs
#: (a name server and the numbers it hands out) from above it: singles are rarely released,
#: and scattered among the runs they would leave no room for a run of 400 (a CI failure).
SINGLES = 3000


def is_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
            return True
        except OSError:
            return False


def registry_path() -> Path:
    """Where the machine's given runs are kept (``YARP_LITE_PORT_REGISTRY`` overrides)."""
    explicit = os.environ.get("YARP_LITE_PORT_REGISTRY")
    if explicit:
        return Path(explicit)
    return Path(tempfile.gettempdir()) / f"yarp-lite-ports-{os.getuid()}.json"


def _start_time(pid: int) -> Optional[str]:
    """The kernel's start time of ``pid`` (field 22 of /proc/pid/stat), None if it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]


@dataclass(frozen=True)
class Given:
    """A run of numbers and the process it was given to."""

    start: int
    stop: int
    pid: int
    started: str

    def overlaps(self, base: int, span: int) -> bool:
        return base < self.stop and self.start < base + span


@contextmanager
def _registry() -> Iterator[List[Given]]:
    """The live runs, locked for the whole machine; what the caller leaves in it is saved."""
    path = registry_path()
    with _lock, open(path, "a+", encoding="utf-8") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        handle.seek(0)
        try:
            rows = json.loads(handle.read() or "[]")
            given = [Given(int(r["start"]), int(r["stop"]), int(r["pid"]), str(r["started"]))
                     for r in rows]
        except (ValueError, KeyError, TypeError):
            given = []   # a torn or foreign file: forget it rather than refuse every port
        started = {pid: _start_time(pid) for pid in {g.pid for g in given}}
        given = [g for g in given if started[g.pid] == g.started]
        yield given
        handle.seek(0)
        handle.truncate()
        handle.write(json.dumps([g.__dict__ for g in given]))
        handle.flush()


def free_port(span: int = 1, start: int = 11000, end: int = 32000) -> int:
    """A port such that ``port .. port + span - 1`` are free and not given out before.

    Next fit from where this process last gave out (first from a random
    point), wrapping around: one process packs its runs side by side (random
    bases fragment the range until no run of 400 fits), another process most
    likely starts elsewhere, and every base is reachable, so a free run is
    found whenever one exists.  A number still in TIME_WAIT
    after its server stopped only rules out the runs that contain it.
    """
    if end - start > 2 * SINGLES:
        start, end = (start, start + SINGLES) if span == 1 else (start + SINGLES, end)
    last = end - span - 1          # the highest base (``end`` itself is never given)
    if last < start:
        raise RuntimeError(f"no run of {span} free TCP ports between {start} and {end}")
    me = os.getpid()
    started = _start_time(me) or ""
    with _registry() as given:
        first = _cursor.get((start, end), random.randint(start, last))
        first = first if start <= first <= last else start
        for lo, hi in ((first, last), (start, first - 1)):
            base = lo
            while base <= hi:
                clash = next((taken for taken in given if taken.overlaps(base, span)), None)
                if clash is not None:
                    base = clash.stop
                    continue
                busy = next((base + offset for offset in range(span)
                             if not is_free(base + offset)), None)
                if busy is not None:
                    base = busy + 1
                    continue
                given.append(Given(base, base + span, me, started))
                _cursor[start, end] = base + span
                return base
    raise RuntimeError(f"no run of {span} free TCP ports between {start} and {end}")


def release(base: int) -> None:
    """The run starting at ``base`` may be given out again (its server has stopped)."""
    me = os.getpid()
    with _registry() as given:
        given[:] = [taken for taken in given if not (taken.start == base and taken.pid == me)]
