"""Port authentication with yarp_lite processes on real sockets.

A world whose ``auth.conf`` holds a key: its server and ports work together;
a tool with another key, or none, is refused on both sides with a message
saying so (and which ``auth.conf`` it used) within seconds; peers that stay
silent or send garbage are dropped without blocking anyone else.
"""

from __future__ import annotations

import os
import socket
import time

import pytest

from harness import free_port
from yarp_lite import auth, stream
from yarp_lite.auth import AuthConfig
from yarp_lite.carriers import BottlePayload
from yarp_lite.connection import OutgoingConnection
from yarp_lite.errors import AuthenticationError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

KEY = "walkman-drc-2015"
REFUSED = "authentication failed"


@pytest.fixture
def keyed(make_world, lite, monkeypatch):
    """A yarp-lite server requiring KEY, with this test process holding KEY too."""
    world = make_world(lite, auth_key=KEY)
    world.apply_to_process(monkeypatch)
    monkeypatch.chdir(world.root)  # no stray auth.conf in the current directory
    return world


def test_keyed_server_and_ports_work_together(keyed, lite):
    keyed.server.wait_for(f"Authentication enabled \\(key from {keyed.config}/auth.conf\\)")
    reader = keyed.tool(lite, "read", "/k/r")
    reader.wait_for("Port /k/r active")
    writer = keyed.tool(lite, "write", "/k/w", "/k/r", stdin=True)
    reader.wait_for("Receiving input from /k/w to /k/r using tcp")
    writer.send("hello (1 2) 3.5\n")
    reader.wait_for(r"^hello \(1 2\) 3.5$")
    writer.close_stdin()
    assert writer.wait() == 0
    assert REFUSED not in keyed.server.output()


@pytest.mark.parametrize("rogue_key", ["not-the-key", None], ids=["rogue key", "no key"])
@pytest.mark.parametrize("verb", [["name", "list"], ["read", "/rogue/r"],
                                  ["write", "/rogue/w", "/k/r"], ["rpc", "/k/r"],
                                  ["connect", "/k/w", "/k/r"]],
                         ids=lambda verb: verb[0])
def test_other_keys_are_refused_with_a_message_within_seconds(keyed, lite, verb, rogue_key):
    env = keyed.variant_env("rogue", rogue_key)
    result = keyed.run_tool(lite, *verb, env=env, input_text="")
    assert result.returncode == 1, result.stdout + result.stderr
    assert REFUSED in result.stderr
    if rogue_key is None:
        assert "requires authentication" in result.stderr
        assert "no auth.conf found (looked at" in result.stderr
        assert f"{env['YARP_CONFIG_HOME']}/auth.conf" in result.stderr
    else:
        assert f"key from {env['YARP_CONFIG_HOME']}/auth.conf" in result.stderr
    # Refused on what the server said, at once -- not after a timer ran out ("no answer
    # within"): a wall-clock bound here failed beside a loaded machine's slow tool start.
    assert "no answer within" not in result.stderr, result.stderr
    keyed.server.wait_for(f"{REFUSED} .*key from {keyed.config}/auth.conf")
    assert keyed.run_tool(lite, "name", "list").returncode == 0


def test_a_keyed_tool_is_refused_by_a_server_without_authentication(make_world, lite):
    plain = make_world(lite)
    env = plain.variant_env("keyed", KEY)
    result = plain.run_tool(lite, "name", "list", env=env)
    assert result.returncode == 1
    # the 2-s wait for a challenge, not the tool's timeout (run_tool's 60 s would raise)
    assert f"{REFUSED} (connector, waiting for the challenge): no answer within 2 s" \
        in result.stderr


