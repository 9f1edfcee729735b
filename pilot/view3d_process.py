"""The PI's side of the 3-D view's render process: start it, talk to it, start it again.

Theory of operation
-------------------
:class:`RenderProcess` is one child (:mod:`pilot.view3d_child`): a socket pair
carries :mod:`pilot.view3d_protocol` lines, read by a ``QSocketNotifier`` on
the GUI thread and written without ever blocking it (a child that stops
reading fills its socket; what does not fit waits in an outbox, and the
liveness check kills a child that stays stuck).  A thread per child waits for
its exit and hands it to the GUI thread.

:class:`RenderSupervisor` keeps one child showing the view.  A child loads
Python, Qt and librviz and registers its ROS node, then waits to be told
``go``; once the view is up the supervisor starts a second child, which stays
warm, so that when the first dies the spare is told to go and only builds
librviz's frame (about half a fresh start; the next spare starts once the new
view is up).  A child is *up* once it said ``window``; from then it is pinged
every :data:`PING_EVERY` s and killed when it has not answered for
:data:`HANG_AFTER` s (heap corruption can deadlock malloc as well as crash
it).  A child that shows no window within :data:`START_TIMEOUT` s of its go
is killed too.  When the view dies the supervisor says why (``crashed:
signal 11 (SIGSEGV)``) and starts the next after the delay
:class:`RestartPolicy` gives: at once after a view that had been up, longer
and longer after views that died before they were up (a broken installation
must not spin).  Nothing here blocks the GUI thread, so the rest of the PI
never notices.

Each child runs in a folder of its own (:class:`CrashFolders`), where its
faulthandler stacks and the kernel's core file land: a crash's folder is kept
(the newest :data:`KEEP_CRASHES`), a clean exit's is removed.
"""

from __future__ import annotations

import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Sequence

from python_qt_binding.QtCore import QObject, QSocketNotifier, Qt, QTimer, Signal

from nodekit.exits import describe_exit
from pilot.view3d_protocol import (Decoder, Direction, Go, Message, Ping, Pong,
                                   RemoteProtocolError, RosNodes, WindowReady, encode)

log = logging.getLogger("pilot.view3d")

PING_EVERY = 2.0
HANG_AFTER = 20.0
START_TIMEOUT = 90.0
#: Crash folders kept (stacks and core); older ones are removed.
KEEP_CRASHES = 5
#: A child stuck with this much unsent is treated as hung.
MAX_OUTBOX = 1 << 20
PACKAGE_ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class ChildExit:
    """How a child ended: its pid, ``returncode`` (negative: the signal), why we think so."""

    pid: int
    returncode: int
    ran_for: float              # seconds since it was started
    up_for: Optional[float]     # seconds since its window was up; None if it never was
    reason: str                 # "crashed: signal 11 (SIGSEGV)", "hung: ..." (ours)
    folder: Optional[Path]      # its crash folder when kept


class RestartPolicy:
    """How long to wait before the next child (pure: the supervisor feeds it the deaths)."""

    #: A child up for less than this counts as one more failure in a row.
    MIN_UP = 2.0
    DELAYS = (0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 30.0)

    def __init__(self) -> None:
        self.failures = 0

    def died(self, up_for: Optional[float]) -> float:
        """The delay before starting again after a child that was up for ``up_for`` s."""
        if up_for is not None and up_for >= self.MIN_UP:
            self.failures = 0
            return 0.0
        delay = self.DELAYS[min(self.failures, len(self.DELAYS) - 1)]
        self.failures += 1
        return delay


