"""The threads one part of the bridge starts: started in one place, joined in one place.

The node, the TCP channel and the UDP channel each start threads (loops, a handshake per
connection, a receive loop per connection) and must join them when they stop.  Each once
wrote that start-up itself; a :class:`Nursery` is the one place now.  The threads are
daemons: a bridge that cannot join one in time still exits.
"""

from __future__ import annotations

import threading
import time
from typing import Callable, List


class Nursery:
    """The threads of one owner (``"bridge"``: named ``bridge <name>`` in a stack dump)."""

    def __init__(self, owner: str = "bridge") -> None:
        self.owner = owner
        self._threads: List[threading.Thread] = []
        self._lock = threading.Lock()

    def start_soon(self, target: Callable[[], None], name: str) -> threading.Thread:
        """Run ``target`` in a new daemon thread named ``<owner> <name>``."""
        thread = threading.Thread(target=target, name=f"{self.owner} {name}", daemon=True)
        thread.start()
        with self._lock:     # a connection's threads come and go: keep only the living
            self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        return thread

    def join(self, timeout: float = 3.0) -> List[str]:
        """Wait up to ``timeout`` seconds in all for every thread; the names of those still
        running (a thread blocked in a call that never returns)."""
        deadline = time.monotonic() + timeout
        with self._lock:
            threads = list(self._threads)
        for thread in threads:
            if thread is not threading.current_thread():
                thread.join(max(0.0, deadline - time.monotonic()))
        return [thread.name for thread in threads if thread.is_alive()
                and thread is not threading.current_thread()]

    def alive(self) -> List[str]:
        """The names of the threads running now."""
        with self._lock:
            return [thread.name for thread in self._threads if thread.is_alive()]
