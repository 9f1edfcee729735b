"""Port authentication between yarp_lite and real YARP 3.5, byte for byte, both ways.

* the ``auth.conf`` real YARP finds, and the key it reads, against
  ``yarp_lite.auth.load`` (``cpp/auth_oracle.cpp``), file contents and
  search locations alike;
* the handshake bytes of a real ``yarpserver`` (acceptor) and a real ``yarp``
  tool (connector) checked by yarp_lite's sans-IO :class:`Handshake`;
* live networks with ``auth.conf``: each name server with each pairing of
  tools, and other keys refused both ways with a message on each side.
"""

from __future__ import annotations

import itertools
import os
import socket
import subprocess
import threading
from pathlib import Path
from typing import Dict, Optional, Tuple

import pytest

from harness import compile_cpp, missing_reference, pair_id, pick, write_auth_conf
from yarp_lite import auth
from yarp_lite.auth import AuthConfig, Handshake, Role
from yarp_lite.errors import AuthenticationError
from yarp_lite.nameconfig import read_server_address

IMPLS = ["yarp", "yarp_lite"]
PAIRS = list(itertools.product(IMPLS, IMPLS))
KEY = "walkman-drc-2015"
#: What each implementation says when it refuses a peer.
REFUSAL = {"yarp": "Authentication failed.", "yarp_lite": "authentication failed"}
ORACLE = Path(__file__).parent / "cpp" / "auth_oracle.cpp"




# -- where the key comes from ---------------------------------------------------------------


@pytest.fixture(scope="module")
def oracle() -> Path:
    from harness import reference_yarp_prefix

    if reference_yarp_prefix() is None:
        missing_reference()
    return compile_cpp(ORACLE, "auth_oracle")


Lookup = Tuple[Optional[str], Optional[bytes]]


def real_lookup(oracle: Path, env: Dict[str, str], cwd: Path) -> Lookup:
    lines = subprocess.run([str(oracle)], env=env, cwd=cwd, capture_output=True, text=True,
                           check=True, timeout=20).stdout.splitlines()
    path = lines[0][len("path "):] or None
    key = next((bytes.fromhex(line[4:]) for line in lines if line.startswith("key ")), None)
    return path, key or None


def lite_lookup(env: Dict[str, str], cwd: Path) -> Lookup:
    config = auth.load(env, str(cwd))
    return (str(config.path) if config.path else None), config.key


@pytest.fixture
def place(tmp_path):
    """A clean environment and current directory for one lookup."""
    (tmp_path / "cwd").mkdir()
    env = {"PATH": os.environ["PATH"], "HOME": str(tmp_path / "home"),
           "YARP_DATA_DIRS": str(tmp_path / "none"), "YARP_CONFIG_DIRS": str(tmp_path / "none")}
    return tmp_path, env


CONTENTS = [
    "[AUTH]\nkey secret\n", "[AUTH]\nkey 1234\n", '[AUTH]\nkey "two words"\n',
    "[AUTH]\nkey = eq\n", "[AUTH]\nkey abc // c\n", "[AUTH]\nkey abc#x\n", "[AUTH]\nkey a #c\n",
    "[AUTH]\nkey first\nkey second\n", "[AUTH]\nx 1\n[AUTH]\nkey again\n", "[AUTH]\n",
    "key top\n", "[AUTH]\nkey ${TEST_VAR}x\n", "[AUTH]\nkey pa$$word\n", "[AUTH]\nkey 1.5\n",
    "[AUTH]\nkey [vo]\n", "[AUTH]\nkey true\n", "[AUTH]\nkey (a b)\n", '[AUTH]\nkey "m\nl"\n',
    "[auth]\nkey lower\n", "[AUTH]\r\nkey crlf\r\n", "s v1\n[AUTH]\nkey $s\n",
    '[AUTH]\nkey "q // not a comment"\n', "[AUTH]\nkey \xe9t\xe9\n", "[AUTH]\nkey\n",
    '[AUTH]\nkey "esc\\"aped"\n', "[AUTH]\nkey 0x1F\n", "[search AUTH]\nkey via\n",
]


@pytest.mark.parametrize("text", CONTENTS)
def test_key_read_as_real_yarp_reads_it(oracle, place, text):
    root, env = place
    env.update({"YARP_CONFIG_HOME": str(root / "config"), "TEST_VAR": "V"})
    (root / "config").mkdir()
    (root / "config" / "auth.conf").write_text(text)
    assert lite_lookup(env, root / "cwd") == real_lookup(oracle, env, root / "cwd")


def _put(path: Path, key: str = "k") -> None:
    write_auth_conf(path, key)


