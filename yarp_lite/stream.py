"""Thin blocking byte streams over sockets: the only place yarp_lite calls recv/send.

A :class:`Stream` is what carriers talk through.  :class:`SocketStream` wraps
a connected TCP socket with a small read buffer (so line reads and 8-byte
reads do not cost a syscall each) and scatter-gather writes (so a header and
a 1 MB blob leave in one ``sendmsg`` without being joined first).
:class:`DatagramStream` (in :mod:`yarp_lite.carriers.udp`) offers the same
interface over UDP.  Every read raises :class:`NetworkError` when the peer goes
away, so callers never see ``OSError`` or a silent short read.
:func:`authenticate` drives the sans-IO :class:`yarp_lite.auth.Handshake` over
a fresh socket, for both the side that connected and the side that accepted.
"""

from __future__ import annotations

import os
import socket
import threading
import time
from typing import Optional, Tuple, Union

from yarp_lite import auth
from yarp_lite.errors import NetworkError, RemoteProtocolError
from yarp_lite.lines import split_line

Buffer = Union[bytes, bytearray, memoryview]
Address = Tuple[str, int]

_RECV_CHUNK = 262144
#: Adaptive busy-poll window (``YARP_LITE_SPIN_US``, 0 disables).  When the
#: peer answered within this window last time (request/reply traffic), the
#: next read polls the socket for that long before sleeping: on a VM a sleep
#: and wake-up costs more than the whole Python round trip.  Streams that
#: wait longer (periodic data) never spin, so idle connections cost nothing.
SPIN_SECONDS = float(os.environ.get("YARP_LITE_SPIN_US", "150")) / 1e6
_this_thread = threading.local()
_perf = time.perf_counter
#: Longest text line accepted from a peer (a text-mode Bottle or command).
MAX_LINE = 1 << 20


def no_spin_in_this_thread() -> None:
    """Reads in the calling thread never busy-poll: a real-time thread polling its socket
    would keep the threads it feeds off the CPU (``walkman.realtime``)."""
    _this_thread.no_spin = True


def no_spin_in_this_process() -> None:
    """:func:`no_spin_in_this_thread` for every thread (a process whose threads are all
    real-time)."""
    global SPIN_SECONDS
    SPIN_SECONDS = 0.0


class Stream:
    """Interface shared by the socket and datagram streams."""

    where: str = "stream"

    def read_exact(self, count: int) -> bytes:
        raise NotImplementedError

    def read_some(self) -> bytes:
        raise NotImplementedError

    def read_line(self, limit: int = MAX_LINE) -> str:
        raise NotImplementedError

    def unread(self, data: bytes) -> None:
        """Push bytes back so the next read sees them first."""
        raise NotImplementedError

    def write(self, *chunks: Buffer) -> None:
        raise NotImplementedError

    def flush(self) -> None:
        """Mark a message boundary (datagram streams send here)."""

    def readable_now(self) -> bool:
        """Whether a read would find bytes at once (never blocks)."""
        return False

    def close(self) -> None:
        raise NotImplementedError

    @property
    def local_address(self) -> Address:
        raise NotImplementedError

    @property
    def remote_address(self) -> Address:
        raise NotImplementedError


