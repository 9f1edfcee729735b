"""BufferedPort: a port that buffers what it receives and sends in the background.

Reading side, as YARP's ``BufferedPort``/``PortReaderBuffer``:

* default ("latest-only"): a new message replaces one still unread, so a slow
  reader always sees the freshest state; a message with a newer one already
  waiting in the connection is not even decoded (a reader that fell behind a
  500 Hz stream catches up at once, instead of working through a second of
  backlog in its socket); :attr:`dropped` counts the casualties;
* ``min_interval=S`` (latest-only): a connection delivers at most one message
  every S seconds, the newest, skipping the rest undecoded -- for a reader that
  needs a 500 Hz stream at its own, slower, rate;
* ``strict=True``: every message is kept, in order; when ``max_pending`` are
  waiting, the sender is held back (TCP pushes back) rather than losing data;
* ``on_read=callback``: each Bottle goes to the callback, one at a time.

Writing side: :meth:`write` hands the Bottle to a sender thread and returns
at once; a newer write replaces a Bottle not yet sent (``strict=False``) or
queues behind it (``strict=True``).  :meth:`wait_for_write` blocks until
everything handed over has left.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Callable, Deque, Optional, Sequence, Tuple, Union

from yarp_lite.bottle import Bottle
from yarp_lite.carriers import Incoming, Payload
from yarp_lite.delivery import Source
from yarp_lite.port import Port


class InboxDelivery:
    """BufferedPort's delivery (:mod:`yarp_lite.delivery`): into an inbox (latest-only, or
    every message in order with ``strict``), or to ``on_read`` one at a time."""

    def __init__(self, is_open: Callable[[], bool], strict: bool, max_pending: int,
                 on_read: Optional[Callable[[Bottle], None]], min_interval: float) -> None:
        if min_interval and strict:
            raise ValueError("min_interval is for latest-only ports, not strict ones")
        self._is_open = is_open
        self.strict = strict
        self.max_pending = max_pending
        self.on_read = on_read
        self.envelope = ""
        self.dropped = 0
        self.received = 0
        self._min_interval = max(0.0, min_interval)
        self._interval_set = threading.Condition()   # wakes connections waiting out the old
        self._inbox: Deque[Tuple[Bottle, str]] = deque()
        self._inbox_cond = threading.Condition()
        self._callback_lock = threading.Lock()

    @property
    def latest_only(self) -> bool:
        return not self.strict

    @property
    def min_interval(self) -> float:
        return self._min_interval

    @min_interval.setter
    def min_interval(self, seconds: float) -> None:
        if self.strict and seconds:
            raise ValueError("min_interval is for latest-only ports, not strict ones")
        with self._interval_set:
            self._min_interval = max(0.0, float(seconds))
            self._interval_set.notify_all()

    def pace(self) -> None:
        if self._min_interval:
            with self._interval_set:
                self._interval_set.wait(self._min_interval)

    def superseded(self, message: Incoming) -> None:
        self.received += 1
        self.dropped += 1

    def deliver(self, message: Incoming, source: Source) -> Optional[Bottle]:
        bottle = message.bottle()
        self.received += 1
        if self.on_read is not None:
            with self._callback_lock:
                self.envelope = message.envelope
                self.on_read(bottle)
            return None
        with self._inbox_cond:
            if self.strict:
                while len(self._inbox) >= self.max_pending and self._is_open():
                    self._inbox_cond.wait(0.5)
            elif self._inbox:
                self.dropped += len(self._inbox)
                self._inbox.clear()
            self._inbox.append((bottle, message.envelope))
            self._inbox_cond.notify_all()
        return None

    def take(self, wait: bool, timeout: Optional[float]) -> Optional[Bottle]:
        """The oldest unread Bottle; None if ``wait`` is False or time runs out."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._inbox_cond:
            while not self._inbox:
                if not wait or not self._is_open():
                    return None
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._inbox_cond.wait(remaining if remaining is not None else 0.5)
            bottle, self.envelope = self._inbox.popleft()
            self._inbox_cond.notify_all()
            return bottle

    @property
    def pending(self) -> int:
        with self._inbox_cond:
            return len(self._inbox)

    def close(self) -> None:
        with self._inbox_cond:
            self._inbox_cond.notify_all()
        with self._interval_set:          # a connection waiting out its interval ends
            self._interval_set.notify_all()