LOCATIONS = {
    "cwd before config home": lambda r, e: (e.update(YARP_CONFIG_HOME=f"{r}/c"),
                                            _put(r / "c"), _put(r / "cwd")),
    "config home before data home": lambda r, e: (
        e.update(YARP_CONFIG_HOME=f"{r}/c", YARP_DATA_HOME=f"{r}/d"), _put(r / "c"),
        _put(r / "d")),
    "XDG config home + yarp": lambda r, e: (e.update(XDG_CONFIG_HOME=f"{r}/x"),
                                            _put(r / "x" / "yarp")),
    "HOME default": lambda r, e: _put(r / "home" / ".config" / "yarp"),
    "set but empty config home": lambda r, e: (e.update(YARP_CONFIG_HOME=""),
                                               _put(r / "home" / ".config" / "yarp")),
    "config dirs list": lambda r, e: (e.update(YARP_CONFIG_DIRS=f"{r}/a:{r}/b"), _put(r / "b")),
    "XDG data dirs + yarp": lambda r, e: (e.pop("YARP_DATA_DIRS"),
                                          e.update(XDG_DATA_DIRS=f"{r}/a:{r}/b"),
                                          _put(r / "b" / "yarp")),
    "robot dir before config home": lambda r, e: (
        e.update(YARP_CONFIG_HOME=f"{r}/c", YARP_DATA_HOME=f"{r}/d"), _put(r / "c"),
        _put(r / "d" / "robots" / "default")),
    "named robot": lambda r, e: (e.update(YARP_CONFIG_HOME=f"{r}/c", YARP_ROBOT_NAME="wm"),
                                 _put(r / "c" / "robots" / "wm"),
                                 _put(r / "c" / "robots" / "default")),
    "auth.conf as a directory": lambda r, e: (
        e.update(YARP_CONFIG_HOME=f"{r}/c"), (r / "c" / "auth.conf").mkdir(parents=True),
        (r / "c" / "auth.conf" / "a.ini").write_text("[AUTH]\nkey fromdir\n")),
    "path.d bundle": lambda r, e: (
        e.update(YARP_DATA_DIRS=f"{r}/dd"), (r / "dd" / "config" / "path.d").mkdir(parents=True),
        (r / "dd" / "config" / "path.d" / "x.ini").write_text(
            f"[search bundle]\n[bundle]\npath {r}/p1 {r}/p2\n"), _put(r / "p2")),
    "nowhere": lambda r, e: None,
}


@pytest.mark.parametrize("setup", LOCATIONS.values(), ids=LOCATIONS.keys())
def test_auth_conf_found_where_real_yarp_finds_it(oracle, place, setup):
    root, env = place
    setup(root, env)
    assert lite_lookup(env, root / "cwd") == real_lookup(oracle, env, root / "cwd")


# -- the bytes on the wire ------------------------------------------------------------------


@pytest.fixture
def real_keyed_world(make_world, implementations, monkeypatch):
    world = make_world(pick(implementations, "yarp"), auth_key=KEY)
    world.apply_to_process(monkeypatch)
    return world


def test_real_yarpserver_challenge_verifies_and_completes_with_our_handshake(real_keyed_world):
    address = read_server_address(environ=real_keyed_world.env)
    machine = Handshake(Role.CONNECTOR, AuthConfig.with_key(KEY))
    with socket.create_connection((address.host, address.port), timeout=5) as sock:
        first = b""
        while len(first) < auth.MESSAGE_LENGTH:
            first += sock.recv(auth.MESSAGE_LENGTH - len(first))
        assert first[8:] == auth.sign(KEY.encode(), first[:8]), "nonce + HMAC(key, nonce)"
        machine.receive_data(first)
        sock.sendall(machine.data_to_send())
        while not machine.done:
            machine.receive_data(sock.recv(auth.MESSAGE_LENGTH))
        sock.sendall(b"NAME_SERVER query /root\n")
        answer = b""
        while b"\n" not in answer:
            answer += sock.recv(4096)
    assert answer.startswith(b"registration name /root ip ")


def serve_one_handshake(key: str) -> Tuple[socket.socket, Dict[str, object], threading.Thread]:
    """A listener that runs our acceptor against the first caller; the outcome in a dict."""
    listener = socket.create_server(("127.0.0.1", 0))
    outcome: Dict[str, object] = {}

    def serve() -> None:
        sock, _ = listener.accept()
        with sock:
            sock.settimeout(5)
            machine = Handshake(Role.ACCEPTOR, AuthConfig.with_key(key))
            try:
                sock.sendall(machine.data_to_send())
                while not machine.done:
                    data = sock.recv(auth.MESSAGE_LENGTH)
                    if not data:
                        outcome["closed"] = True
                        return
                    machine.receive_data(data)
                sock.sendall(machine.data_to_send())
                outcome["done"] = True
            except AuthenticationError as exc:
                outcome["error"] = exc
    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return listener, outcome, thread


@pytest.mark.parametrize("our_key, verified", [(KEY, True), ("another", False)],
                         ids=["same key", "other key"])
def test_real_yarp_answer_verifies_with_our_acceptor(make_world, implementations, our_key,
                                                     verified):
    world = make_world(pick(implementations, "yarp"), auth_key=KEY, start=False)
    listener, outcome, thread = serve_one_handshake(our_key)
    with listener:
        port = listener.getsockname()[1]
        (world.config / "yarp.conf").write_text(f"127.0.0.1 {port} yarp\n")
        result = world.run_tool(pick(implementations, "yarp"), "name", "query", "/x",
                                timeout=30)
        thread.join(10)
    if verified:
        assert outcome.get("done"), outcome
    else:
        # the real tool checks our challenge first, refuses it, and never answers
        assert "done" not in outcome and "Authentication failed." in result.stderr


