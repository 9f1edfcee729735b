"""The pilot interfaces of a GYM module, on their standard ports (:data:`GYM_PORTS`).

==================  ============================  =====================================
interface           port                          Bottle
==================  ============================  =====================================
switch              ``/P/switch:i``               ``cmd seq`` (start pause resume stop quit)
command             ``/P/command:i``              ``cmd seq`` or ``(cmd args...) seq``
status              ``/P/status:o``               ``seq state data...``
warning             ``/P/warning:o``              ``seq text``
receipt             ``/P/receipt:o``              ``seq state [reason]`` (this project's)
==================  ============================  =====================================

The paper's GYM has the first four; ``receipt`` says what became of each
numbered switch and command (``accepted``, ``refused`` with why, ``expired``:
:mod:`walkman.gym.command_life`), so a pilot sees a command's life, not only
its effect.  Programs that do not read it lose nothing.

As in the original GYM a receiver ignores a missing sequence number, so
``yarp write /x /P/switch:i`` then typing ``start`` works; ``(turn 30)`` sends
a command with an argument.  A command whose sequence number was already
seen is dropped, so a command resent after a network hiccup runs once.

Sequence numbers of statuses and warnings start at 2, because YARP's
``yarp read`` treats a two-item ``1 "text"`` message as end-of-stream.

A switch or command may end with its lifetime, ``(age A valid V)``
(:mod:`walkman.gym.validity`): one that has waited longer than its validity
when it would start is refused on the warning port as expired, never run.

The module's reliable outputs (``warning`` and ``receipt``) hold their recent
messages for a reader that connects later (:data:`HELD_MESSAGES`,
:func:`held_for`; :mod:`yarp_lite.held`): a receipt or warning written while
the robot bridge restarts reaches it when it reconnects, instead of being
dropped by a port with no reader.  A reader gets only what it has not taken
under its name, so a restarted bridge is not sent again what its journal has.

Statuses are dictionary-compressed like the DRC modules did: a module that
declares its list of states sends each as one character (``'a'`` for the
first...), 16 bits on the wire instead of a word; :func:`decode_status`
expands it on the pilot side.  Command decoding and status encoding can be
replaced by custom serializers.
"""

from __future__ import annotations

import itertools
import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable, Collection, Deque, List, Optional, Sequence, Tuple

from walkman.gym.command_life import CommandState, Receipt, encode_receipt
from walkman.gym.inbox_journal import ARRIVED, ENDED, TAKEN, InboxJournal
from walkman.gym.validity import (DEFAULT_VALIDITY, Lifetime, ValidityError, describe_expiry,
                                  split, stamp)
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port


@dataclass(frozen=True)
class GymPort:
    """One of a GYM module's standard ports: every program that names one reads it here."""

    flow: str            # "switch", ... (the bridge's flow label: ``<module>/<flow>``)
    suffix: str          # "switch:i"
    to_robot: bool       # written by the pilot's side
    reliable: bool       # never dropped, never duplicated (the bridge journals it)

    def of(self, module: str) -> str:
        """The port's name for ``module`` (``/gaze_control/switch:i``)."""
        return f"/{module.strip('/')}/{self.suffix}"


#: The standard ports, in the order of the bridge's flow kinds (0, 1, ...): never reorder.
GYM_PORTS: Tuple[GymPort, ...] = (
    GymPort("switch", "switch:i", True, True),
    GymPort("command", "command:i", True, True),
    GymPort("status", "status:o", False, False),
    GymPort("warning", "warning:o", False, True),
    GymPort("receipt", "receipt:o", False, True),
)
SWITCH, COMMAND, STATUS, WARNING, RECEIPT = GYM_PORTS

#: How many warnings, and receipts, a module keeps for a reader that connects later.
HELD_MESSAGES = 256
#: ... and for how long at least: a robot bridge restarted by its supervisor is back well
#: within it (seconds); longer, and the pilot's station has long been told the link is down.
HELD_SECONDS = 60.0


def held_for(validity: float) -> float:
    """Seconds a module keeps a warning or receipt for a late reader: a minute, or as long
    as its commands may wait, if longer -- a receipt matters while the pilot may still be
    waiting for its command to start."""
    return max(HELD_SECONDS, validity)


@dataclass(frozen=True)
class PilotCommand:
    name: str
    args: Tuple = ()
    seq: Optional[int] = None
    #: how long it has waited and may wait (None: it says nothing, age 0, default validity)
    lifetime: Optional[Lifetime] = None


class InterfaceError(ValueError):
    """A message on a pilot port is malformed; the text says how."""


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, (bool, Vocab))