class BufferedPort(Port):
    def __init__(self, name: Optional[str] = None, *, strict: bool = False,
                 max_pending: int = 1000,
                 on_read: Optional[Callable[[Bottle], None]] = None,
                 min_interval: float = 0.0, **kwargs) -> None:
        self.inbox = InboxDelivery(lambda: self.is_open, strict, max_pending, on_read,
                                   min_interval)
        self._outbox: Deque[Tuple[Union[Bottle, Payload], bool]] = deque()
        self._outbox_cond = threading.Condition()
        self._sending = False
        self._sender: Optional[threading.Thread] = None
        super().__init__(name, delivery=self.inbox, **kwargs)

    # -- receiving -----------------------------------------------------------------

    @property
    def min_interval(self) -> float:
        """Seconds a connection waits after delivering a message (0: none); settable."""
        return self.inbox.min_interval

    @min_interval.setter
    def min_interval(self, seconds: float) -> None:
        """A reader whose need changes (a module that starts or stops controlling the robot)
        changes its rate at once: a connection waiting out the old interval stops waiting."""
        self.inbox.min_interval = seconds

    @property
    def strict(self) -> bool:
        """Every message kept, in order, and every write sent (else the newest only)."""
        return self.inbox.strict

    @property
    def max_pending(self) -> int:
        """Strict: messages waiting at most before the sender is held back."""
        return self.inbox.max_pending

    @max_pending.setter
    def max_pending(self, count: int) -> None:
        self.inbox.max_pending = count

    @property
    def dropped(self) -> int:
        """Messages a newer one replaced before they were read (latest-only)."""
        return self.inbox.dropped

    @property
    def received(self) -> int:
        return self.inbox.received

    @property
    def on_read(self) -> Optional[Callable[[Bottle], None]]:
        return self.inbox.on_read

    @on_read.setter
    def on_read(self, callback: Optional[Callable[[Bottle], None]]) -> None:
        self.inbox.on_read = callback

    def read(self, wait: bool = True, timeout: Optional[float] = None,  # type: ignore[override]
             will_reply: bool = False) -> Optional[Bottle]:
        """The oldest unread Bottle; None if ``wait`` is False or time runs out."""
        return self.inbox.take(wait, timeout)

    @property
    def pending(self) -> int:
        return self.inbox.pending

    # -- sending ---------------------------------------------------------------------

    def write(self, bottle: Union[Bottle, Sequence, Payload], strict: Optional[bool] = None) -> bool:
        """Queue ``bottle`` for the sender thread; return immediately."""
        keep_all = self.strict if strict is None else strict
        item = bottle if isinstance(bottle, (Bottle, Payload)) else Bottle(bottle)
        with self._outbox_cond:
            if not keep_all and self._outbox:
                self._outbox.clear()
            self._outbox.append((item, keep_all))
            if self._sender is None or not self._sender.is_alive():
                self._sender = threading.Thread(target=self._send_loop, daemon=True,
                                                name=f"{self.name} sender")
                self._sender.start()
            self._outbox_cond.notify_all()
        return True

    def wait_for_write(self, timeout: Optional[float] = None) -> bool:
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._outbox_cond:
            while self._outbox or self._sending:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self._outbox_cond.wait(remaining if remaining is not None else 0.5)
        return True

    def _send_loop(self) -> None:
        while True:
            with self._outbox_cond:
                while not self._outbox:
                    if not self.is_open:
                        return
                    self._outbox_cond.wait(0.5)
                item, _ = self._outbox.popleft()
                self._sending = True
            try:
                Port.write(self, item)
            finally:
                with self._outbox_cond:
                    self._sending = False
                    self._outbox_cond.notify_all()

    def close(self) -> None:
        if self.is_open:
            self.wait_for_write(timeout=2.0)
        super().close()
        with self._outbox_cond:
            self._outbox_cond.notify_all()
