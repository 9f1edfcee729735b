"""What a module process held of its pilots' commands, on disk, for the process after it.

Theory of operation
-------------------
Once the robot bridge has written a command to a module's port, the module alone
knows what becomes of it.  If its process dies -- ``kill -9``, a crash, the
supervisor killing a hung module -- between the command's arrival and the end of
the tick that took it, nobody tells the pilot: the bridge says ``delivered``, the
module may already have said ``accepted``, and the command is silently gone
(fc17 of 2026-11-28: chaos round 3's ``count 34`` was accepted, then its module
was killed before its control thread ran it).

So the command inbox writes one line per step to an append-only file named
after the module's port prefix and its name server::

    a SEQ TEXT    arrived: in the module's queue
    t SEQ         taken by run() (the ``accepted`` receipt follows)
    e SEQ         ended: the tick that took it returned, or it was refused

Each line is one ``write(2)`` on an ``O_APPEND`` descriptor: in the kernel when
the call returns, so it outlives the process (not a power cut: no fsync, like
the bridge journal's default).  The next process reads the file before it opens
its ports (:func:`parse`), says ``interrupted`` of every command its predecessor
left unfinished, with why (:func:`interruptions`), never runs one, keeps every
sequence number it read so a resend is still dropped, and starts the file again
with only those.

:func:`parse` and :func:`interruptions` are pure; :class:`InboxJournal` is the
thin file layer around them.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from walkman.gym.command_life import CommandState, Receipt

log = logging.getLogger("walkman.gym")

ARRIVED, TAKEN, ENDED = "a", "t", "e"
#: Sequence numbers a fresh file starts with (the module's resend filter keeps as many).
REMEMBERED = 256


@dataclass
class Held:
    """One command the previous process had, and how far it got."""

    seq: int
    text: str = ""
    taken: bool = False


@dataclass
class Predecessor:
    """What a journal file says of the process that wrote it."""

    unfinished: List[Held] = field(default_factory=list)   # arrival order
    seen: List[int] = field(default_factory=list)          # every seq, oldest first
    malformed: List[str] = field(default_factory=list)     # "line N: why"


def parse(text: str) -> Predecessor:
    """The commands a journal's lines leave unfinished; a line that is not one of the three
    forms is named in ``malformed`` and skipped (a journal never stops a module)."""
    held: Dict[int, Held] = {}
    seen: Dict[int, None] = {}
    malformed: List[str] = []
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        kind, _, rest = line.partition(" ")
        seq_text, _, command = rest.partition(" ")
        if kind not in (ARRIVED, TAKEN, ENDED) or not re.fullmatch(r"-?\d+", seq_text):
            malformed.append(f"line {number}: {line[:60]!r} is not 'a|t|e SEQ [TEXT]'")
            continue
        seq = int(seq_text)
        seen.pop(seq, None)
        seen[seq] = None
        if kind == ARRIVED:
            held[seq] = Held(seq, command)
        elif kind == TAKEN:
            held.setdefault(seq, Held(seq)).taken = True
        else:
            held.pop(seq, None)
    return Predecessor(list(held.values()), list(seen)[-REMEMBERED:], malformed)


def interruptions(unfinished: Sequence[Held], module: str) -> List[Receipt]:
    """The ``interrupted`` receipt of each command a dead process left, with why."""
    receipts = []
    for held in unfinished:
        what = f"`{held.text}`" if held.text else "it"
        why = (f"{module}'s previous process ended during the tick that took {what} (it may "
               f"have begun); not run again" if held.taken else
               f"{module}'s previous process ended before taking {what}; not run")
        receipts.append(Receipt(held.seq, CommandState.INTERRUPTED, why))
    return receipts


def line(kind: str, seq: int, text: str = "") -> bytes:
    """One journal line; a command's text is kept on one line."""
    tail = " " + " ".join(text.split()) if text else ""
    return f"{kind} {seq}{tail}\n".encode("utf-8", "replace")


def journal_path(prefix: str, server: str, state_home: Optional[str] = None) -> Path:
    """``$XDG_STATE_HOME/walkman-modules/<prefix>@<server>.inbox``: one module, one robot."""
    base = state_home or os.environ.get("XDG_STATE_HOME") or \
        str(Path.home() / ".local" / "state")
    name = f"{prefix.strip('/').replace('/', '_')}@{server.replace(':', '_')}.inbox"
    return Path(base) / "walkman-modules" / name


class InboxJournal:
    """The file layer: read the predecessor's file, start a fresh one, append lines."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: Optional[int] = None

    def take_over(self) -> Predecessor:
        """Read what the previous process left, then start the file with its seqs only."""
        try:
            before = parse(self.path.read_text("utf-8", "replace"))
        except FileNotFoundError:
            before = Predecessor()
        for problem in before.malformed:
            log.warning("%s: %s (skipped)", self.path, problem)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fresh = self.path.with_suffix(".new")
        fresh.write_bytes(b"".join(line(ENDED, seq) for seq in before.seen))
        os.replace(fresh, self.path)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        return before

    def write(self, kind: str, seq: int, text: str = "") -> None:
        if self._fd is None:
            return
        try:
            os.write(self._fd, line(kind, seq, text))
        except OSError as exc:     # a full disk must not stop the module: said once
            log.warning("%s: cannot write (%s); commands are no longer journalled",
                        self.path, exc)
            self.close()

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