def decode_command(bottle: Bottle, needs_numbers: Collection[str] = ()) -> PilotCommand:
    """``cmd seq`` | ``(cmd args...) seq`` | ``cmd args...`` -> :class:`PilotCommand`.

    ``cmd N`` is ambiguous: a bare command with its sequence number, or a command
    with one argument (``go_straight 10``, as a pilot types it).  For the commands
    in ``needs_numbers`` -- which are never valid bare -- N is the argument.
    """
    if not bottle:
        raise InterfaceError("empty command")
    head = bottle[0]
    seq = int(bottle[1]) if len(bottle) == 2 and _is_int(bottle[1]) else None
    if isinstance(head, list):
        if not head or not isinstance(head[0], str):
            raise InterfaceError(f"a custom command starts with its name: {bottle}")
        if len(bottle) > 2 or (len(bottle) == 2 and seq is None):
            raise InterfaceError(f"expected (cmd args...) seq, got {bottle}")
        return PilotCommand(str(head[0]), tuple(head[1:]), seq)
    if not isinstance(head, str):
        raise InterfaceError(f"a command starts with its name, not {head!r}")
    if seq is not None and str(head) not in needs_numbers:
        return PilotCommand(str(head), (), seq)
    return PilotCommand(str(head), tuple(bottle[1:]), None)


def decoder_for(module_class: object) -> Callable[[Bottle], PilotCommand]:
    """The command decoder of a module whose ``arguments`` say which commands need numbers."""
    needs = frozenset(name for name, (fewest, *_) in
                      getattr(module_class, "arguments", {}).items() if fewest >= 1)
    return lambda bottle: decode_command(bottle, needs)


def encode_command(command: PilotCommand) -> Bottle:
    if command.args:
        bottle = Bottle([Bottle([command.name, *command.args])])
    else:
        bottle = Bottle([command.name])
    if command.seq is not None:
        bottle.append(command.seq)
    return bottle if command.lifetime is None else stamp(bottle, command.lifetime)


def readable(bottle: Sequence) -> str:
    """A Bottle as a pilot reads it in the logs: YARP's text, but each float with ten
    significant digits (YARP prints 1.45 as 1.44999999999999995559)."""
    def one(value: object) -> str:
        if isinstance(value, list):
            return f"({readable(value)})"
        if isinstance(value, float) and math.isfinite(value):
            text = f"{value:.10g}"
            return text if any(c in text for c in ".e") else f"{text}.0"
        return Bottle([value]).to_text()
    return " ".join(one(value) for value in bottle)


def command_text(command: PilotCommand) -> str:
    """The command as a pilot typed it: name and arguments, no sequence number."""
    return readable([command.name, *command.args])


def command_seq(bottle: Bottle) -> Optional[int]:
    """The sequence number of a switch or command as written (lifetime and all), if it
    has one: what its receipts name."""
    try:
        message, _ = split(bottle)
        return decode_command(message).seq
    except (InterfaceError, ValidityError):
        return None


def validity_of(module_class: object) -> float:
    """The seconds a module's commands may wait by default (its ``command_validity``)."""
    return float(getattr(module_class, "command_validity", DEFAULT_VALIDITY))


def encode_status(seq: int, state: str, data: Sequence = (),
                  dictionary: Optional[Sequence[str]] = None) -> Bottle:
    """``seq state data...``; with a dictionary the state is one letter."""
    word = state
    if dictionary is not None and state in dictionary:
        word = chr(ord("a") + list(dictionary).index(state))
    return Bottle([seq, word, *data])


def decode_status(bottle: Bottle, dictionary: Optional[Sequence[str]] = None) -> Tuple[int, str, list]:
    if len(bottle) < 2 or not _is_int(bottle[0]) or not isinstance(bottle[1], str):
        raise InterfaceError(f"status must be seq state data..., got {bottle}")
    state = str(bottle[1])
    if dictionary is not None and len(state) == 1 and 0 <= ord(state) - ord("a") < len(dictionary):
        state = dictionary[ord(state) - ord("a")]
    return int(bottle[0]), state, list(bottle[2:])


