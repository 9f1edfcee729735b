"""How a port hands what its inputs receive to its owner: the delivery strategies.

Theory of operation
-------------------
Each input connection's thread reads messages and gives every data message to its
port's :class:`Delivery`, which decides where it goes and what is replied.  The
input thread asks the delivery three more things: whether a data message with a
newer one already waiting behind it may be skipped undecoded
(:attr:`Delivery.latest_only`; :meth:`Delivery.superseded` hears of each one), and,
after each delivery, whether to wait before reading the next (:meth:`Delivery.pace`:
what arrives meanwhile waits in the socket).

A plain :class:`~yarp_lite.port.Port` delivers to a callback, or to a blocking
:meth:`~yarp_lite.port.Port.read` through a :class:`Handoff`, as YARP's port adapter
does (:class:`ReaderDelivery`).  :class:`~yarp_lite.buffered_port.BufferedPort`
buffers instead (:class:`yarp_lite.buffered_port.InboxDelivery`).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable, Optional, Protocol, Sequence, Tuple, Union

from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle
from yarp_lite.carriers import Incoming, Payload
from yarp_lite.errors import LocalProtocolError

log = logging.getLogger("yarp_lite.port")

Reply = Optional[Union[Bottle, Sequence]]
Reader = Callable[[Bottle], Reply]


class Source(Protocol):
    """Where a delivered message came from: the input connection it arrived on."""

    route: Route

    @property
    def remote_host(self) -> str:
        """The sending machine's address ("" when not over a socket)."""


class Delivery(Protocol):
    """Where a port's received data messages go (see the module's theory)."""

    #: the envelope of the message delivered or read last (YARP's ``getEnvelope``)
    envelope: str

    @property
    def latest_only(self) -> bool:
        """A data message with a newer one waiting behind it is skipped undecoded."""

    def superseded(self, message: Incoming) -> None:
        """A data message skipped for a newer one."""

    def deliver(self, message: Incoming, source: Source) -> Union[None, Bottle, Payload]:
        """Hand one data message over; its reply, if any."""

    def pace(self) -> None:
        """An input connection's wait after a delivery, before reading the next."""

    def close(self) -> None:
        """The port closed: wake whoever waits for a message."""


class Handoff:
    """Rendezvous between input threads and a blocking :meth:`Port.read`.

    Like YARP's port adapter, a message waits until its reader takes it (so a
    plain Port never buffers), and a reader that promised a reply holds the
    sender until :meth:`Port.reply`.
    """

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.serial = threading.Lock()
        self.item: Optional[Tuple[Incoming, Route]] = None
        self.taken = False
        self.readers = 0
        self.reply_wanted = False
        self.reply_value: Optional[Bottle] = None
        self.reply_ready = False
        self.closed = False

    def offer(self, message: Incoming, route: Route) -> Optional[Bottle]:
        with self.serial:
            with self.cond:
                if self.closed:
                    return None
                self.item, self.taken = (message, route), False
                self.reply_ready, self.reply_value, self.reply_wanted = False, None, False
                self.cond.notify_all()
                # One wake-up: when the reader took it (no reply promised), or replied.
                while not self.closed and not (
                        self.taken and (not self.reply_wanted or self.reply_ready)):
                    self.cond.wait()
                return self.reply_value

    def take(self, timeout: Optional[float], will_reply: bool) -> Optional[Tuple[Incoming, Route]]:
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.cond:
            self.readers += 1
            try:
                while (self.item is None or self.taken) and not self.closed:
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    self.cond.wait(remaining)
                if self.closed:
                    return None
                item = self.item
                self.taken = True
                self.item = None
                self.reply_wanted = will_reply and item[0].wants_reply
                if not self.reply_wanted:  # a promised reply wakes the sender instead
                    self.cond.notify_all()
                return item
            finally:
                self.readers -= 1

    def give_reply(self, reply: Optional[Bottle]) -> bool:
        with self.cond:
            if not self.reply_wanted or self.reply_ready:
                return False
            self.reply_value, self.reply_ready = reply, True
            self.cond.notify_all()
            return True

    def close(self) -> None:
        with self.cond:
            self.closed = True
            self.cond.notify_all()

    def reopen(self) -> None:
        with self.cond:
            self.closed, self.item, self.taken = False, None, False


class ReaderDelivery:
    """A plain port's delivery: to ``reader`` (called in the input's thread with each
    Bottle, and with ``wants_source`` the sender's port name too; what it returns is the
    reply), or, without one, to a blocking :meth:`read`.  A port nobody reads drops what
    arrives."""

    latest_only = False

    def __init__(self, port_name: Callable[[], str], reader: Optional[Reader] = None,
                 wants_source: bool = False) -> None:
        self._port_name = port_name
        self.reader = reader
        self.wants_source = wants_source
        self.envelope = ""
        self._handoff = Handoff()
        self._used_for_read = reader is not None

    def reopen(self) -> None:
        """A port opened again takes messages again (a read already waiting included)."""
        self._handoff.reopen()

    def superseded(self, message: Incoming) -> None:
        """Never: a plain port decodes every message."""

    def pace(self) -> None:
        """No wait: a plain port reads on at once."""

    def close(self) -> None:
        self._handoff.close()

    def deliver(self, message: Incoming, source: Source) -> Union[None, Bottle, Payload]:
        route = source.route
        if message.envelope:
            self.envelope = message.envelope
        if self.reader is not None:
            reply = self.reader(message.bottle(), route.source) if self.wants_source \
                else self.reader(message.bottle())
            if reply is None:
                return None
            return reply if isinstance(reply, Bottle) else Bottle(reply)
        if not self._used_for_read:
            log.debug("%s: nobody reads this port; dropping a message from %s",
                      self._port_name(), route.source)
            return None
        return self._handoff.offer(message, route)

    def read(self, timeout: Optional[float], will_reply: bool) -> Optional[Bottle]:
        """The next Bottle; None on timeout or close.  With ``will_reply`` the sender is
        held until :meth:`reply`."""
        if self.reader is not None:
            raise LocalProtocolError(f"{self._port_name()} delivers to a callback; read() is "
                                     f"unused")
        self._used_for_read = True
        item = self._handoff.take(timeout, will_reply)
        if item is None:
            return None
        message, _ = item
        self.envelope = message.envelope
        return message.bottle()

    def reply(self, bottle: Bottle) -> bool:
        """Answer the message taken by ``read(will_reply=True)``."""
        return self._handoff.give_reply(bottle)
