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

A test marked ``alone`` has the machine to itself too (the main job's run, the PI's valve by
clicks: the real-time smoke tests of issue 65).  The PI's courses with the harness off, which
walk a free-standing robot through the drc topology, held it until they moved onto the
lockstep clock (``lockstep``, below): there the robot waits for its modules, and a loaded
machine slows it down instead of tripping its balance guard.

"To itself" means: beside no other real-time thread.  Normal-priority load stalls a FIFO
thread only where the CPU's real-time load nears the budget, which one robot's does not (the
robot tests pass beside two CPU burners; loopback floods delay its packets through
``ksoftirqd``, 2-27 ms, ``bench/bench_rt_loopback.py``, as the burners' runs already saw).
So a test that runs no real-time thread takes no share of the machine (:data:`Share.NONE`)
and runs beside a test alone as a burner would: the tests of :data:`NO_REAL_TIME_FOLDERS`
(codecs, trajectories, yarp_lite and real YARP processes, the PI's widgets offscreen, ROS
nodes), unless marked ``real_time`` (they start a HAL), and the tests marked ``offline`` (a
robot on simulated time in the test's own process; a test alone is alone whatever else it
is marked).  While such a test runs, ``WALKMAN_NO_RT`` is set (:func:`no_real_time`): what
it starts, and what it runs in-process, stays at normal priority even if it was wrongly left
unmarked.  Every other test holds the machine shared.  The suite begins with the tests alone
on one worker while the other runs those that hold nothing (:func:`arranged`): on 2 cores
the light tests no longer wait out the minutes the PI's click tests take.  A fixture wider
than a test serves tests of one share only (:func:`one_share_per_fixture`): set up under one
test's ``WALKMAN_NO_RT``, it would start programs without real-time threads for another
that needs them, or the reverse.

The machine is a ``flock`` on a file under the system's temporary folder: the kernel releases
it when its holder dies, so a killed run never leaves it taken.
"""

from __future__ import annotations

import enum
import fcntl
import os
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Dict, Iterable, Iterator, List, Sequence, Tuple, TypeVar

#: Where the machine's lock files live (machine-wide: every pytest run on the machine shares them).
SLOT_FOLDER = Path(tempfile.gettempdir()) / "walkman-free-standing-robots"


#: The marks that give a test the machine to itself.
MACHINE_TO_ITSELF = frozenset({"alone", "free_standing", "two_pcs"})
#: Folders of tests/ whose tests start no simulated robot, GYM module or bridge -- the only
#: programs with real-time threads (walkman/realtime.py).
NO_REAL_TIME_FOLDERS = frozenset({"unit", "control", "fuzz", "integration", "interop",
                                  "pilot", "nodekit", "rosnodes", "netem"})
#: The mark of a test there that does start one (a HAL, to speak to it as a YARP robot).
REAL_TIME_MARK = "real_time"
#: The mark of a test elsewhere that starts none: it runs the robot on simulated time in
#: its own process (walkman.gym.offline), where nothing is real-time (a helper program it
#: starts, such as the head camera's renderer, runs at normal priority).
OFFLINE_MARK = "offline"
#: The mark of a test that runs the robot and its modules as processes on the lockstep clock
#: (walkman-hal --clock --rtf max, modules --lockstep): nothing there is real-time, and the
#: robot waits for its modules however loaded the machine is.
LOCKSTEP_MARK = "lockstep"


class Share(enum.Enum):
    """How much of the machine a test holds while it runs."""
    ALONE = "alone"      # beside no other test that runs real-time threads
    SHARED = "shared"    # beside other shared tests: it runs real-time threads
    NONE = "none"        # nothing: it runs none, beside anything


def machine_to_itself(marks: Iterable[str]) -> bool:
    """Whether a test with these marks runs with the machine to itself."""
    return not MACHINE_TO_ITSELF.isdisjoint(marks)


def share_of(marks: Iterable[str], folder: str) -> Share:
    """The share of the machine a test in ``folder`` (of tests/) with these marks holds."""
    marks = set(marks)
    if machine_to_itself(marks):
        return Share.ALONE
    if OFFLINE_MARK in marks or LOCKSTEP_MARK in marks or (folder in NO_REAL_TIME_FOLDERS
                                 and REAL_TIME_MARK not in marks):
        return Share.NONE
    return Share.SHARED


Item = TypeVar("Item")


def arranged(items: Sequence[Item], share: Callable[[Item], Share], workers: int) -> List[Item]:
    """``items`` in the order the suite runs them on ``workers`` (each class in its order).

    pytest-xdist's work stealing first hands each worker a contiguous part of the list
    (``len // workers`` tests for whichever worker is ready first, then an even share of
    the rest; every worker collects the same list, ``PYTEST_XDIST_WORKER_COUNT`` set).  The
    first part begins with the tests alone, then the shared ones; the next with the tests
    that hold nothing, so that another worker runs them while the first has the machine to
    itself; the shared tests left over come last.  One worker (or none): alone, shared, free.
    """
    kinds: Dict[Share, List[Item]] = {kind: [] for kind in Share}
    for item in items:
        kinds[share(item)].append(item)
    alone, shared, free = kinds[Share.ALONE], kinds[Share.SHARED], kinds[Share.NONE]
    if workers < 2:
        return alone + shared + free
    first = max(len(items) // workers - len(alone), 0)
    return alone + shared[:first] + free + shared[first:]


def one_share_per_fixture(uses: Iterable[Tuple[str, str, Share]]) -> None:
    """Raise ValueError naming each fixture wider than a test (``(fixture, test, share)``
    for each use) that serves tests of more than one share."""
    shares: Dict[str, Dict[Share, str]] = {}
    for fixture, test, share in uses:
        shares.setdefault(fixture, {}).setdefault(share, test)
    mixed = [f"{fixture} serves " + ", ".join(f"{test} ({share.value})"
                                              for share, test in tests.items())
             for fixture, tests in shares.items() if len(tests) > 1]
    if mixed:
        raise ValueError("a fixture wider than a test must serve tests of one share of the "
                         "machine (tests/robot_slots.py): " + "; ".join(mixed))


@contextmanager
def no_real_time() -> Iterator[None]:
    """``WALKMAN_NO_RT`` set for the block (walkman/realtime.py): the programs started in it,
    which inherit the environment, and the code it runs in this process keep normal priority."""
    before = os.environ.get("WALKMAN_NO_RT")
    os.environ["WALKMAN_NO_RT"] = "1"
    try:
        yield
    finally:
        if before is None:
            del os.environ["WALKMAN_NO_RT"]
        else:
            os.environ["WALKMAN_NO_RT"] = before


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
