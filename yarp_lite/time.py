"""Time as YARP programs see it: the system clock, or a network clock named by ``YARP_CLOCK``.

Theory of operation
-------------------
YARP's ``yarp::os::Time`` answers ``now()`` and ``delay(s)`` from one clock per process.
With ``YARP_CLOCK`` unset that is the system clock.  With ``YARP_CLOCK=/clock`` it is a
network clock: the process opens ``/<host>/<process>/<pid>/clock:i``, has the name server
connect ``/clock`` to it persistently (so a clock source restarted later is found again),
and takes its time from the ticks it reads (:mod:`yarp_lite.clock_wire`).  Then ``now()``
is the newest tick, ``delay(s)`` waits for a tick at or past ``now() + s`` however long
that takes in wall time (a paused simulator holds every delay), and a source that never
ticks holds them forever, as YARP does.

This module does the same, with three differences a user can rely on:

* a malformed tick is refused with a log line and the time stays where it was (YARP reads
  it as time 0);
* a tick that goes backwards (a simulation's time reset) moves every pending delay back
  with it, so each still waits the simulated time it asked for (YARP moves only the first);
* :meth:`NetworkClock.close` wakes every waiter, which then finishes its wait on the system
  clock: a program shutting down never hangs on a clock that stopped.

The system clock here is ``time.monotonic``: YARP's is the epoch time, but only
differences of ``now()`` mean anything to a program, and a monotonic clock cannot jump
when the machine's time is set.  Code that waits or stamps takes a :class:`Clock` (or asks
:func:`clock`), so the same code runs on the wall clock, the robot's simulated clock, or a
test's manual clock.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time as _system_time
from typing import List, Optional, Protocol

from yarp_lite import clock_wire
from yarp_lite.bottle import Bottle
from yarp_lite.errors import LocalProtocolError, NetworkError, RemoteProtocolError

log = logging.getLogger("yarp_lite.time")

#: ``YARP_CLOCK``'s default source when the variable is set but empty is no network clock
#: (YARP: an empty value selects the system clock); this is the port a source opens by default.
DEFAULT_SOURCE = "/clock"
#: While waiting for a network clock's first tick, say so this often (wall seconds).
FIRST_TICK_REMINDER = 5.0


class Clock(Protocol):
    """What code that waits or stamps asks (``yarp::os::Clock``)."""

    def now(self) -> float: ...

    def delay(self, seconds: float) -> None: ...

    def is_valid(self) -> bool: ...


class SystemClock:
    """The machine's monotonic clock."""

    def now(self) -> float:
        return _system_time.monotonic()

    def delay(self, seconds: float) -> None:
        if seconds > 0:
            _system_time.sleep(seconds)

    def is_valid(self) -> bool:
        return True

    def __repr__(self) -> str:
        return "SystemClock()"


def process_clock_port(pid: Optional[int] = None) -> str:
    """``/<host>/<process>/<pid>/clock:i``, the name YARP's ``NetworkClock::open`` gives the
    port it reads ticks on (the process is the first word of its command line, as YARP's
    ``SystemInfo::getProcessInfo`` reads it)."""
    pid = os.getpid() if pid is None else pid
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as cmdline:
            program = cmdline.read().split(b"\0")[0].decode(errors="replace")
    except OSError:
        program = ""
    program = program.split(" ")[0] or "python"
    return f"/{socket.gethostname()}/{program}/{pid}/clock:i"


