"""Real-time priorities for the HAL's and the modules' threads on the sense -> move path.

The real Walk-Man ran its loops under Xenomai; here the kernel's FIFO class keeps a 2 ms
loop on time while other threads are busy.  The physics loop and a module's control loop
are periodic threads of our own; the threads that carry a state to the loop and its
command back (the HAL's publisher and command readers, a module's state readers) are
port threads, made real-time on their first message.  Where that is not permitted
(neither root nor ``CAP_SYS_NICE``) everything silently stays at normal priority;
``WALKMAN_NO_RT=1`` opts out.  A real-time thread never busy-polls its sockets
(:func:`yarp_lite.stream.no_spin_in_this_thread`): it would keep the loops it feeds off
the CPU.

Every other thread of such a process runs real-time too (:func:`make_process_realtime`,
called before the first thread starts: threads inherit their creator's class).  A Python
thread holds the interpreter lock while it runs; a normal-priority one (an rpc handler, a
status writer) preempted by any busy process of the machine keeps it, and the 1 kHz
physics or a control loop waits for the lock until the scheduler comes back to that
thread: HAL steps of 35-94 ms were measured beside two busy loops, and a robot walking as
processes fell short or tripped its guard (issue 31).  A module's other threads run at
``BACKGROUND_PRIORITY``, below its loop; the HAL's at ``HAL_BACKGROUND_PRIORITY``, above
every module's loop: the robot's threads are never preempted by a module's, so a lock one
of them holds comes back at once.  A module's lifecycle hooks (``custom_init`` loading a
model for seconds) run in its control thread at ``BACKGROUND_PRIORITY``
(:func:`at_priority`): only the periodic loop is above the rest of the machine -- and only
the loop of a module that moves the robot (a ``ControlThread``): the others' loops (the head
camera's renders, 20-100 ms of CPU each) run at normal priority, below every real-time
thread (at ``CONTROL_PRIORITY`` a render runs on its CPU until it is done, and a balancing
robot's loop that waits for that CPU cannot preempt it: likely the 14-ms ticks before a
balance trip on the kerb).  A
bridge's threads run at ``BRIDGE_PRIORITY``, below all of those: on a robot PC loaded by
other programs (two busy loops and a PI rendering the 3-D view, in a test) the link to the
pilot went silent for 2-4 s at a time and the modules' link-loss policies paused them.
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from typing import Iterator, Optional

from yarp_lite import stream

#: GIL hand-over interval in module and HAL processes.  Python's default (5 ms)
#: lets a port thread hold the interpreter for 2.5 control periods at 500 Hz.
SWITCH_INTERVAL = 0.0002
#: SCHED_FIFO priorities: the physics, then the threads between it and the loops (above
#: the module's loop, so a state it waits for is handed over at once), then the loops.
HAL_PRIORITY = 60
PATH_PRIORITY = 55
CONTROL_PRIORITY = 50
#: Every other thread of the HAL (port servers, rpc handlers): above the modules' loops.
HAL_BACKGROUND_PRIORITY = 52
#: Every other thread of a module (port servers, writers) and its lifecycle hooks.
BACKGROUND_PRIORITY = 10
#: Every thread of a bridge (walkman-bridge): the pilot's link and its watchdogs (a module
#: pauses after 5 s without it) above every normal process, below the robot's threads.
BRIDGE_PRIORITY = 5

_this_thread = threading.local()


def realtime_refused(priority: int) -> Optional[str]:
    """Give the calling thread SCHED_FIFO ``priority``: None when granted, else why not
    (for a process that says so in its log)."""
    if os.environ.get("WALKMAN_NO_RT"):
        return "WALKMAN_NO_RT is set"
    if not hasattr(os, "sched_setscheduler"):
        return "this system has no sched_setscheduler"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:
        return str(exc)
    stream.no_spin_in_this_thread()
    return None


def make_realtime(priority: int) -> bool:
    """Give the calling thread SCHED_FIFO ``priority``; False where not permitted."""
    return realtime_refused(priority) is None


def make_normal() -> bool:
    """Run the calling thread at normal priority (``SCHED_OTHER``); returns False, as
    :func:`make_realtime` does for a thread that is not real-time."""
    if hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            pass  # only ever lowers priority; False is the answer either way
    return False


def make_process_realtime(priority: int = BACKGROUND_PRIORITY) -> bool:
    """Run the calling thread, and so every thread it starts later, at ``priority``, and let
    no thread of the process busy-poll; False where not permitted.  Call it first thing in
    ``main``: threads started before keep their class."""
    if not make_realtime(priority):
        return False
    stream.no_spin_in_this_process()
    return True


@contextmanager
def at_priority(priority: int, realtime: bool) -> Iterator[None]:
    """Within the block the calling real-time thread runs at ``priority``, then back at the
    priority it had (``realtime`` False: the thread is not real-time, nothing changes)."""
    if not realtime:
        yield
        return
    before = os.sched_getparam(0).sched_priority
    make_realtime(priority)
    try:
        yield
    finally:
        make_realtime(before)


def make_realtime_once(priority: int) -> None:
    """:func:`make_realtime` for a thread this code does not start (a port's reader),
    called on each message: only the thread's first call asks the kernel."""
    if getattr(_this_thread, "realtime_asked", None) is None:
        keep_priority(priority)


def keep_priority(priority: int) -> None:
    """Run the calling thread (a port's reader, called on each message) at ``priority``:
    the kernel is asked only when it differs from what this thread last asked for."""
    if getattr(_this_thread, "realtime_asked", None) != priority:
        _this_thread.realtime_asked = priority
        make_realtime(priority)
