"""The stop-all across the link: sent by every way at once, acted on by the first copy.

Theory of operation
-------------------
The pilot's stop-all (``stop_all`` on ``/bridge/pilot/rpc:i``, which the gateway's
``/pilot/stop_all`` and the PI's button call) must reach the robot even when the
link is bad: it skips the journal and the period, goes at once on the TCP channel
*and* as repeated datagrams on the UDP channel, and is sent again -- as datagrams only,
after :data:`RESEND`, then twice as long each time up to :data:`RESEND_MAX` -- until the
robot acknowledges it.  Each stop carries a random id; the robot acts on the first copy
of an id (:class:`walkman.gym.stop_all.StopAll`: the HAL holds, every module pauses) and
answers the copies with the same acknowledgement, which comes back the same two ways, at
most once per :data:`ANSWER_GAP`.  ``release`` travels alike.

The back-off and the gap keep the stop from drowning itself: on a 9600 bit/s radio a TCP
copy and three datagrams every 250 ms, each copy answered by four more, were more than
the link carries, and the acknowledgements were lost in their own queue.

Messages (Bottles): ``stop_all ID`` / ``release ID`` pilot->robot;
``held ID HAL_OK MS MODULE...`` / ``released ID HAL_OK MS`` robot->pilot.  They
ride on the bridge's authenticated channels: a stranger cannot stop the robot.
"""

from __future__ import annotations

import logging
import random
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Tuple

from bridge.transport.nursery import Nursery
from yarp_lite.bottle import Bottle

log = logging.getLogger("bridge.stop")

#: Seconds before a stop not yet acknowledged is sent again; the wait doubles each time.
RESEND = 0.25
#: The longest wait between two sendings.
RESEND_MAX = 2.0
#: Seconds between two answers the robot sends to copies of one stop.
ANSWER_GAP = 0.2
#: Stop ids a robot remembers (a late copy of an old stop is answered, never acted on again).
REMEMBERED = 64
VERBS = {"stop_all": "held", "release": "released"}


class StopLineError(ValueError):
    """A stop-all message is malformed; the text says how."""


@dataclass(frozen=True)
class Ack:
    stop_id: int
    word: str                 # held or released
    hal: bool
    took_ms: float            # on the robot, from the first copy to the HAL's and modules' answer
    modules: Tuple[str, ...] = ()
    round_trip_ms: float = 0.0    # on the pilot: from the first sending to this answer


def parse_order(bottle: Any) -> Tuple[str, int]:
    if not isinstance(bottle, list) or len(bottle) != 2 or bottle[0] not in VERBS or \
            isinstance(bottle[1], bool) or not isinstance(bottle[1], int):
        raise StopLineError(f"a stop order is stop_all ID or release ID, got {bottle!r}")
    return str(bottle[0]), int(bottle[1])


def encode_ack(ack: Ack) -> Bottle:
    return Bottle([ack.word, ack.stop_id, int(ack.hal), round(ack.took_ms, 1),
                   *ack.modules])


def parse_ack(bottle: Any) -> Ack:
    if not isinstance(bottle, list) or len(bottle) < 4 or bottle[0] not in VERBS.values() or \
            not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                    for v in bottle[1:4]) or not all(isinstance(m, str) for m in bottle[4:]):
        raise StopLineError(f"a stop acknowledgement is held|released ID HAL MS MODULE..., "
                            f"got {bottle!r}")
    return Ack(int(bottle[1]), str(bottle[0]), bool(bottle[2]), float(bottle[3]),
               tuple(str(m) for m in bottle[4:]))


#: ``send(order, again)``: ``again`` is a resending (datagrams only, :mod:`bridge.node`).
SendOrder = Callable[[Bottle, bool], None]


