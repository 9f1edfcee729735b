"""yarp_lite.stream on in-process sockets: refused-connection retry and the auth driver."""

from __future__ import annotations

import socket
import threading
import time
from typing import Callable

import pytest

from yarp_lite import auth, stream
from yarp_lite.auth import AuthConfig, Role
from yarp_lite.errors import AuthenticationError, NetworkError
from yarp_lite.stream import SocketStream, authenticate

KEY = AuthConfig.with_key("k1")


# -- connect: only a refusal is retried ----------------------------------------------------


def test_a_refused_connection_succeeds_once_the_port_listens(monkeypatch):
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))  # bound but not listening: connections are refused
    port = listener.getsockname()[1]
    refusals = []
    real = socket.create_connection

    def listen_after_two_refusals(*args, **kwargs):
        try:
            return real(*args, **kwargs)
        except ConnectionRefusedError:
            refusals.append(1)
            if len(refusals) == 2:
                listener.listen()
            raise

    monkeypatch.setattr(stream.socket, "create_connection", listen_after_two_refusals)
    with listener:
        connected = SocketStream.connect("127.0.0.1", port, retry_refused=5.0)
        connected.close()
    assert len(refusals) == 2


def test_refusals_are_retried_for_a_bounded_time():
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        port = listener.getsockname()[1]
        started = time.monotonic()
        with pytest.raises(NetworkError, match="cannot connect"):
            SocketStream.connect("127.0.0.1", port, retry_refused=0.4)
        elapsed = time.monotonic() - started
    assert 0.4 <= elapsed < 1.5


def test_other_connection_failures_are_not_retried(monkeypatch):
    calls = []

    def unreachable(*args, **kwargs):
        calls.append(1)
        raise OSError(101, "Network is unreachable")

    monkeypatch.setattr(stream.socket, "create_connection", unreachable)
    with pytest.raises(NetworkError, match="unreachable"):
        SocketStream.connect("192.0.2.1", 9, retry_refused=5.0)
    assert calls == [1]


# -- authenticate: the handshake over a socket ----------------------------------------------


@pytest.fixture
def streams():
    left, right = socket.socketpair()
    pair = SocketStream(left, "acceptor side"), SocketStream(right, "connector side")
    yield pair
    for each in pair:
        each.close()


def in_thread(function, *args):
    outcome = {}

    def run():
        try:
            function(*args)
            outcome["ok"] = True
        except AuthenticationError as exc:
            outcome["error"] = exc
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, outcome


def test_both_sides_authenticate_and_carrier_bytes_follow(streams):
    acceptor, connector = streams
    thread, outcome = in_thread(authenticate, acceptor, Role.ACCEPTOR, KEY)
    authenticate(connector, Role.CONNECTOR, KEY)
    connector.write(b"CONNECT /x\r\n")
    thread.join(5)
    assert outcome == {"ok": True}
    assert acceptor.read_line() == "CONNECT /x"
    assert acceptor.sock.gettimeout() is None and connector.sock.gettimeout() is None


def test_without_a_key_nothing_is_exchanged(streams):
    acceptor, connector = streams
    authenticate(acceptor, Role.ACCEPTOR, auth.DISABLED)
    connector.write(b"NAME_SER")
    assert acceptor.read_exact(8) == b"NAME_SER"


def test_wrong_key_fails_on_both_sides(streams):
    acceptor, connector = streams
    thread, outcome = in_thread(authenticate, acceptor, Role.ACCEPTOR, KEY)
    with pytest.raises(AuthenticationError, match="challenge"):
        authenticate(connector, Role.CONNECTOR, AuthConfig.with_key("k2"))
    connector.close()  # what the callers do with a failed stream
    thread.join(5)
    assert "authentication failed" in str(outcome["error"])


def test_a_silent_peer_is_dropped_after_the_timeout(streams, monkeypatch):
    monkeypatch.setattr(auth, "TIMEOUT", 0.3)
    acceptor, connector = streams
    started = time.monotonic()
    with pytest.raises(AuthenticationError, match="no answer within 0.3 s"):
        authenticate(acceptor, Role.ACCEPTOR, KEY)
    assert time.monotonic() - started < 2.0


def test_a_peer_stopping_mid_message_is_dropped_after_the_timeout(streams, monkeypatch):
    monkeypatch.setattr(auth, "TIMEOUT", 0.3)
    acceptor, connector = streams
    connector.write(b"\x00" * 39)
    with pytest.raises(AuthenticationError, match="within 0.3 s"):
        authenticate(acceptor, Role.ACCEPTOR, KEY)


def test_a_peer_hanging_up_is_an_authentication_failure(streams):
    acceptor, connector = streams
    connector.write(b"half")
    connector.sock.shutdown(socket.SHUT_WR)
    with pytest.raises(AuthenticationError, match="peer closed the connection"):
        authenticate(acceptor, Role.ACCEPTOR, KEY)


def test_a_peer_gone_before_the_challenge_is_an_authentication_failure(streams):
    acceptor, connector = streams
    connector.close()
    with pytest.raises(AuthenticationError, match="authentication failed"):
        authenticate(acceptor, Role.ACCEPTOR, KEY)


class _CountingSocket:
    """A socket whose non-blocking reads are counted (the busy-poll's)."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock, self.polls = sock, 0

    def recv(self, size: int, flags: int = 0) -> bytes:
        if flags & socket.MSG_DONTWAIT:
            self.polls += 1
        return self.sock.recv(size, flags)



def polls_of_a_read_that_waits(before: Callable[[], None] = lambda: None) -> int:
    """How often a reader (in a new thread that first calls ``before``) polls its socket
    for a byte that comes 50 ms after one answered at once."""
    left, right = socket.socketpair()
    polls = []

    def read_twice() -> None:
        before()
        reader = SocketStream(left)
        counting = _CountingSocket(left)
        reader.sock = counting  # type: ignore[assignment]
        right.sendall(b"a")
        reader._fill()          # answered at once (a poll, for a spinning thread)...
        reader._last_wait = 0.0  # ...so the next read would poll first (however loaded the
        threading.Timer(0.05, right.sendall, (b"b",)).start()  # machine was just now)
        reader._fill()          # for up to SPIN_SECONDS before sleeping in recv
        polls.append(counting.polls)

    try:
        thread = threading.Thread(target=read_twice)
        thread.start()
        thread.join(5)
        return polls[0]
    finally:
        left.close()
        right.close()


@pytest.mark.skipif(not stream.SPIN_SECONDS, reason="YARP_LITE_SPIN_US=0: no busy-poll at all")
def test_a_thread_told_not_to_spin_sleeps_in_recv_at_once():
    assert polls_of_a_read_that_waits() >= 2
    assert polls_of_a_read_that_waits(stream.no_spin_in_this_thread) == 0
    assert polls_of_a_read_that_waits() >= 2     # other threads still do


def test_a_process_told_not_to_spin_never_polls_in_any_thread(monkeypatch):
    monkeypatch.setattr(stream, "SPIN_SECONDS", 150e-6)  # put back after the test
    assert polls_of_a_read_that_waits() >= 2
    stream.no_spin_in_this_process()
    assert polls_of_a_read_that_waits() == 0
