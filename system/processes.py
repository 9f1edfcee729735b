"""Child processes a user would start by hand: output collected, groups killed, waits that say why.

Shared by the launchers, the comparison tool, the benchmarks and the tests:
:class:`Proc` starts a program in its own session (so killing it kills its
children too), collects its combined output line by line, and waits for a
line, an exit or a count of lines; :func:`wait_until` polls any condition.
A wait that runs out raises :class:`WaitTimeout` (an ``AssertionError``, so a
test reads it as a failure) with the output so far.
"""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

REPO = Path(__file__).resolve().parents[1]

#: The line ``roscore`` prints once it is usable.  Not ``process[master]``: the master is up
#: then but ``/run_id`` is not set yet, and a ``roslaunch`` started in that gap declares its
#: own run id and dies with "run_id on parameter server does not match declared run_id".
ROSCORE_READY = r"started core service \[/rosout\]"


def descendants(pid: int) -> List[int]:
    """Every living process below ``pid`` (children, grandchildren ...), from /proc."""
    children: Dict[int, List[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                parent = int(stat.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(parent, []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def usage(pid: int) -> Optional[Tuple[int, int]]:
    """``(resident KiB, open file descriptors)`` of a living process; None once it is gone.

    Read from /proc, so a soak can sample every program without its cooperation.
    """
    try:
        with open(f"/proc/{pid}/status") as status:
            rss = next((int(line.split()[1]) for line in status if line.startswith("VmRSS:")),
                       0)  # a zombie has no VmRSS line
        return rss, len(os.listdir(f"/proc/{pid}/fd"))
    except (FileNotFoundError, ProcessLookupError):
        return None


def thread_count(pid: int) -> int:
    """How many threads a process has now (0 once it is gone)."""
    try:
        return len(os.listdir(f"/proc/{pid}/task"))
    except (FileNotFoundError, ProcessLookupError):
        return 0


def fifo_priorities(pid: int) -> List[int]:
    """The SCHED_FIFO priorities of a process's threads, read from /proc (policy 1)."""
    found = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        rt_priority, policy = int(fields[37]), int(fields[38])  # stat fields 40 and 41
        if policy == os.SCHED_FIFO:
            found.append(rt_priority)
    return sorted(found)


class WaitTimeout(AssertionError):
    """Something awaited did not happen in time; the text says what and shows the output."""


class Proc:
    """A child process whose combined output is collected line by line."""

    def __init__(self, argv: Sequence[str], env: Dict[str, str], name: str,
                 stdin: bool = False, cwd: Optional[Path] = None,
                 log: Optional[Path] = None) -> None:
        self.name = name
        self.log = None
        if log is not None:
            log.parent.mkdir(parents=True, exist_ok=True)
            self.log = open(log, "a", buffering=1)
        self.argv = list(argv)
        self.lines: List[str] = []
        self._queue: "queue.Queue[str]" = queue.Queue()
        self.popen = subprocess.Popen(
            self.argv, env=env, cwd=str(cwd or REPO), stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
            # A byte that is not UTF-8 (a library's stray output) is shown escaped: a strict
            # decoder killed the reader there and lost every later line (fc29: the PI's DONE).
            encoding="utf-8", errors="backslashreplace", bufsize=1, start_new_session=True)
        self._reader = threading.Thread(target=self._pump, daemon=True)
        self._reader.start()

    def _pump(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            line = line.rstrip("\n")
            self.lines.append(line)
            self._queue.put(line)
            if self.log is not None:  # stamped, to line up with other programs and events
                now = time.time()
                self.log.write(f"{time.strftime('%H:%M:%S', time.localtime(now))}"
                               f".{int(now % 1 * 1000):03d} {line}\n")

    def send(self, text: str) -> None:
        assert self.popen.stdin is not None
        self.popen.stdin.write(text)
        self.popen.stdin.flush()

    def close_stdin(self) -> None:
        if self.popen.stdin is not None:
            self.popen.stdin.close()

    def wait_for(self, pattern: str, timeout: float = 15.0, count: int = 1) -> re.Match:
        """Block until ``count`` output lines (so far) match ``pattern`` (searched anywhere)."""
        regex = re.compile(pattern)
        deadline = time.monotonic() + timeout
        while True:
            matches = [m for m in map(regex.search, list(self.lines)) if m]
            if len(matches) >= count:
                return matches[count - 1]
            if time.monotonic() > deadline:
                raise WaitTimeout(f"{self.name}: {len(matches)} of {count} line(s) matching "
                                     f"{pattern!r} within {timeout}s; output so far:\n"
                                     + "\n".join(self.lines))
            if self.popen.poll() is not None and self._queue.empty():
                self._reader.join(timeout=1)
                if len([m for m in map(regex.search, list(self.lines)) if m]) >= count:
                    continue
                raise WaitTimeout(f"{self.name} exited ({self.popen.returncode}) "
                                     f"before printing {pattern!r}:\n" + "\n".join(self.lines))
            try:
                self._queue.get(timeout=0.2)
            except queue.Empty:
                pass  # no new line within 0.2 s: look again

    def output(self) -> str:
        return "\n".join(self.lines)

    def wait(self, timeout: float = 15.0) -> int:
        code = self.popen.wait(timeout=timeout)
        self._reader.join(timeout=2)
        return code

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Signal the process, its group and every descendant.

        The descendants matter: ``roscore`` starts ``rosmaster`` and ``rosout``
        in sessions of their own, which a signal to the group never reaches.
        """
        family = descendants(self.popen.pid) if self.popen.poll() is None else []
        if self.popen.poll() is None:
            try:
                os.killpg(self.popen.pid, sig)
            except ProcessLookupError:
                pass  # the group already exited: nothing to signal
        for pid in family:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass  # already exited: nothing to signal
        try:
            self.popen.wait(timeout=5)
        except subprocess.TimeoutExpired:
            os.killpg(self.popen.pid, signal.SIGKILL)
            self.popen.wait(timeout=5)

    def interrupt(self) -> int:
        """Ctrl-C, as a user would stop a tool; returns the exit status."""
        if self.popen.poll() is None:
            os.killpg(self.popen.pid, signal.SIGINT)
        try:
            return self.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.kill()
            return -9


def wait_until(predicate, timeout: float = 10.0, interval: float = 0.05,
               message: str = "condition") -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise WaitTimeout(f"timed out after {timeout}s waiting for {message}")
        time.sleep(interval)