class PilotStops:
    """The pilot side: sends a stop or release until acknowledged.

    The first resending waits :data:`RESEND`, or the link's measured round trip
    (``round_trip()``, seconds: the TCP channel's) where that is longer: on a 9600 bit/s
    radio an answer takes most of a second to come back, and copies sent meanwhile only
    queue in front of the next stop, each answered again by the robot.
    """

    def __init__(self, send: SendOrder, round_trip: Callable[[], float] = lambda: 0.0) -> None:
        self._send = send
        self._round_trip = round_trip
        self._lock = threading.Condition()
        self._acks: Dict[int, Ack] = {}

    def order(self, word: str, timeout: float) -> Optional[Ack]:
        """``stop_all`` or ``release``; the robot's acknowledgement, or None in time."""
        stop_id = random.SystemRandom().getrandbits(31) or 1
        started = time.monotonic()
        deadline = started + timeout
        order = Bottle([word, stop_id])
        log.info("%s %d: sent", word, stop_id)
        wait, again = min(max(RESEND, self._round_trip()), RESEND_MAX), False
        with self._lock:
            while stop_id not in self._acks:
                self._send(order, again)
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    log.error("%s %d: no acknowledgement from the robot within %g s", word,
                              stop_id, timeout)
                    return None
                self._lock.wait(min(wait, remaining))
                wait, again = min(2 * wait, RESEND_MAX), True
            ack = self._acks.pop(stop_id)
        rtt = (time.monotonic() - started) * 1000.0
        log.info("%s %d: acknowledged (%s) %.0f ms after it was sent", word, stop_id, ack.word,
                 rtt)
        return Ack(ack.stop_id, ack.word, ack.hal, ack.took_ms, ack.modules, rtt)

    def on_ack(self, bottle: Any) -> None:
        try:
            ack = parse_ack(bottle)
        except StopLineError as exc:
            log.warning("stop line: %s", exc)
            return
        with self._lock:
            self._acks[ack.stop_id] = ack
            while len(self._acks) > REMEMBERED:
                del self._acks[next(iter(self._acks))]
            self._lock.notify_all()


@dataclass
class RobotStops:
    """The robot side: carries out each order once (``carry_out(word, id) -> Ack``, run in
    a thread of its own, started by ``threads``), answers its copies, at most once per
    :data:`ANSWER_GAP`: ``send(ack, again)``, ``again`` for every answer after the first
    (datagrams only: the TCP connection carries the first)."""

    carry_out: Callable[[str, int], Ack]
    send: SendOrder
    clock: Callable[[], float] = time.monotonic
    threads: Nursery = field(default_factory=Nursery)
    _done: Dict[int, Optional[Ack]] = field(default_factory=dict)
    _answered: Dict[int, float] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def on_order(self, bottle: Any) -> None:
        try:
            word, stop_id = parse_order(bottle)
        except StopLineError as exc:
            log.warning("stop line: %s", exc)
            return
        with self._lock:
            if stop_id in self._done:
                ack = self._done[stop_id]
                now = self.clock()
                if ack is not None and now - self._answered.get(stop_id, -ANSWER_GAP) >= \
                        ANSWER_GAP:      # a copy after the answer: answer again, now and then
                    self._answered[stop_id] = now
                    self.send(encode_ack(ack), True)
                return                   # a copy while it is carried out: one answer comes
            self._done[stop_id] = None
            log.info("%s %d: its first copy arrived, carrying it out", word, stop_id)
            while len(self._done) > REMEMBERED:
                gone = next(iter(self._done))
                del self._done[gone]
                self._answered.pop(gone, None)
        self.threads.start_soon(lambda: self._carry_out(word, stop_id), f"stop {stop_id}")

    def _carry_out(self, word: str, stop_id: int) -> None:
        ack = self.carry_out(word, stop_id)
        log.info("%s %d: %s, the HAL %s, in %.1f ms", word, stop_id, ack.word,
                 "with it" if ack.hal else "NOT with it", ack.took_ms)
        with self._lock:
            self._done[stop_id] = ack
            self._answered[stop_id] = self.clock()
        self.send(encode_ack(ack), False)
