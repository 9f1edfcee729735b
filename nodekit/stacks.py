"""``kill -USR1 <pid>``: every thread's stack on stderr, without risking the process.

``faulthandler.register(SIGUSR1, all_threads=True)`` walks the other threads' frames
from inside the signal, while they run: a thread in the middle of an import had
its frames change under the walk and the module process died of SIGSEGV instead of
printing (2026-11-28, ``test_a_module_asked_with_sigusr1_prints_every_thread_s_stack``).
So SIGUSR1 runs a Python handler: the main thread, between two bytecodes, holding
the interpreter lock, reads every thread's frames (:func:`format_stacks`) -- nothing
moves under it.  That needs an interpreter that still runs Python; for one wedged in C
with the lock held, ``kill -USR2`` is faulthandler's dump, as before (unsafe, and the
only thing that can answer then).

The format is faulthandler's, so one reader serves both::

    Thread 0x00007f... "name" (most recent call first):
      File "/path/x.py", line 12 in function
"""

from __future__ import annotations

import faulthandler
import signal
import sys
import threading
from types import FrameType
from typing import Dict, List, TextIO


def format_stacks(frames: Dict[int, FrameType], names: Dict[int, str],
                  current: int) -> str:
    """Every thread's stack, most recent call first, the calling thread's marked."""
    out: List[str] = []
    for ident, frame in frames.items():
        title = "Current thread" if ident == current else "Thread"
        name = f' "{names[ident]}"' if ident in names else ""
        out.append(f"{title} 0x{ident:016x}{name} (most recent call first):")
        walk = frame
        while walk is not None:
            code = walk.f_code
            out.append(f'  File "{code.co_filename}", line {walk.f_lineno} in {code.co_name}')
            walk = walk.f_back
        out.append("")
    return "\n".join(out)


def print_stacks(stream: TextIO = sys.stderr) -> None:
    names = {thread.ident: thread.name for thread in threading.enumerate()
             if thread.ident is not None}
    stream.write(format_stacks(sys._current_frames(), names, threading.get_ident()))
    stream.flush()


def on_signals() -> None:
    """SIGUSR1: :func:`print_stacks`; SIGUSR2: faulthandler's dump (a wedged interpreter).
    Call from the main thread."""
    signal.signal(signal.SIGUSR1, lambda *_: print_stacks())
    faulthandler.register(signal.SIGUSR2, all_threads=True)
