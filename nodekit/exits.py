"""How a child process ended, in the words a log reader looks for.

One phrase for every place that reports a child's end -- the PI's 3-D view
supervisor, a GYM module's supervisor, the tests' dumps of a failed test's
programs -- so "crashed: signal 11 (SIGSEGV)" reads the same in each.
"""

from __future__ import annotations

import signal
from typing import Optional


def describe_exit(returncode: Optional[int]) -> str:
    """``crashed: signal 11 (SIGSEGV)``, ``was killed: signal 9 (SIGKILL)``,
    ``exited: status 1``, ``exited`` (0), or ``running`` (None: no exit yet)."""
    if returncode is None:
        return "running"
    if returncode < 0:
        number = -returncode
        try:
            name = signal.Signals(number).name
        except ValueError:
            name = "unknown"
        verb = "was killed" if number in (signal.SIGKILL, signal.SIGTERM) else "crashed"
        return f"{verb}: signal {number} ({name})"
    return "exited" if returncode == 0 else f"exited: status {returncode}"