class _Inbox:
    """Commands from a port, in order, each sequence number once, none past its validity."""

    def __init__(self, decode: Callable[[Bottle], PilotCommand],
                 validity: float = DEFAULT_VALIDITY,
                 clock: Callable[[], float] = time.monotonic,
                 taking_accepts: bool = True) -> None:
        self.decode = decode
        #: taking a command is accepting it (commands); a switch is accepted or refused by
        #: the lifecycle, which says so itself (:meth:`PilotInterfaces.receipt`)
        self.taking_accepts = taking_accepts
        self.validity = validity
        self.clock = clock
        self.queue: "queue.Queue[Tuple[PilotCommand, float]]" = queue.Queue(maxsize=1000)
        self.recent: Deque[int] = deque(maxlen=256)
        self.rejected: List[str] = []
        self.expired = 0
        self.lock = threading.Lock()
        self.on_arrival: Optional[Callable[[], None]] = None
        #: told what became of each numbered command (:mod:`walkman.gym.command_life`)
        self.on_receipt: Callable[[Receipt], None] = lambda receipt: None
        #: where each command's arrival, take and end are written for the next process
        #: (:mod:`walkman.gym.inbox_journal`); None: not kept
        self.journal: Optional[InboxJournal] = None
        #: taken by the tick now running; ended by :meth:`settle` once it returns
        self.in_hand: List[int] = []

    def remember(self, seqs: Sequence[int]) -> None:
        """Seqs a previous process of this module saw: a resend of one is dropped too."""
        with self.lock:
            self.recent.extend(seqs)

    def feed(self, bottle: Bottle) -> None:
        arrived = self.clock()
        try:
            message, lifetime = split(bottle)
            command = self.decode(message)
        except (InterfaceError, ValidityError) as exc:
            self.rejected.append(str(exc))
            if self.on_arrival:
                self.on_arrival()
            return
        if lifetime is not None:
            command = PilotCommand(command.name, command.args, command.seq, lifetime)
        with self.lock:
            if command.seq is not None:
                if command.seq in self.recent:
                    return  # already executed: a resend
                self.recent.append(command.seq)
                self._journal(ARRIVED, command.seq, command_text(command))
        try:
            self.queue.put_nowait((command, arrived))
        except queue.Full:
            self.rejected.append(f"command queue full, dropped {command.name}")
            self._journal(ENDED, command.seq)
            self._receipt(command, CommandState.REFUSED, "the module's command queue is full")
        if self.on_arrival:
            self.on_arrival()

    def _receipt(self, command: PilotCommand, state: CommandState, reason: str = "") -> None:
        if command.seq is not None:
            self.on_receipt(Receipt(command.seq, state, reason))

    def _journal(self, kind: str, seq: Optional[int], text: str = "") -> None:
        if self.journal is not None and seq is not None:
            self.journal.write(kind, seq, text)

    def settle(self) -> None:
        """The tick that took :attr:`in_hand` returned: those commands are the module's doing
        now, not a dead process's to report (control thread, after each tick)."""
        for seq in self.in_hand:
            self._journal(ENDED, seq)
        self.in_hand.clear()

    def get(self, timeout: Optional[float] = None) -> Optional[PilotCommand]:
        """The next command that may still start; older ones are refused on the way
        (:meth:`take_rejections` says which), never returned."""
        deadline = None if not timeout else self.clock() + timeout
        while True:
            try:
                wait = None if deadline is None else max(0.0, deadline - self.clock())
                command, arrived = self.queue.get(timeout=wait) if wait else \
                    self.queue.get_nowait()
            except queue.Empty:
                return None
            lifetime = (command.lifetime or Lifetime()).older(self.clock() - arrived)
            if not lifetime.expired(self.validity):
                if self.taking_accepts:
                    if command.seq is not None and self.journal is not None:
                        self.in_hand.append(command.seq)
                        self._journal(TAKEN, command.seq)
                    self._receipt(command, CommandState.ACCEPTED)
                return command
            self.expired += 1
            refusal = describe_expiry(command_text(command), lifetime, self.validity)
            self.rejected.append(refusal)
            self._journal(ENDED, command.seq)
            self._receipt(command, CommandState.EXPIRED, refusal)
            if self.on_arrival:
                self.on_arrival()   # the refusal is said now, not with the next command

    def take_rejections(self) -> List[str]:
        rejected, self.rejected = self.rejected, []
        return rejected


