"""Picking TCP port numbers for servers started by launchers, tests and benchmarks.

Numbers come from below the kernel's ephemeral range (32768 and up on Linux):
there, an outgoing connection can take a number between the check and the
moment a server (or the ports it hands numbers to) binds it.

A name server hands out the numbers after its own (``socket + 2`` upward, as
yarpserver does) without checking them, and the programs that will bind them
may start much later.  So a run given out here is remembered for the life of
this process and never given out again, even while it still looks free.
"""

from __future__ import annotations

import random
import socket
import threading
from typing import Dict, List, Tuple

_given: List[range] = []
_cursor: Dict[Tuple[int, int], int] = {}   # region -> where the next search starts
_lock = threading.Lock()


def is_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
            return True
        except OSError:
            return False


#: Single numbers (bridge links, one-off servers) come from the bottom of the range and runs
#: (a name server and the numbers it hands out) from above it: singles are rarely released,
#: and scattered among the runs they would leave no room for a run of 400 (a CI failure).
SINGLES = 3000


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
    with _lock:
        first = _cursor.get((start, end), random.randint(start, last))
        first = first if start <= first <= last else start
        for lo, hi in ((first, last), (start, first - 1)):
            base = lo
            while base <= hi:
                clash = next((taken for taken in _given
                              if base < taken.stop and taken.start < base + span), None)
                if clash is not None:
                    base = clash.stop
                    continue
                busy = next((base + offset for offset in range(span)
                             if not is_free(base + offset)), None)
                if busy is not None:
                    base = busy + 1
                    continue
                _given.append(range(base, base + span))
                _cursor[start, end] = base + span
                return base
    raise RuntimeError(f"no run of {span} free TCP ports between {start} and {end}")


def release(base: int) -> None:
    """The run starting at ``base`` may be given out again (its server has stopped)."""
    with _lock:
        _given[:] = [taken for taken in _given if taken.start != base]
