"""Robots take turns on a machine: the ``free_standing``, ``two_pcs`` and ``alone`` marks.

Theory of operation.  A simulated robot with the harness off balances on its own feet: its
physics (SCHED_FIFO 60), the threads that carry its states (55) and its walking loop (50)
must run on time, and they do beside any amount of normal-priority load -- up to a point
the kernel sets.  Linux (6.12 and later: the "fair server") gives normal tasks 50 ms in
every second on a CPU whose real-time threads would otherwise starve them, and it takes
those 50 ms *at once*: a FIFO thread busy 96 % of a CPU beside one normal busy loop stalls
54-56 ms once a second; at 90 % never beyond 5 ms (``bench/bench_rt_budget.py``).
A free-standing robot's real-time threads take about one of this machine's two cores
(physics 35-45 %, walking's loop 30-37 %, the state ports 20 %, measured per thread while
it walks); a second robot's -- a free-standing one, or the harnessed robot of a two-PC
topology with its radio stage at 70 -- takes 0.3-1 core more, and a CPU then crosses the
budget.  Fresh-clone run fc74 (2026-11-28, quiet): the walking robot's physics stalled
52 ms and its loop 59 ms, and the balance guard tripped; ticks of 33 ms were logged beside
another robot in fc15, fc16 and the run of 2026-11-27.  A real Walk-Man has a computer to
itself; the suite's two workers do not.  So a test marked ``free_standing`` has the machine
to itself, as ``alone`` does (:func:`machine_share`).

A test marked ``two_pcs`` starts both PCs of the drc topology -- a simulated robot with its
modules, both bridges, the emulated radio and the pilot's side -- and judges what a pilot
would see on time: a status no older than its widget's bound, a stop that reaches every
module.  Every thread of those PCs but the PI's runs real-time (the bridges at 5, the
modules' readers at 10, the radio at 70): 1.1-1.5 CPUs of the two, sampled per thread.
Beside another topology it is over the budget: fc68 (2026-11-28) read ``drc_wall`` as "not
running", its status 10.8 s stale, while another two-PC test ran on the other worker, and
fc76 (2026-11-29, two CPU burners) logged the HAL's physics stalled 52-54 ms while the PI
drove, and the steering wheel ended 15 degrees from where the slider had put it.  Such tests
first took turns among themselves (one slot per two cores); they now have the machine to
themselves as well.

A test marked ``alone`` has the machine to itself too: the PI's courses with the harness off
walk a free-standing robot through the drc topology.  Every other test holds the machine
shared (:func:`machine_share`).

The machine is a ``flock`` on a file under the system's temporary folder: the kernel releases
it when its holder dies, so a killed run never leaves it taken.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

#: Where the machine's lock files live (machine-wide: every pytest run on the machine shares them).
SLOT_FOLDER = Path(tempfile.gettempdir()) / "walkman-free-standing-robots"


#: The marks that give a test the machine to itself.
MACHINE_TO_ITSELF = frozenset({"alone", "free_standing", "two_pcs"})


def machine_to_itself(marks: Iterable[str]) -> bool:
    """Whether a test with these marks runs with the machine to itself."""
    return not MACHINE_TO_ITSELF.isdisjoint(marks)


def shared_folder(folder: Path) -> None:
    """``folder``, made writable by every user of the machine (as /tmp is) if we make it."""
    try:
        folder.mkdir(parents=True)
    except FileExistsError:
        return
    os.chmod(folder, 0o1777)


@contextmanager
def machine_share(alone: bool, folder: Path = SLOT_FOLDER) -> Iterator[float]:
    """Hold the machine for the block, to ourselves (``alone``) or shared with every other
    test not alone; yields how long it waited (s).  A test waiting to be alone goes before
    any test that comes later (it holds the turnstile while it waits), so a stream of
    shared tests on another worker cannot keep it out."""
    shared_folder(folder)
    began = time.monotonic()
    turnstile = os.open(folder / "turnstile.lock", os.O_RDONLY | os.O_CREAT, 0o666)
    machine = os.open(folder / "machine.lock", os.O_RDONLY | os.O_CREAT, 0o666)
    try:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            fcntl.flock(machine, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        yield time.monotonic() - began
    finally:
        os.close(machine)           # closing the last descriptor releases its lock
        os.close(turnstile)