class CrashFolders:
    """One working folder per child under ``root``: kept when it holds crash evidence."""

    def __init__(self, root: Path) -> None:
        self.root = root

    @staticmethod
    def default_root() -> Path:
        base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
        return Path(base) / "walkman-pilot" / "view3d"

    def new(self) -> Path:
        self.root.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix="starting-", dir=self.root))

    def named_for(self, folder: Path, pid: int) -> Path:
        """Renamed after the child's pid (its working directory follows: same inode)."""
        target = folder.with_name(f"pid{pid}-{time.strftime('%Y%m%d-%H%M%S')}")
        folder.rename(target)
        return target

    @staticmethod
    def evidence(folder: Path) -> List[Path]:
        """The stacks file if faulthandler wrote to it, and core files."""
        found = [p for p in folder.glob("core*") if p.is_file()]
        stacks = folder / "stacks.txt"
        if stacks.is_file() and stacks.stat().st_size > 0:
            found.insert(0, stacks)
        return found

    def settle(self, folder: Path) -> bool:
        """After the child's exit: keep the folder if it holds evidence (pruning old ones),
        else remove it.  True when kept."""
        if self.evidence(folder):
            kept = sorted((p for p in self.root.iterdir() if p.is_dir() and self.evidence(p)),
                          key=lambda p: p.stat().st_mtime)
            for old in kept[:-KEEP_CRASHES]:
                shutil.rmtree(old, ignore_errors=True)
            return True
        shutil.rmtree(folder, ignore_errors=True)
        return False


