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
"""

from __future__ import annotations

import os
import threading

from yarp_lite import stream

#: GIL hand-over interval in module and HAL processes.  Python's default (5 ms)
#: lets a port thread hold the interpreter for 2.5 control periods at 500 Hz.
SWITCH_INTERVAL = 0.0002
#: SCHED_FIFO priorities: the physics, then the threads between it and the loops (above
#: the module's loop, so a state it waits for is handed over at once), then the loops.
HAL_PRIORITY = 60
PATH_PRIORITY = 55
CONTROL_PRIORITY = 50

_this_thread = threading.local()


def make_realtime(priority: int) -> bool:
    """Give the calling thread SCHED_FIFO ``priority``; False where not permitted."""
    if os.environ.get("WALKMAN_NO_RT") or not hasattr(os, "sched_setscheduler"):
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError):
        return False
    stream.no_spin_in_this_thread()
    return True


def make_realtime_once(priority: int) -> None:
    """:func:`make_realtime` for a thread this code does not start (a port's reader),
    called on each message: only the thread's first call asks the kernel."""
    if not getattr(_this_thread, "realtime_asked", False):
        _this_thread.realtime_asked = True
        make_realtime(priority)
