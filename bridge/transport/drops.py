"""What the bridge drops, why, and how it says so: one place for both channels.

Theory of operation
-------------------
A bridge drops input for few reasons, and each is a decision of this module:

* the sender is not the peer (:func:`from_peer`) -- a stranger on the network;
* the bytes fail the link's tag or replay window -- forged, tampered, replayed
  (:mod:`bridge.wire.link` raises, the channel reports it here);
* they break a codec -- malformed;
* they name an id the configuration does not have -- unknown id;
* they are older than what was already published (:func:`is_newer`) -- stale;
  a reliable message already accepted -- duplicate;
* a streaming value cannot leave because the link is slower than we write
  (:func:`hold_back`) -- held back, the next period sends a fresher one;
* a message for a local port that does not exist yet, or for a flow no longer
  configured.

Reliable messages (pilot commands, warnings) are never dropped by policy: they
wait in the journal.  Every drop is counted in a :class:`DropLedger` by
:class:`Reason` (the bridge status shows the counts) and logged by yarp_lite's
burst rule (:class:`~yarp_lite.bursts.Burst`: the 1st, 10th, 100th ... of a
burst, a new burst after a quiet spell), so a flood cannot flood the log.
"""

from __future__ import annotations

import logging
import threading
import time
from enum import Enum
from typing import Callable, Dict, Iterable, Optional

from bridge.errors import BridgeProtocolError
from bridge.wire.link import AuthenticationFailed, ForgedInput, ReplayedInput
from yarp_lite.bursts import Burst
#: Unsent bytes in the kernel above which a frame's streaming part is held back.
BACKLOG_LIMIT = 2048


class Reason(str, Enum):
    STRANGER = "stranger"              # not from the peer's address
    UNAUTHENTICATED = "unauthenticated"  # a handshake that did not prove the key
    FORGED = "forged"                  # fails its authentication tag
    REPLAYED = "replayed"              # valid tag, already accepted or too old
    MALFORMED = "malformed"            # breaks a codec
    UNKNOWN_ID = "unknown_id"          # id/kind not in the configuration
    STALE = "stale"                    # older than what was already published
    DUPLICATE = "duplicate"            # reliable message already accepted
    HELD_BACK = "held_back"            # streaming value waits: the link is slower
    COPY_SKIPPED = "copy_skipped"      # a datagram copy not sent: the radio's queue is full
    NOT_READY = "not_ready"            # no local endpoint yet for it
    UNCONFIGURED = "unconfigured"      # queued for a flow the configuration dropped
    BUSY = "busy"                      # too many handshakes at once


def reason_for(error: BridgeProtocolError) -> Reason:
    """Which drop a peer error is."""
    if isinstance(error, AuthenticationFailed):
        return Reason.UNAUTHENTICATED
    if isinstance(error, ForgedInput):
        return Reason.FORGED
    if isinstance(error, ReplayedInput):
        return Reason.REPLAYED
    return Reason.MALFORMED


def from_peer(host: str, peer_addresses: Iterable[str]) -> bool:
    """Input is only taken from the peer's addresses (all, if they are unknown)."""
    addresses = set(peer_addresses)
    return not addresses or host in addresses


def is_newer(candidate: int, reference: Optional[int]) -> bool:
    """Message numbers are mod 2**32: newer means less than half the circle ahead."""
    return reference is None or 0 < (candidate - reference) % (1 << 32) < (1 << 31)


def hold_back(unsent_bytes: int) -> bool:
    """Hold a frame's streaming part when the kernel still has this much to send."""
    return unsent_bytes > BACKLOG_LIMIT


class DropLedger:
    """Counts drops by reason and logs each reason by the burst rule (thread-safe)."""

    def __init__(self, channel: str, logger: logging.Logger,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.channel = channel
        self.log = logger
        self.clock = clock
        self.counts: Dict[str, int] = {}
        self.last_error = ""
        self._lock = threading.Lock()
        self._bursts: Dict[Reason, Burst] = {}

    def drop(self, reason: Reason, detail: str = "", count: int = 1) -> None:
        with self._lock:
            total = self.counts.get(reason.value, 0) + count
            self.counts[reason.value] = total
            if detail:
                self.last_error = f"{reason.value}: {detail}"
            burst = self._bursts.setdefault(reason, Burst(clock=self.clock))
        if not burst.record(count):
            return
        level = logging.WARNING if reason not in (Reason.HELD_BACK, Reason.NOT_READY) \
            else logging.INFO
        self.log.log(level, "%s: dropped %s%s (%d in this burst, %d in all)", self.channel,
                     reason.value, f" -- {detail}" if detail else "", burst.count, total)

    def peer_error(self, error: BridgeProtocolError, where: str = "") -> Reason:
        """Count a peer error as its drop reason; return the reason."""
        reason = reason_for(error)
        self.drop(reason, f"{where}: {error}" if where else str(error))
        return reason

    def get(self, reason: Reason) -> int:
        return self.counts.get(reason.value, 0)
