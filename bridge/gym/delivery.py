"""The inbox: reliable messages from the link written to their local ports, each exactly once.

Theory of operation
-------------------
The TCP channel puts every reliable message (a pilot's switch or command, a
module's warning, a receipt) in the journal as it arrives and wakes
:meth:`Delivery.run`, which writes the undelivered ones in order, one flow at a
time.  A message stays in the journal until its port takes it: a command to a
module that is down (or whose stand-in is not open yet) waits for it, and the
flows behind it are not held up.  An exception from a port -- its network gone,
or our bug -- blocks only that flow until the next round, so the thread never
dies and nothing is lost.

On the way out an expiring message (a GYM switch or command) is aged by the
time it spent on the link and in the inbox (:func:`bridge.gym.expiry.aged_payload`),
so the module can refuse one that arrives too late for the pilot's intent; one
the pilot cancelled arrives as a tombstone and is dropped.  Each delivered one
is said on its module's receipt flow (:mod:`walkman.gym.command_life`).  On the
pilot side :meth:`Delivery.cancel` takes back commands that no frame has
carried yet.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

from bridge.config import PILOT, BridgeConfig
from bridge.errors import BridgeProtocolError, BridgeUsageError
from bridge.flows import FlowKey, Route
from bridge.gym.expiry import aged_payload
from bridge.transport.drops import DropLedger, Reason
from bridge.transport.journal import Journal, is_tombstone
from bridge.wire import compact
from walkman.gym.command_life import CommandState, Receipt, encode_receipt
from walkman.gym.interfaces import GYM_PORTS, RECEIPT, command_seq
from walkman.gym.validity import ValidityError, split
from yarp_lite.errors import YarpError

log = logging.getLogger("bridge")

#: The kind of a GYM module's receipt flow.
RECEIPT_KIND = GYM_PORTS.index(RECEIPT)


class Delivery:
    """Writes the journal's undelivered messages to the endpoints ``source`` names."""

    def __init__(self, config: BridgeConfig, side: str, journal: Journal,
                 routes: Dict[FlowKey, Route], source: Callable[[FlowKey], Optional[Any]],
                 post: Callable[[Route, Any], None], one_way: Callable[[], float],
                 on_delivered: Callable[[int], None], drops: DropLedger) -> None:
        self.config = config
        self.side = side
        self.journal = journal
        self.routes = routes
        self._source = source            # the open endpoint of a flow, if any
        self._post = post                # a receipt onto the link
        self._one_way = one_way          # s a message takes over the link now
        self._on_delivered = on_delivered   # a module id: its status changes are answers
        self.drops = drops
        self.wake = threading.Event()
        self.delivered = 0
        self.cancelled_dropped = 0       # tombstones of cancelled commands, not delivered
        self.internal_errors = 0

    def run(self, stopping: threading.Event) -> None:
        """Deliver until ``stopping``, a round whenever woken (at least every 0.25 s)."""
        failing: set = set()   # rows whose delivery raised a bug, logged once each
        while not stopping.is_set():
            self.wake.wait(0.25)
            self.wake.clear()
            self.round(failing)

    def round(self, failing: set) -> None:
        blocked = set()
        for message in self.journal.undelivered():
            row, key = message.row, FlowKey(message.id, message.kind)
            if key in blocked:
                continue
            route = self.routes.get(key)
            if route is None:
                self.drops.drop(Reason.UNCONFIGURED, f"queued message for {key}")
                self.journal.delivered(row)
                continue
            payload = message.payload
            if route.expiring and _cancelled(payload):   # the pilot took it back
                self.journal.delivered(row)
                self.cancelled_dropped += 1
                continue
            if route.expiring:   # the link's way over, and the wait in our inbox
                payload = aged_payload(payload, self._one_way() + time.time() - message.received)
            source = self._source(key)
            try:
                # A stand-in closed meanwhile says not delivered: kept.
                ok = source is not None and source.ready and \
                    source.deliver(compact.decode(payload))
            except BridgeProtocolError as exc:
                self.drops.peer_error(exc, "queued message")
                self.journal.delivered(row)
                continue
            except YarpError as exc:
                log.warning("delivering on %s failed, will retry: %s", key, exc)
                ok = False
            except Exception:  # noqa: BLE001 -- our bug: seen, counted, message kept
                self.internal_errors += 1
                if row not in failing:
                    failing.add(row)
                    log.exception("delivering queued message %d on %s failed (a bug); "
                                  "it stays queued", row, key)
                ok = False
            if ok:
                self.journal.delivered(row)
                self.delivered += 1
                self._on_delivered(key.id)
                if route.expiring:
                    self._say_delivered(key, payload)
            else:
                blocked.add(key)

    def _say_delivered(self, key: FlowKey, payload: bytes) -> None:
        """Tell the pilots a numbered switch or command reached its module's port."""
        receipts = self.routes.get(FlowKey(key.id, RECEIPT_KIND))
        seq = command_seq(compact.decode(payload))
        if receipts is not None and seq is not None:
            self._post(receipts, encode_receipt(Receipt(seq, CommandState.DELIVERED)))

    def cancel(self, module: str, seq: Optional[int]) -> Tuple[List[int], List[int]]:
        """Take back the module's switch or command numbered ``seq`` (every one, for None)
        if no frame has carried it yet; ``(cancelled, too late)`` sequence numbers.  The
        pilots hear of each cancelled one on the module's receipt port."""
        if self.side != PILOT:
            raise BridgeUsageError("commands are cancelled on the pilot side, where they wait")
        ident = self.config.modules.get(module)
        if ident is None or module not in self.config.gym_modules:
            raise BridgeUsageError(f"{module!r} is not a GYM module of {self.config.path}")
        flows = {key for key, route in self.routes.items()
                 if key.id == ident and route.expiring}
        wanted = lambda payload: seq is None or _seq_of(payload) == seq  # noqa: E731
        cancelled, too_late = self.journal.cancel(flows, wanted)
        numbers = [n for n in map(_seq_of, cancelled) if n is not None]
        late = [n for n in map(_seq_of, too_late) if n is not None]
        receipts = self._source(FlowKey(ident, RECEIPT_KIND))
        for number in numbers:
            log.info("cancelled %s's command %d before it left", module, number)
            if receipts is not None:
                receipts.deliver(encode_receipt(Receipt(number, CommandState.CANCELLED,
                                                        "cancelled by a pilot")))
        return numbers, late


def _seq_of(payload: bytes) -> Optional[int]:
    """The sequence number of a journalled switch or command, if it has one."""
    try:
        return command_seq(compact.decode(payload))
    except BridgeProtocolError:
        return None


def _cancelled(payload: bytes) -> bool:
    """Is this journalled switch or command the tombstone of a cancelled one?"""
    try:
        message, _ = split(compact.decode(payload))
    except (BridgeProtocolError, ValidityError):
        return False
    return is_tombstone(message)