# -- live networks ----------------------------------------------------------------------------


@pytest.fixture(params=IMPLS, ids=lambda name: f"server={name}")
def world(request, make_world, implementations):
    return make_world(pick(implementations, request.param), auth_key=KEY)


@pytest.mark.parametrize("writer, reader", PAIRS, ids=[pair_id(p) for p in PAIRS])
def test_keyed_read_write_across_implementations(world, implementations, writer, reader):
    read_proc = world.tool(pick(implementations, reader), "read", "/a/r")
    read_proc.wait_for("Port /a/r active")
    write_proc = world.tool(pick(implementations, writer), "write", "/a/w", "/a/r", stdin=True)
    read_proc.wait_for("Receiving input from /a/w to /a/r using tcp")
    write_proc.send("hello 1 (2 3)\n")
    read_proc.wait_for(r"^hello 1 \(2 3\)$")
    write_proc.close_stdin()
    assert write_proc.wait() == 0
    for tool in IMPLS:
        listing = world.run_tool(pick(implementations, tool), "name", "list")
        assert "registration name /a/r" in listing.stdout, listing.stdout + listing.stderr
    assert REFUSAL[world.server_impl.name] not in world.server.output()


@pytest.mark.parametrize("rogue", IMPLS)
def test_another_key_is_refused_on_both_sides(world, implementations, rogue):
    env = world.variant_env("rogue", "not-the-key")
    result = world.run_tool(pick(implementations, rogue), "read", "/rogue", env=env, timeout=30)
    assert REFUSAL[rogue] in result.stderr, result.stdout + result.stderr
    if rogue == "yarp_lite":  # real `yarp read` exits 0 even when its port cannot open
        assert result.returncode == 1
    world.server.wait_for(REFUSAL[world.server_impl.name])
    assert world.run_tool(pick(implementations, rogue), "name", "list").returncode == 0


def test_lite_without_a_key_says_the_real_server_requires_one(make_world, implementations, lite):
    world = make_world(pick(implementations, "yarp"), auth_key=KEY)
    result = world.run_tool(lite, "name", "list", env=world.variant_env("none", None))
    assert result.returncode == 1
    assert "requires authentication" in result.stderr and "no auth.conf found" in result.stderr
    world.server.wait_for(REFUSAL["yarp"])


def test_lite_with_a_key_says_the_open_real_server_sent_no_challenge(make_world, implementations,
                                                                     lite):
    world = make_world(pick(implementations, "yarp"))
    result = world.run_tool(lite, "name", "list", env=world.variant_env("keyed", KEY))
    assert result.returncode == 1
    assert "waiting for the challenge): no answer within 2 s" in result.stderr


def test_a_real_port_refuses_a_lite_direct_connection_with_another_key(world, implementations,
                                                                      lite):
    port_proc = world.tool(pick(implementations, "yarp"), "read", "/a/direct")
    port_proc.wait_for("Port /a/direct active")
    words = world.run_tool(lite, "name", "query", "/a/direct").stdout.split()
    host, number = words[4], words[6]  # real YARP announces a non-loopback address
    rogue = world.run_tool(lite, "rpc", f"tcp://{host}:{number}",
                           env=world.variant_env("rogue", "other"), input_text="x\n")
    assert rogue.returncode == 1 and REFUSAL["yarp_lite"] in rogue.stderr
    port_proc.wait_for(REFUSAL["yarp"])
    writer = world.tool(lite, "write", "/a/ok", "/a/direct", stdin=True)
    port_proc.wait_for("Receiving input from /a/ok to /a/direct")
    writer.send("still served\n")
    port_proc.wait_for("^still served$")


CROSS = [("yarp", "yarp_lite"), ("yarp_lite", "yarp")]


@pytest.mark.parametrize("writer, reader", CROSS, ids=[pair_id(p) for p in CROSS])
@pytest.mark.parametrize("carrier", ["tcp", "fast_tcp", "udp", "text", "text_ack"])
def test_every_carrier_authenticates_first(make_world, implementations, lite, writer, reader,
                                           carrier):
    world = make_world(lite, auth_key=KEY)
    read_proc = world.tool(pick(implementations, reader), "read", "/c/r")
    read_proc.wait_for("Port /c/r active")
    write_proc = world.tool(pick(implementations, writer), "write", "/c/w", stdin=True)
    write_proc.wait_for("Port /c/w active")
    connect = world.run_tool(pick(implementations, reader), "connect", "/c/w", "/c/r", carrier)
    assert connect.returncode == 0, connect.stdout + connect.stderr
    read_proc.wait_for(f"Receiving input from /c/w to /c/r using {carrier}")
    write_proc.send("over the carrier\n")
    read_proc.wait_for("^over the carrier$")