class NetworkClock:
    """Time read from a clock source's ticks (``yarp::os::NetworkClock``)."""

    def __init__(self, source: str = DEFAULT_SOURCE, local_name: Optional[str] = None,
                 nameclient=None) -> None:
        self.source = source
        self.local_name = local_name or process_clock_port()
        self._nameclient = nameclient
        self._cond = threading.Condition()
        self._time = 0.0
        self._ticks = 0
        #: Total of the backward jumps so far: a waiter's target moves back by the jumps
        #: that happened while it waited.
        self._moved_back = 0.0
        self._closing = False
        self._port = None
        self.refused = 0

    # -- lifecycle -----------------------------------------------------------------------

    def open(self, wait: Optional[float] = None) -> "NetworkClock":
        """Open the reading port, connect the source to it persistently, and wait (``wait``
        wall seconds, None: as long as it takes, as YARP) for the first tick."""
        from yarp_lite import network
        from yarp_lite.nameclient import NameClient
        from yarp_lite.port import Port

        client = self._nameclient or NameClient()
        self._port = Port(reader=self._on_tick, nameclient=client)
        self._port.open(self.local_name)
        outcome = network.connect(self.source, self._port.name, client=client, persist=True)
        if not outcome.ok:
            self._port.close()
            raise NetworkError(f"cannot follow the clock {self.source}: {outcome.message}")
        if client.query(self.source) is None:
            log.warning("the clock %s is not there yet: %s waits for it", self.source,
                        self._port.name)
        self.wait_for_first_tick(wait)
        return self

    def wait_for_first_tick(self, wait: Optional[float] = None) -> bool:
        deadline = None if wait is None else _system_time.monotonic() + wait
        with self._cond:
            while not self._ticks and not self._closing:
                remaining = FIRST_TICK_REMINDER if deadline is None else \
                    min(FIRST_TICK_REMINDER, deadline - _system_time.monotonic())
                if remaining <= 0:
                    return False
                if not self._cond.wait(remaining) and not self._ticks and deadline is None:
                    log.info("waiting for the first tick of the clock %s", self.source)
            return bool(self._ticks)

    def close(self) -> None:
        """Stop following: every pending delay finishes on the system clock."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        if self._port is not None:
            from yarp_lite import network

            # A failed unsubscription (the name server gone first) leaves nothing to undo.
            network.disconnect(self.source, self._port.name, client=self._nameclient,
                               persist=True)
            self._port.close()

    # -- the clock -------------------------------------------------------------------------

    def now(self) -> float:
        with self._cond:
            return self._time

    def is_valid(self) -> bool:
        with self._cond:
            return self._ticks > 0

    @property
    def ticks(self) -> int:
        return self._ticks

    def delay(self, seconds: float) -> None:
        if seconds <= 1e-12:
            return
        with self._cond:
            if self._closing:
                closing = True
            else:
                closing = False
                target, moved_back = self._time + seconds, self._moved_back
                while not self._closing:
                    if self._time >= target - (self._moved_back - moved_back) - 1e-12:
                        return
                    self._cond.wait()
                remaining = target - (self._moved_back - moved_back) - self._time
        # Closing: the rest of the wait on the system clock (YARP: the whole of it).
        _system_time.sleep(seconds if closing else max(0.0, remaining))

    def wait_until(self, when: float) -> None:
        """Wait for the clock to reach ``when`` (already there: return at once)."""
        self.delay(when - self.now())

    # -- ticks -----------------------------------------------------------------------------

    def _on_tick(self, bottle: Bottle) -> None:
        try:
            tick = clock_wire.decode_tick(bottle, self.local_name)
        except RemoteProtocolError as exc:
            self.refused += 1
            log.warning("%s; the clock stays at %.6f s", exc, self._time)
            return None
        self.feed(tick.seconds)
        return None

    def feed(self, seconds: float) -> None:
        """The source says it is ``seconds`` now (what each tick does; tests call it)."""
        with self._cond:
            if self._ticks and seconds < self._time:
                log.warning("the clock %s went back from %.6f s to %.6f s: pending delays "
                            "move back with it", self.source, self._time, seconds)
                self._moved_back += self._time - seconds
            self._time = seconds
            self._ticks += 1
            self._cond.notify_all()

    def __repr__(self) -> str:
        return f"NetworkClock({self.source!r} -> {self.local_name!r}, t={self._time:.6f})"


class ManualClock:
    """A clock a program or a test moves by hand (``yarp::os::Time::useCustomClock``)."""

    def __init__(self, start: float = 0.0) -> None:
        self._cond = threading.Condition()
        self._time = start

    def now(self) -> float:
        with self._cond:
            return self._time

    def is_valid(self) -> bool:
        return True

    def advance(self, seconds: float) -> None:
        if seconds < 0:
            raise LocalProtocolError(f"a manual clock only goes forward, not by {seconds} s")
        with self._cond:
            self._time += seconds
            self._cond.notify_all()

    def delay(self, seconds: float) -> None:
        with self._cond:
            target = self._time + seconds
            while self._time < target - 1e-12:
                self._cond.wait()


class Pacer:
    """Wake every ``period`` seconds of ``clock`` (YARP's ``PeriodicThread`` timing): tick k
    is due at ``start + k * period``; a tick that found itself more than a period late
    starts the schedule again from now instead of bursting to catch up."""

    def __init__(self, period: float, clock: Optional[Clock] = None) -> None:
        if not period > 0:
            raise LocalProtocolError(f"a pacer's period must be above 0 s, not {period!r}")
        self.period = period
        self.clock = clock if clock is not None else process_clock()
        self.due = self.clock.now() + period
        self.overruns = 0

    def wait(self) -> float:
        """Wait for the next tick; return how late (s) this call was on its schedule."""
        now = self.clock.now()
        if now < self.due:
            self.clock.delay(self.due - now)
            now = self.clock.now()
        late = max(0.0, now - self.due)
        if late > self.period:
            self.overruns += 1
            self.due = now + self.period
        else:
            self.due += self.period
        return late


# -- the process's clock (``yarp::os::Time``) --------------------------------------------------

_lock = threading.Lock()
_clock: Optional[Clock] = None


def source_from_environment(environ=os.environ) -> Optional[str]:
    """The clock source ``YARP_CLOCK`` names (None: the system clock), as ``yarpClockInit``."""
    value = environ.get("YARP_CLOCK", "").strip()
    return value or None


def process_clock() -> Clock:
    """The clock of this process, chosen from ``YARP_CLOCK`` on first use (that first use
    waits for the source's first tick, as YARP's network initialisation does)."""
    global _clock
    with _lock:
        if _clock is None:
            source = source_from_environment()
            _clock = SystemClock() if source is None else NetworkClock(source).open()
        return _clock


def use_system_clock() -> Clock:
    """Leave any network clock for the system clock (a clock *source* does this first)."""
    return use_clock(SystemClock())


def use_network_clock(source: str = DEFAULT_SOURCE, local_name: Optional[str] = None,
                      wait: Optional[float] = None) -> NetworkClock:
    clock = NetworkClock(source, local_name).open(wait)
    use_clock(clock)
    return clock


def use_clock(new: Clock) -> Clock:
    """Make ``new`` the process's clock; a network clock it replaces is closed."""
    global _clock
    with _lock:
        old, _clock = _clock, new
    if isinstance(old, NetworkClock) and old is not new:
        old.close()
    return new


def is_system_clock() -> bool:
    return isinstance(process_clock(), SystemClock)


def now() -> float:
    """``yarp::os::Time::now``."""
    return process_clock().now()


def delay(seconds: float) -> None:
    """``yarp::os::Time::delay``."""
    process_clock().delay(seconds)


__all__: List[str] = ["Clock", "SystemClock", "NetworkClock", "ManualClock", "Pacer",
                      "process_clock", "use_system_clock", "use_network_clock", "use_clock",
                      "is_system_clock", "now", "delay", "process_clock_port",
                      "source_from_environment", "DEFAULT_SOURCE"]