class SocketStream(Stream):
    """A connected TCP socket with buffered reads and gathered writes."""

    def __init__(self, sock: socket.socket, where: str = "tcp") -> None:
        # Blocking, whatever socket.setdefaulttimeout() says: rospy sets 60 s process-wide
        # when a subscriber connects, and an accepted socket would inherit it -- an input
        # idle for a minute (a module's warning port) was then dropped while its sender
        # still believed it connected.  Reads that want a deadline set one themselves.
        sock.settimeout(None)
        self.sock = sock
        self.where = where
        self._buffer = bytearray()
        self._start = 0
        self._closed = False
        self._last_wait = 0.0
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError:
            pass  # not TCP (no Nagle to turn off), or gone: getpeername says so
        try:
            self._local = sock.getsockname()[:2]
            self._remote = sock.getpeername()[:2]
        except OSError as exc:
            raise NetworkError(f"{where}: socket is not connected ({exc})") from exc

    @classmethod
    def connect(cls, host: str, port: int, timeout: Optional[float] = 10.0,
                where: str = "", retry_refused: float = 0.0) -> "SocketStream":
        """Connect; a *refused* connection is tried again for ``retry_refused`` seconds.

        Only ECONNREFUSED retries (pauses of 20 ms doubling to 250 ms): it is
        what a port that registered but does not listen yet answers.  An
        unreachable host or a timeout fails at once.
        """
        deadline = time.monotonic() + retry_refused
        pause = 0.02
        while True:
            try:
                sock = socket.create_connection((host, port), timeout=timeout)
                break
            except ConnectionRefusedError as exc:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise NetworkError(f"cannot connect to {host}:{port}: "
                                       f"{exc.strerror or exc}") from exc
                time.sleep(min(pause, remaining))
                pause = min(pause * 2, 0.25)
            except OSError as exc:
                raise NetworkError(f"cannot connect to {host}:{port}: {exc.strerror or exc}") \
                    from exc
        sock.settimeout(None)
        return cls(sock, where or f"tcp {host}:{port}")

    # -- reading ---------------------------------------------------------------

    def _fill(self) -> None:
        if self._closed:
            raise NetworkError(f"{self.where}: stream closed")
        data = None
        started = _perf()
        try:
            if SPIN_SECONDS and self._last_wait < SPIN_SECONDS and \
                    not getattr(_this_thread, "no_spin", False):
                deadline = started + SPIN_SECONDS
                recv = self.sock.recv
                while True:
                    try:
                        data = recv(_RECV_CHUNK, socket.MSG_DONTWAIT)
                        break
                    except BlockingIOError:
                        if _perf() > deadline:
                            break
            if data is None:
                data = self.sock.recv(_RECV_CHUNK)
        except (OSError, ValueError) as exc:
            raise NetworkError(f"{self.where}: receive failed: {exc}") from exc
        self._last_wait = _perf() - started
        if not data:
            raise NetworkError(f"{self.where}: peer closed the connection")
        if self._start == len(self._buffer):
            self._buffer = bytearray(data)
            self._start = 0
        else:
            self._buffer += data

    @property
    def buffered(self) -> int:
        return len(self._buffer) - self._start

    def readable_now(self) -> bool:
        if self.buffered:
            return True
        try:
            return bool(self.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT))
        except (OSError, ValueError):
            return False

    def _take(self, count: int) -> bytes:
        data = bytes(self._buffer[self._start:self._start + count])
        self._start += count
        if self._start == len(self._buffer):
            self._buffer.clear()
            self._start = 0
        return data

    def read_exact(self, count: int) -> bytes:
        if count > self.buffered and count > _RECV_CHUNK:
            return self._read_large(count)
        while self.buffered < count:
            self._fill()
        return self._take(count)

    def _read_large(self, count: int) -> bytes:
        out = bytearray(count)
        view = memoryview(out)
        have = min(self.buffered, count)
        view[:have] = self._buffer[self._start:self._start + have]
        self._start += have
        self.read_into(view[have:])
        return bytes(out)

    def read_into(self, view: memoryview) -> None:
        """Fill ``view`` completely, straight from the socket when possible."""
        filled = 0
        have = min(self.buffered, len(view))
        if have:
            view[:have] = self._buffer[self._start:self._start + have]
            self._start += have
            filled = have
        while filled < len(view):
            try:
                got = self.sock.recv_into(view[filled:])
            except (OSError, ValueError) as exc:
                raise NetworkError(f"{self.where}: receive failed: {exc}") from exc
            if not got:
                raise NetworkError(f"{self.where}: peer closed the connection")
            filled += got

    def read_some(self) -> bytes:
        if not self.buffered:
            self._fill()
        return self._take(self.buffered)

    def read_line(self, limit: int = MAX_LINE) -> str:
        """One line as YARP reads it (see :func:`yarp_lite.lines.split_line`)."""
        while True:
            found = split_line(self._buffer, self._start)
            if found is not None:
                line, end = found
                self._take(end - self._start)
                return line
            if self.buffered > limit:
                raise RemoteProtocolError(f"line longer than {limit} bytes", self.where)
            self._fill()

    def unread(self, data: bytes) -> None:
        self._buffer[self._start:self._start] = data

    # -- writing ---------------------------------------------------------------

    def write(self, *chunks: Buffer) -> None:
        if self._closed:
            raise NetworkError(f"{self.where}: stream closed")
        if all(type(chunk) is bytes for chunk in chunks):
            total = b"".join(chunks)
            if len(total) <= _RECV_CHUNK:
                try:
                    self.sock.sendall(total)
                except (OSError, ValueError) as exc:
                    raise NetworkError(f"{self.where}: send failed: {exc}") from exc
                return
        pending = [memoryview(chunk).cast("B") for chunk in chunks if len(chunk)]
        try:
            while pending:
                sent = self.sock.sendmsg(pending[:1024])
                while sent and pending:
                    head = pending[0]
                    if sent >= len(head):
                        sent -= len(head)
                        pending.pop(0)
                    else:
                        pending[0] = head[sent:]
                        sent = 0
        except (OSError, ValueError) as exc:
            raise NetworkError(f"{self.where}: send failed: {exc}") from exc

    def set_timeout(self, timeout: Optional[float]) -> None:
        try:
            self.sock.settimeout(timeout)
        except OSError:
            pass  # socket already closed: the next read or write reports it

    def shutdown_read(self) -> None:
        """Wake a thread blocked in recv on this stream (used by close())."""
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass  # not connected or already closed: no reader to wake

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.shutdown_read()
            self.sock.close()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def local_address(self) -> Address:
        return self._local

    @property
    def remote_address(self) -> Address:
        return self._remote


def authenticate(stream: SocketStream, role: auth.Role, config: auth.AuthConfig) -> None:
    """YARP's AuthHMAC exchange on a fresh connection, before any carrier byte.

    A no-op when ``config`` has no key.  Each awaited message must arrive
    within :data:`yarp_lite.auth.TIMEOUT` (YARP's 2 s; a whole message, so a
    peer dripping bytes cannot hold us longer).  Raises
    :class:`~yarp_lite.errors.AuthenticationError`; the caller closes.
    """
    if not config.enabled:
        return
    machine = auth.Handshake(role, config, stream.where)
    previous = stream.sock.gettimeout()
    try:
        while True:
            pending = machine.data_to_send()
            if pending:
                stream.set_timeout(auth.TIMEOUT)
                stream.write(pending)
            if machine.done:
                break
            deadline = time.monotonic() + auth.TIMEOUT
            awaited = machine.state
            while machine.state is awaited:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise machine.failure(f"no answer within {auth.TIMEOUT:g} s")
                stream.set_timeout(remaining)
                try:
                    machine.receive_data(stream.read_some())
                except NetworkError as exc:
                    if time.monotonic() >= deadline:
                        raise machine.failure(f"no answer within {auth.TIMEOUT:g} s") from exc
                    raise machine.failure(_without_where(exc, stream)) from exc
    except NetworkError as exc:  # a write failed
        raise machine.failure(_without_where(exc, stream)) from exc
    if machine.trailing:
        stream.unread(machine.trailing)
    stream.set_timeout(previous)


def _without_where(exc: NetworkError, stream: Stream) -> str:
    return str(exc).removeprefix(f"{stream.where}: ")