class RenderProcess(QObject):
    """One render child, GUI thread: started, talked to, reaped."""

    message = Signal(object)
    exited = Signal(int)                    # returncode
    _reaped = Signal(int)

    def __init__(self, module: str, argv: Sequence[str], folder: Path) -> None:
        """Run ``python -m module --fd N *argv`` in ``folder``."""
        super().__init__()
        self.started_at = time.monotonic()
        ours, theirs = socket.socketpair()
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(PACKAGE_ROOT),
                                                        env.get("PYTHONPATH", "")) if p)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", module, "--fd", str(theirs.fileno()), *argv],
            pass_fds=(theirs.fileno(),), cwd=str(folder), env=env)
        theirs.close()
        self.pid = self.proc.pid
        self.folder = folder                # its working folder (renamed after its pid)
        self.warm = False                   # started as a spare, before it was needed
        self.killed_because = ""            # why we killed it, if we did
        self.sock = ours
        self.sock.setblocking(False)
        self.decoder = Decoder(Direction.TO_PI)
        self.outbox = bytearray()
        self.reading = QSocketNotifier(ours.fileno(), QSocketNotifier.Read, self)
        self.reading.activated.connect(self._readable)
        self.writing = QSocketNotifier(ours.fileno(), QSocketNotifier.Write, self)
        self.writing.setEnabled(False)
        self.writing.activated.connect(self._flush)
        self._reaped.connect(self._on_reaped, Qt.QueuedConnection)
        threading.Thread(target=lambda: self._reaped.emit(self.proc.wait()),
                         name=f"reap view3d {self.pid}", daemon=True).start()

    def send(self, message: Message) -> None:
        if self.sock is None:
            return
        self.outbox += encode(message)
        self._flush()

    @property
    def stuck(self) -> bool:
        return len(self.outbox) > MAX_OUTBOX

    def kill(self, why: str = "") -> None:
        """SIGKILL; ``why`` is what its exit will be reported as (else its signal)."""
        self.killed_because = self.killed_because or why
        try:
            os.kill(self.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass  # already exited: nothing to kill

    def close(self, wait: float = 2.0) -> None:
        """Ask it to quit (the socket's end), give it ``wait`` s, then kill it."""
        self._drop_socket()
        try:
            self.proc.wait(wait)
        except subprocess.TimeoutExpired:
            self.kill()
            self.proc.wait(5)

    def _flush(self) -> None:
        while self.outbox and self.sock is not None:
            try:
                sent = self.sock.send(self.outbox)
            except BlockingIOError:
                break
            except OSError:              # the child is gone: its exit says why
                self.outbox.clear()
                break
            del self.outbox[:sent]
        if self.sock is not None:
            self.writing.setEnabled(bool(self.outbox))

    def _readable(self) -> None:
        while self.sock is not None:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                return
            except OSError:
                data = b""
            self.decoder.feed(data)
            try:
                for message in self.decoder.messages():
                    self.message.emit(message)
            except RemoteProtocolError as exc:
                self.kill(f"broke the protocol: {exc}")
                data = b""
            if not data:
                self._drop_socket()      # its exit follows (or the reaper has it already)

    def _drop_socket(self) -> None:
        if self.sock is None:
            return
        self.reading.setEnabled(False)
        self.writing.setEnabled(False)
        self.sock.close()
        self.sock = None

    def _on_reaped(self, returncode: int) -> None:
        self._drop_socket()
        self.exited.emit(returncode)


class RenderSupervisor(QObject):
    """Keeps one render child showing the 3-D view (and one warm beside it); says when the
    view is up, down, and why."""

    up = Signal(int, int)                   # X window, pid
    down = Signal(object, float)            # ChildExit, seconds until the next view
    message = Signal(object)                # the child's other messages (moved, nodes)

    def __init__(self, pi_name: str, markers_topic: str,
                 folders: Optional[CrashFolders] = None,
                 child_module: str = "pilot.view3d_child", standby: bool = True) -> None:
        """``standby``: keep a second child loaded and registered, told to go when the first
        dies (the view is back in the time librviz takes to build its frame)."""
        super().__init__()
        self.child_module = child_module
        self.standby = standby
        self.ping_every, self.hang_after, self.start_timeout = \
            PING_EVERY, HANG_AFTER, START_TIMEOUT
        self.pi_name = pi_name
        self.markers_topic = markers_topic
        self.folders = folders or CrashFolders(CrashFolders.default_root())
        self.policy = RestartPolicy()
        self.child: Optional[RenderProcess] = None      # the one told to go
        self.spare: Optional[RenderProcess] = None      # loaded, waiting to be told
        self.went_at = 0.0                  # when the child was told to go
        self.up_at: Optional[float] = None
        self.answered_at = 0.0
        self.nodes: Optional[RosNodes] = None   # the child's ROS nodes, once it said them
        self.forget: List[str] = []         # the last dead child's ROS nodes
        self.starts = 0
        self._seq = 0
        self.answered_seq = 0               # the child's last pong: it read all sent before
        self._closed = False
        self.pinger = QTimer(self)
        self.pinger.timeout.connect(self._ping)
        self.restart = QTimer(self)
        self.restart.setSingleShot(True)
        self.restart.timeout.connect(self.start)

    @property
    def pid(self) -> Optional[int]:
        return self.child.pid if self.child is not None else None

    @property
    def folder(self) -> Optional[Path]:
        return self.child.folder if self.child is not None else None

    def start(self) -> None:
        """Tell the spare to go, or start a child and tell it (its Go waits in the socket)."""
        if self._closed or self.child is not None:
            return
        child, self.spare = self.spare or self._spawn(), None
        self.child, self.up_at, self.nodes, self.answered_seq = child, None, None, 0
        self.went_at = self.answered_at = time.monotonic()
        self.starts += 1
        child.send(Go(tuple(self.forget)))
        self.pinger.start(int(self.ping_every * 1000))
        log.info("pilot: 3-D view starting (pid %d, %s, folder %s)", child.pid,
                 "the warm spare" if child.warm else "a new process", child.folder)

    def _spawn(self) -> RenderProcess:
        folder = self.folders.new()
        child = RenderProcess(self.child_module,
                              ["--pi", self.pi_name, "--markers", self.markers_topic], folder)
        child.folder = self.folders.named_for(folder, child.pid)
        child.message.connect(lambda message, c=child: self._message(c, message))
        child.exited.connect(lambda code, c=child: self._exited(c, code))
        return child

    def send(self, message: Message) -> None:
        if self.child is not None:
            self.child.send(message)

    def ping(self) -> int:
        """Ask the child to answer; once :attr:`answered_seq` reaches the number returned, it
        has read everything sent before (one ordered stream)."""
        self._seq += 1
        self.send(Ping(self._seq))
        return self._seq

    def kill(self, why: str) -> None:
        """Kill the child; its exit is reported with ``why``."""
        if self.child is not None:
            self.child.kill(why)

    def close(self) -> None:
        self._closed = True
        self.pinger.stop()
        self.restart.stop()
        for child in (self.child, self.spare):
            if child is not None:
                child.close()
                self.folders.settle(child.folder)
        self.child = self.spare = None

    def _message(self, child: RenderProcess, message: Message) -> None:
        if child is not self.child:
            return                              # a spare has nothing to say yet
        self.answered_at = time.monotonic()
        if isinstance(message, WindowReady):
            self.up_at = time.monotonic()
            log.info("pilot: 3-D view up (pid %d, window 0x%x) %.2f s after its go",
                     message.pid, message.window, self.up_at - self.went_at)
            self.up.emit(message.window, message.pid)
            if self.standby and self.spare is None:
                self.spare = self._spawn()
                self.spare.warm = True
        elif isinstance(message, RosNodes):
            self.nodes = message
            self.message.emit(message)
        elif isinstance(message, Pong):
            self.answered_seq = max(self.answered_seq, message.seq)
        else:
            self.message.emit(message)

    def _ping(self) -> None:
        child = self.child
        if child is None:
            return
        now = time.monotonic()
        if self.up_at is None:
            if now - self.went_at > self.start_timeout:
                self.kill(f"hung: no window after {self.start_timeout:g} s")
            return
        if now - self.answered_at > self.hang_after or child.stuck:
            self.kill(f"hung: no answer for {now - self.answered_at:.0f} s")
            return
        self.ping()

    def _exited(self, child: RenderProcess, returncode: int) -> None:
        if self._closed:
            return
        kept = self.folders.settle(child.folder)
        reason = child.killed_because or describe_exit(returncode)
        if child is self.spare:                 # the next view will be a new process
            self.spare = None
            log.warning("pilot: the 3-D view's spare (pid %d) %s%s", child.pid, reason,
                        f"; kept its evidence in {child.folder}" if kept else "")
            return
        if child is not self.child:
            return
        self.child = None
        self.pinger.stop()
        now = time.monotonic()
        up_for = None if self.up_at is None else now - self.up_at
        exit = ChildExit(child.pid, returncode, now - self.went_at, up_for, reason,
                         child.folder if kept else None)
        self.forget = [self.nodes.node, *self.nodes.librviz] if self.nodes is not None \
            else [f"/{self.pi_name}_view3d_{child.pid}"]
        delay = self.policy.died(up_for)
        self._report(exit, delay)
        self.down.emit(exit, delay)
        self.restart.start(int(delay * 1000))

    def _report(self, exit: ChildExit, delay: float) -> None:
        """The log line of a death, and the stacks faulthandler left (the core stays put)."""
        if self._closed:
            return
        up = f"up {exit.up_for:.1f} s" if exit.up_for is not None else "never up"
        evidence = ""
        if exit.folder is not None:
            found = self.folders.evidence(exit.folder)
            evidence = f"; kept {', '.join(p.name for p in found)} in {exit.folder}"
            if found and found[0].name == "stacks.txt":   # written as it crashed
                evidence += (f" (it crashed {time.time() - found[0].stat().st_mtime:.1f} s "
                             f"before we knew: the core is written first)")
        log.warning("pilot: 3-D view (pid %d) %s after %.1f s (%s)%s; restarting %s", exit.pid,
                    exit.reason, exit.ran_for, up, evidence,
                    "now" if delay == 0 else f"in {delay:g} s")
        stacks = exit.folder / "stacks.txt" if exit.folder is not None else None
        if stacks is not None and stacks.is_file():
            for line in stacks.read_text(errors="replace").splitlines()[:200]:
                log.warning("pilot: 3-D view's stacks: %s", line)
