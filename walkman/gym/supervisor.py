"""``walkman-module NAME``: keeps a module process alive, whatever its code does.

The supervisor starts the module process (:mod:`walkman.gym.runner`) and
watches its heartbeat (a byte every 0.5 s on a pipe):

* the process exits 0 (the pilot said ``quit``): the supervisor exits too;
* it says it is quitting (``QUITTING`` on the pipe, once the pilot's ``quit`` is done
  and it closes its ports): the supervisor waits up to ``QUIT_GRACE`` for it to end,
  then kills it, and exits either way -- a module told to quit is never restarted;
* it exits with ``EXIT_ESCALATED`` (``run()`` ignored a ``stop``), crashes, or
  its heartbeat stops for 5 s (a hang that even blocks the watchdog; a process
  that has not beaten yet is still importing and gets 60 s, as systemd's
  start timeout is apart from its watchdog's): the
  supervisor has it print its threads' stacks (faulthandler), kills it and starts a fresh one in the *stopped* state, so the
  pilot can ``start`` it again.  Restarts are logged and rate-limited.

This is the "escalate from thread to process" of the module template: a
module can never be left ignoring the pilot.  ``kill -USR1`` to the supervisor
has the module process print every thread's stack (:mod:`nodekit.stacks`), to see
where a module that does not answer is; ``kill -USR2``, faulthandler's dump, for
one whose interpreter is wedged.
"""

from __future__ import annotations

import logging
import os
import select
import signal
import subprocess
import sys
import time
from typing import List, Optional

from nodekit.exits import describe_exit
from nodekit.logs import time_prefix
from walkman.gym.runner import (EXIT_ESCALATED, EXIT_QUIT, QUITTING, SIGNALS_ARMED, parse_args,
                                run_module)

log = logging.getLogger("walkman.gym.supervisor")

HEARTBEAT_TIMEOUT = 5.0
#: s a hung module has to write its threads' stacks before it is killed.
STACKS_GRACE = 0.5
#: Before its first beat a module is starting (Python, numpy, MuJoCo imports on a loaded
#: 2-core PC took over 5 s and the module was killed ten times over, never started).
STARTUP_TIMEOUT = 60.0
#: s a module that said it is quitting has to end (closing its ports, each unregistered
#: from the name server) before it is killed
QUIT_GRACE = 30.0


class Supervisor:
    def __init__(self, argv: List[str]) -> None:
        self.argv = argv
        self.child: Optional[subprocess.Popen] = None
        self.child_armed = False   # it has its SIGUSR1/2 handlers (it said SIGNALS_ARMED)
        self.stopping = False
        self.restarts: List[float] = []

    def _spawn(self, initial: str) -> int:
        read_fd, write_fd = os.pipe()
        argv = [sys.executable, "-m", "walkman.gym.runner", *self.argv, "--initial", initial,
                "--heartbeat-fd", str(write_fd)]
        self.child = subprocess.Popen(argv, pass_fds=(write_fd,))
        self.child_armed = False
        os.close(write_fd)
        return read_fd

    def run(self) -> int:
        initial = "constructor"
        while True:
            read_fd = self._spawn(initial)
            code = self._watch(read_fd)
            os.close(read_fd)
            if self.stopping or code == EXIT_QUIT:
                return 0 if code in (EXIT_QUIT, None) else code
            now = time.monotonic()
            self.restarts = [t for t in self.restarts if now - t < 60] + [now]
            if len(self.restarts) > 10:
                log.error("module restarted 10 times in a minute; giving up")
                return 1
            reason = ("run() ignored the pilot" if code == EXIT_ESCALATED else
                      "no heartbeat" if code is None else describe_exit(code))
            log.warning("module process ended (%s); starting a fresh one, stopped", reason)
            initial = "stopped"

    def _watch(self, read_fd: int) -> Optional[int]:
        assert self.child is not None
        last_beat, limit = time.monotonic(), STARTUP_TIMEOUT
        quitting = False
        while True:
            readable, _, _ = select.select([read_fd], [], [], 0.5)
            if readable:
                words = os.read(read_fd, 1024)
                if SIGNALS_ARMED in words:
                    self.child_armed = True
                    words = words.replace(SIGNALS_ARMED, b"")
                if words and not quitting:
                    last_beat, limit = time.monotonic(), HEARTBEAT_TIMEOUT
                if QUITTING in words and not quitting:
                    quitting, last_beat, limit = True, time.monotonic(), QUIT_GRACE
            code = self.child.poll()
            if code is not None:
                return code
            if time.monotonic() - last_beat > limit and not self.stopping:
                if quitting:
                    log.warning("module still closing %.0f s after the pilot's quit: "
                                "killing it", limit)
                else:
                    log.warning("module heartbeat %s for %.0f s: killing it (its threads' "
                                "stacks first)",
                                "lost" if limit == HEARTBEAT_TIMEOUT else "never came", limit)
                    self._dump_stacks()
                self.child.kill()
                self.child.wait()
                return EXIT_QUIT if quitting else None

    def _dump_stacks(self) -> None:
        """faulthandler's dump of a hung module's threads, on its stderr (ours): where it
        hung is the one thing a restart cannot tell.  It is written from the signal handler
        in C, so it comes even when the interpreter is wedged; the grace is its writing."""
        assert self.child is not None
        try:
            self.child.send_signal(signal.SIGUSR2)
        except ProcessLookupError:
            return
        try:
            self.child.wait(STACKS_GRACE)   # (faulthandler's dump does not end the process)
        except subprocess.TimeoutExpired:
            pass  # still alive after its dump: the caller kills it next

    def forward(self, signum: int, _frame) -> None:
        self.stopping = True
        if self.child is not None and self.child.poll() is None:
            self.child.send_signal(signal.SIGINT if signum == signal.SIGINT else signal.SIGTERM)

    def show_stacks(self, signum: int, _frame) -> None:
        """``SIGUSR1`` (``SIGUSR2``): the module process prints every thread's stack (a
        module that does not answer can be asked where it is), passed on as it came -- not
        to one still importing: a signal it has no handler for yet would kill it."""
        if self.child is None or self.child.poll() is not None:
            return
        if not self.child_armed:
            log.warning("module process %d is still starting (no stack handlers yet): no "
                        "stacks to show", self.child.pid)
            return
        self.child.send_signal(signum)


def main(argv: Optional[List[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    options = parse_args(argv)
    if options.no_supervisor:
        return run_module(argv)
    logging.basicConfig(level=logging.INFO,
                        format=f"{time_prefix()}[%(levelname)s] %(message)s", stream=sys.stderr)
    supervisor = Supervisor([arg for arg in argv if arg != "--no-supervisor"])
    signal.signal(signal.SIGINT, supervisor.forward)
    signal.signal(signal.SIGTERM, supervisor.forward)
    signal.signal(signal.SIGUSR1, supervisor.show_stacks)
    signal.signal(signal.SIGUSR2, supervisor.show_stacks)
    return supervisor.run()


if __name__ == "__main__":
    sys.exit(main())
