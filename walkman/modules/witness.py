"""witness: a GYM module that writes down every command it executes, and when.

It moves no joint and needs no robot.  It is the observer that ``walkman-chaos``
and the bridge tests put on the robot's end of the command path to tell lost,
duplicated, reordered, late and cancelled commands apart; shipped inside the
package, as python-can ships its virtual bus, so an installed ``walkman-chaos``
has it::

    COUNTER_LOG=/tmp/executed.log walkman-module witness --name /counter

Theory of operation
-------------------
For each command ``run()`` takes, one line is appended to the file named by
``$COUNTER_LOG`` and fsynced before the status says so, so a kill -9 right
after cannot lose a command that ran::

    executed count 42 at 1717171717.250 age 0.35 valid 3

``count`` and ``42`` are the command's name and sequence number; ``at`` is
the wall clock when it started (the same clock as the pilot's on one machine,
or on emulated hosts that share its kernel); ``age``/``valid`` are the
lifetime it arrived with (:mod:`walkman.gym.validity`; ``-`` when it had
none).  The runner refuses an expired command before ``run()`` sees it, so a
line whose age exceeds its validity is a command that ran after its deadline.
:func:`parse_line` and :func:`read_log` are the one reader of this format.

It declares a validity of an hour: as a witness of exactly-once delivery, a
command held through a long outage must still run unless its pilot asked for
less (``validity`` of ``send_command``).
"""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, List, Optional

from walkman.gym.interfaces import PilotCommand
from walkman.gym.thread import GenericThread

#: The environment variable naming the file the witness appends to.
LOG_VARIABLE = "COUNTER_LOG"

_LINE = re.compile(r"^executed (?P<name>\S+) (?P<seq>\S+)"
                   r"(?: at (?P<at>\S+) age (?P<age>\S+) valid (?P<valid>\S+))?$")


@dataclass(frozen=True)
class Execution:
    """One command the witness ran."""

    name: str
    seq: Optional[int]
    at: Optional[float] = None          # time.time() when it started
    age: Optional[float] = None         # seconds it had waited when it arrived
    validity: Optional[float] = None    # seconds it was allowed to wait (None: the module's)

    @property
    def arrived_expired(self) -> bool:
        """It had already waited longer than its validity when it reached the module."""
        return self.validity is not None and self.age is not None and self.age > self.validity


def _number(text: Optional[str]) -> Optional[float]:
    return None if text in (None, "-") else float(text)


def line_of(command: PilotCommand, at: float) -> str:
    """The log line for ``command`` started at wall-clock time ``at``."""
    life = command.lifetime
    age = "-" if life is None else f"{life.age:g}"
    valid = "-" if life is None or life.validity is None else f"{life.validity:g}"
    return f"executed {command.name} {command.seq} at {at:.3f} age {age} valid {valid}"


def parse_line(line: str) -> Optional[Execution]:
    """The execution a log line records; None for a line that is not one."""
    match = _LINE.match(line.strip())
    if match is None:
        return None
    seq = match.group("seq")
    return Execution(match.group("name"), None if seq == "None" else int(seq),
                     _number(match.group("at")), _number(match.group("age")),
                     _number(match.group("valid")))


def read_log(path: Path) -> List[Execution]:
    """Every execution in the witness's log, in the order they ran (none if no file yet).

    A last line still being written (no newline yet) is left for the next read."""
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        return []
    complete = text[:text.rfind("\n") + 1]
    return [e for e in map(parse_line, complete.splitlines()) if e is not None]


class Module(GenericThread):
    statuses = ["idle", "counting"]
    status_format = {"counting": "ran command {0:.0f}"}
    #: Held commands must still run after long outages, unless the pilot asks for less.
    command_validity = 3600.0

    log: Optional[IO[str]] = None

    def custom_init(self) -> bool:
        self.log = open(os.environ[LOG_VARIABLE], "a", buffering=1)
        self.status_interface.set_status("idle")
        return True

    def run(self) -> None:
        command = self.command_interface.get_command()
        if command is None:
            return
        assert self.log is not None
        self.log.write(line_of(command, time.time()) + "\n")
        self.log.flush()
        os.fsync(self.log.fileno())
        self.status_interface.set_status("counting", command.seq)

    def custom_release(self) -> None:
        if self.log is not None:
            self.log.close()
            self.log = None