def test_a_port_refuses_a_direct_connection_with_another_key(keyed, lite):
    reader = keyed.tool(lite, "read", "/k/direct")
    reader.wait_for("Port /k/direct active")
    contact = NameClient().query("/k/direct")
    rogue = keyed.run_tool(lite, "rpc", f"tcp://127.0.0.1:{contact.port}",
                           env=keyed.variant_env("rogue", "other"), input_text="hi\n")
    assert rogue.returncode == 1 and REFUSED in rogue.stderr
    reader.wait_for(f"/k/direct: dropping connection .*{REFUSED}")
    writer = keyed.tool(lite, "write", "/k/ok", "/k/direct", stdin=True)
    reader.wait_for("Receiving input from /k/ok to /k/direct")
    writer.send("still served\n")
    reader.wait_for("^still served$")


def read_until_closed(sock: socket.socket, timeout: float) -> bytes:
    sock.settimeout(timeout)
    data = b""
    while chunk := sock.recv(4096):
        data += chunk
    return data


def test_silent_and_garbage_peers_are_dropped_without_blocking_others(keyed, lite):
    address = ("127.0.0.1", keyed.socket_number)
    silent = socket.create_connection(address)
    stalled = socket.create_connection(address)
    garbage = socket.create_connection(address)
    try:
        stalled.sendall(b"NAME_SER")          # a peer without a key, part of an answer
        garbage.sendall(os.urandom(40))
        started = time.monotonic()
        listing = keyed.run_tool(lite, "name", "list")
        assert listing.returncode == 0 and "registration name /root" in listing.stdout
        assert time.monotonic() - started < 5, "the silent peers held the server"
        assert len(read_until_closed(garbage, 5)) == auth.MESSAGE_LENGTH
        for peer in (silent, stalled):  # the challenge, then a hang-up after 2 s
            assert len(read_until_closed(peer, 6)) == auth.MESSAGE_LENGTH
    finally:
        for peer in (silent, stalled, garbage):
            peer.close()
    keyed.server.wait_for(REFUSED, count=3)
    assert keyed.run_tool(lite, "name", "list").returncode == 0


def test_in_process_api_raises_authentication_error_and_ports_survive(keyed):
    with Port("/k/api", reader=lambda bottle: [len(bottle)]) as port:
        rogue = NameClient(environ=keyed.variant_env("rogue", "other"))
        with pytest.raises(AuthenticationError, match="key from .*variant-rogue/auth.conf"):
            rogue.query("/k/api")
        with pytest.raises(AuthenticationError, match=REFUSED):
            OutgoingConnection.open(port.address, "/rogue", "tcp",
                                    credentials=AuthConfig.with_key("other"))
        connection = OutgoingConnection.open(NameClient().query("/k/api"), "/k/client", "tcp")
        try:
            assert connection.send("d", BottlePayload(["a", "b"]), want_reply=True) == [2]
        finally:
            connection.close()


def test_a_registered_port_that_listens_late_is_connected(lite_world, monkeypatch):
    """A port registers before it listens (real YARP does): a refusal is retried."""
    number = free_port()
    NameClient().register("/late", "tcp", "127.0.0.1", number)
    late = Port(register=False)
    real = socket.create_connection
    refusals = []

    def open_late_after_first_refusal(address, *args, **kwargs):
        try:
            return real(address, *args, **kwargs)
        except ConnectionRefusedError:
            if address[1] == number and not refusals:
                refusals.append(address)
                late.open("/late", host="127.0.0.1", socket_number=number)
            raise

    monkeypatch.setattr(stream.socket, "create_connection", open_late_after_first_refusal)
    try:
        with Port("/early") as early:
            assert early.add_output("/late")
            assert refusals and late.wait_for_inputs(1, timeout=5)
    finally:
        late.close()


def test_a_registered_port_that_never_listens_fails_within_two_seconds(lite_world):
    number = free_port()
    NameClient().register("/never", "tcp", "127.0.0.1", number)
    with Port("/early2") as early:
        started = time.monotonic()
        assert not early.add_output("/never")
        elapsed = time.monotonic() - started
    assert 1.4 < elapsed < 4, f"gave up after {elapsed:.2f} s"