class PilotInterfaces:
    """Opens and serves the module's :data:`GYM_PORTS` under ``/P``."""

    def __init__(self, prefix: str, nameclient: Optional[NameClient] = None,
                 statuses: Optional[Sequence[str]] = None,
                 command_decoder: Callable[[Bottle], PilotCommand] = decode_command,
                 status_encoder: Optional[Callable[[int, str, Sequence], Bottle]] = None,
                 validity: float = DEFAULT_VALIDITY) -> None:
        self.prefix = prefix.rstrip("/")
        self.nameclient = nameclient or NameClient()
        self.statuses = list(statuses) if statuses else None
        self.validity = validity
        self.switch = _Inbox(decode_command, validity, taking_accepts=False)
        self.commands = _Inbox(command_decoder, validity)
        self.status_encoder = status_encoder or (
            lambda seq, state, data: encode_status(seq, state, data, self.statuses))
        # Sequences start at 2: ``yarp read`` takes ``(1 "text")`` for end-of-stream.
        self._status_seq = itertools.count(2)
        self._warning_seq = itertools.count(2)
        self.state = "initializing"
        self.data: list = []
        self.ports: List[Port] = []
        self.status_port: Optional[Port] = None
        self.warning_port: Optional[Port] = None
        self.receipt_port: Optional[Port] = None
        self.switch.on_receipt = self.commands.on_receipt = self.receipt

    def open(self, wait: float) -> None:
        switch = Port(nameclient=self.nameclient, reader=self.switch.feed)
        switch.open(SWITCH.of(self.prefix), wait=wait)
        command = Port(nameclient=self.nameclient, reader=self.commands.feed)
        command.open(COMMAND.of(self.prefix), wait=wait)
        self.status_port = Port(nameclient=self.nameclient)
        self.status_port.open(STATUS.of(self.prefix), wait=wait)
        self.warning_port = self._reliable_output(WARNING, wait)
        self.receipt_port = self._reliable_output(RECEIPT, wait)
        self.ports = [switch, command, self.status_port, self.warning_port, self.receipt_port]

    def _reliable_output(self, gym_port: GymPort, wait: float) -> Port:
        """A port whose messages say something once: held for readers that connect later,
        and sent in order by a thread of its own.  The watchdog that writes them must never
        wait on a reader: a robot bridge whose link to the pilot was down held back its
        acknowledgements of drc_door's warnings (a flood of "may not command" while another
        module held the arms) for 5 s, and the supervisor killed the module as hung."""
        port = BufferedPort(nameclient=self.nameclient, strict=True)
        port.hold_for_late_readers(HELD_MESSAGES, held_for(self.validity))
        port.open(gym_port.of(self.prefix), wait=wait)
        return port

    def set_status(self, state: str, data: Sequence = ()) -> bool:
        """Record the status; True when it changed (the watchdog then sends it at once)."""
        changed = state != self.state or list(data) != self.data
        self.state, self.data = state, list(data)
        return changed

    def send_status(self) -> None:
        """The status to every reader that took the last one: the watchdog that sends it
        also carries out the pilot's ``stop``, and must never wait on a reader held up
        (the status is sent again within a period; a slow reader misses some)."""
        if self.status_port is not None:
            self.status_port.write(self.status_encoder(next(self._status_seq), self.state,
                                                       self.data), skip_busy=True)

    def warn(self, text: str) -> None:
        if self.warning_port is not None:
            self.warning_port.write(Bottle([next(self._warning_seq), text]))

    def receipt(self, receipt: Receipt) -> None:
        """Say what became of a numbered switch or command (``/P/receipt:o``)."""
        if self.receipt_port is not None:
            self.receipt_port.write(encode_receipt(receipt))

    def close(self) -> None:
        for port in self.ports:
            port.close()


class RecordingInterfaces(PilotInterfaces):
    """Pilot interfaces with no ports: statuses and warnings are kept in lists.

    What the offline runner and in-process tests of the runner use instead of
    YARP; :meth:`wait_for` lets a test wait for what the module says, from any thread.
    """

    def __init__(self, prefix: str, module_class: type) -> None:
        super().__init__(prefix, statuses=getattr(module_class, "statuses", None) or None,
                         command_decoder=decoder_for(module_class),
                         validity=validity_of(module_class))
        self.warnings: List[str] = []
        self.history: List[str] = []
        self.receipts: List[Receipt] = []
        self._changed = threading.Condition()

    def open(self, wait: float) -> None:
        """Nothing to open."""

    def set_status(self, state: str, data: Sequence = ()) -> bool:
        with self._changed:
            if state != self.state:
                self.history.append(state)
            changed = super().set_status(state, data)
            self._changed.notify_all()
        return changed

    def warn(self, text: str) -> None:
        with self._changed:
            self.warnings.append(text)
            self._changed.notify_all()

    def receipt(self, receipt: Receipt) -> None:
        with self._changed:
            self.receipts.append(receipt)
            self._changed.notify_all()

    def wait_for(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Block until ``predicate()`` holds after a status or warning; False on timeout."""
        with self._changed:
            return self._changed.wait_for(predicate, timeout)
