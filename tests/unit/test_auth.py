"""yarp_lite.auth without a network: the handshake, the HMAC bytes, auth.conf discovery.

Known answers were computed with ``openssl dgst -sha256 -hmac`` (not Python's
hmac), so they check :func:`yarp_lite.auth.sign` independently; the
interop tests check the same bytes against real YARP.
"""

from __future__ import annotations

import itertools
import logging
from pathlib import Path
import pytest
from hypothesis import given
from hypothesis import strategies as st

from yarp_lite import auth
from yarp_lite.auth import AuthConfig, Handshake, Role, State
from yarp_lite.errors import AuthenticationError, LocalProtocolError, RemoteProtocolError

KEY = AuthConfig.with_key("secret123", Path("/etc/test/auth.conf"))
OTHER = AuthConfig.with_key("wrong")
N1, N2, N3 = b"\x01" * 8, b"\x02" * 8, b"\x03" * 8
# HMAC-SHA256("secret123", ...) of nonce1, nonce1+nonce2, nonce1+nonce2+nonce3 (openssl)
MAC1 = bytes.fromhex("0efc4d0dcace4ee0f144ccafc1b1cace751faae10afbb368d52f695705d9a5b9")
MAC12 = bytes.fromhex("386fd80d9ea845ae7256f88747a4441c7808d310ac5e7018a7f4e2d02fb5c3a1")
MAC123 = bytes.fromhex("dc2a21c036404aaef2660b1e9a1ef0f55b65234a5d017513f5f599a38c109224")


def nonces(*values: bytes):
    """A nonce source that hands out ``values`` in order."""
    iterator = iter(values)
    return lambda: next(iterator)


def pair(acceptor_config: AuthConfig = KEY, connector_config: AuthConfig = KEY):
    return Handshake(Role.ACCEPTOR, acceptor_config), Handshake(Role.CONNECTOR, connector_config)


def run(acceptor: Handshake, connector: Handshake, chunk: int = 0) -> None:
    """Shuttle bytes between the two machines (``chunk`` bytes at a time, 0 = all)."""
    while not (acceptor.done and connector.done):
        moved = False
        for sender, receiver in ((acceptor, connector), (connector, acceptor)):
            data = sender.data_to_send()
            pieces = [data[i:i + chunk] for i in range(0, len(data), chunk)] if chunk else [data]
            for piece in pieces:
                if piece:
                    receiver.receive_data(piece)
                    moved = True
        assert moved, "handshake stalled"


# -- the exchange --------------------------------------------------------------------------


def test_rfc4231_vector():
    # RFC 4231 test case 2: the primitive is plain HMAC-SHA256
    expected = "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"
    assert auth.sign(b"Jefe", b"what do ya want for ", b"nothing?").hex() == expected


def test_known_answer_bytes_of_every_message():
    acceptor = Handshake(Role.ACCEPTOR, KEY, nonce=nonces(N1, N3))
    connector = Handshake(Role.CONNECTOR, KEY, nonce=nonces(N2))
    first = acceptor.data_to_send()
    assert first == N1 + MAC1
    connector.receive_data(first)
    second = connector.data_to_send()
    assert second == N2 + MAC12
    acceptor.receive_data(second)
    third = acceptor.data_to_send()
    assert third == N3 + MAC123
    connector.receive_data(third)
    assert acceptor.done and connector.done
    assert connector.data_to_send() == b"" and acceptor.data_to_send() == b""


@pytest.mark.parametrize("chunk", [0, 1, 7, 40, 41])
def test_both_roles_complete_whatever_the_chunking(chunk):
    acceptor, connector = pair()
    run(acceptor, connector, chunk)
    assert acceptor.state is State.DONE and connector.state is State.DONE
    assert acceptor.trailing == b"" and connector.trailing == b""


def test_a_long_key_is_hashed_first_as_hmac_says():
    long_key = AuthConfig.with_key("k" * 100)
    run(*pair(long_key, long_key))  # both sides agree; the mac is plain HMAC over it
    assert auth.sign(long_key.key, N1) == auth.sign(auth.hashlib.sha256(long_key.key).digest(), N1)


def test_acceptor_speaks_first_and_connector_waits():
    acceptor, connector = pair()
    assert len(acceptor.data_to_send()) == auth.MESSAGE_LENGTH
    assert connector.data_to_send() == b""
    assert connector.bytes_needed == auth.MESSAGE_LENGTH


def test_truncated_message_waits_for_the_rest_byte_by_byte():
    acceptor, connector = pair()
    first = acceptor.data_to_send()
    for index, byte in enumerate(first[:-1]):
        connector.receive_data(bytes([byte]))
        assert connector.state is State.AWAIT_CHALLENGE
        assert connector.bytes_needed == auth.MESSAGE_LENGTH - index - 1
        assert connector.data_to_send() == b""
    connector.receive_data(first[-1:])
    assert connector.state is State.AWAIT_CONFIRMATION


def test_bytes_after_the_handshake_belong_to_the_carrier():
    acceptor, connector = pair()
    connector.receive_data(acceptor.data_to_send())
    header = b"YA\xe4\x1e\x00\x00RP"
    acceptor.receive_data(connector.data_to_send() + header)
    assert acceptor.done and acceptor.trailing == header
    acceptor.receive_data(b"more")
    assert acceptor.trailing == header + b"more"


# -- refusals -----------------------------------------------------------------------------


def test_connector_with_another_key_refuses_the_challenge():
    acceptor, connector = pair(KEY, OTHER)
    with pytest.raises(AuthenticationError) as caught:
        connector.receive_data(acceptor.data_to_send())
    message = str(caught.value)
    assert "authentication failed" in message and "challenge" in message
    assert connector.state is State.FAILED and connector.data_to_send() == b""


def test_acceptor_refuses_an_answer_signed_with_another_key():
    acceptor = Handshake(Role.ACCEPTOR, KEY, where="/root input #3", nonce=nonces(N1))
    forged = N2 + auth.sign(OTHER.key, N1, N2)  # a peer that skipped checking our challenge
    acceptor.data_to_send()
    with pytest.raises(AuthenticationError) as caught:
        acceptor.receive_data(forged)
    message = str(caught.value)
    assert message.startswith("/root input #3: authentication failed (acceptor")
    assert "key from /etc/test/auth.conf" in message
    assert acceptor.data_to_send() == b"", "no confirmation for a refused peer"


def test_connector_refuses_a_forged_confirmation():
    acceptor, connector = pair()
    connector.receive_data(acceptor.data_to_send())
    connector.data_to_send()
    with pytest.raises(AuthenticationError, match="confirmation"):
        connector.receive_data(b"\x00" * auth.MESSAGE_LENGTH)


@pytest.mark.parametrize("role", list(Role))
def test_garbage_is_refused_and_the_machine_stays_failed(role):
    machine = Handshake(role, KEY)
    machine.data_to_send()
    with pytest.raises(AuthenticationError):
        machine.receive_data(b"NAME_SERVER list\n" + b"x" * 40)  # a peer without a key
    with pytest.raises(LocalProtocolError, match="already failed"):
        machine.receive_data(b"x")


def test_a_handshake_without_a_key_is_a_local_error():
    with pytest.raises(LocalProtocolError, match="no key"):
        Handshake(Role.CONNECTOR, auth.DISABLED)


def test_authentication_error_is_a_remote_protocol_error():
    # ports drop such connections and keep serving, as for any peer misbehaviour
    assert issubclass(AuthenticationError, RemoteProtocolError)


@given(role=st.sampled_from(list(Role)), key=st.sampled_from([KEY, OTHER]),
       chunks=st.lists(st.binary(max_size=90), max_size=6))
def test_fuzz_any_input_completes_waits_or_raises_authentication_error(role, key, chunks):
    machine = Handshake(role, key)
    machine.data_to_send()
    for chunk in chunks:
        try:
            machine.receive_data(chunk)
        except AuthenticationError:
            assert machine.state is State.FAILED
            return
        assert machine.state is not State.FAILED
        assert machine.done or 0 < machine.bytes_needed <= auth.MESSAGE_LENGTH


@given(chunking=st.lists(st.integers(min_value=1, max_value=45), min_size=1, max_size=8))
def test_fuzz_any_chunking_of_honest_peers_completes(chunking):
    acceptor, connector = pair()
    sizes = itertools.cycle(chunking)
    while not (acceptor.done and connector.done):
        for sender, receiver in ((acceptor, connector), (connector, acceptor)):
            data = sender.data_to_send()
            while data:
                size = next(sizes)
                receiver.receive_data(data[:size])
                data = data[size:]
    assert acceptor.trailing == connector.trailing == b""


# -- auth.conf ----------------------------------------------------------------------------


@pytest.mark.parametrize("text, key", [
    ("[AUTH]\nkey secret\n", "secret"),
    ('[AUTH]\nkey "two words"\n', "two words"),
    ("[AUTH]\nkey = with_equals\n", "with_equals"),
    ("[AUTH]\nkey abc // a comment\n", "abc"),
    ("[AUTH]\nkey abc#hash\n", "abc#hash"),      # '#' only starts a comment after a space
    ("[AUTH]\nkey abc #comment\n", "abc"),
    ("[AUTH]\nkey first\nkey second\n", "first"),
    ("[AUTH]\nx 1\n[OTHER]\nkey no\n[AUTH]\nkey merged\n", "merged"),
    ("[AUTH]\nkey true\n", "true"),
    ("[AUTH]\nkey [vo]\n", "vo"),
    ('[AUTH]\nkey "multi\nline"\n', "multiline"),
    ("[AUTH]\r\nkey crlf\r\n", "crlf"),
    ("user s1\n[AUTH]\nkey ${user}x\n", "s1x"),
    ("[AUTH]\nkey $TEST_AUTH_VAR\n", "from-env"),
    ("[AUTH]\nkey pa$$word\n", "pa"),                # unknown variables expand to nothing
])
def test_key_read_as_yarp_reads_it(text, key):
    assert auth.parse_auth_conf(text, {"TEST_AUTH_VAR": "from-env"}) == (key, "")


@pytest.mark.parametrize("text, why", [
    ("[AUTH]\nkey 1234\n", 'no "key"'),          # asString() of a number is empty
    ("[AUTH]\nkey 1.5\n", 'no "key"'),
    ("[AUTH]\nkey (a b)\n", 'no "key"'),
    ("[AUTH]\nkey\n", 'no "key"'),
    ("[AUTH]\nother x\n", 'no "key"'),
    ("key top_level_only\n", 'no "AUTH" group'),
    ("[auth]\nkey lower_case\n", 'no "AUTH" group'),
    ("", 'no "AUTH" group'),
])
def test_no_usable_key_leaves_authentication_off(text, why):
    key, reason = auth.parse_auth_conf(text, {})
    assert key is None and why in reason


def fake_tree(*present: str):
    files = set(present)

    def exists(path: str) -> bool:
        return path in files or any(name.startswith(path + "/") for name in files)
    return exists


def test_search_order_follows_the_resource_finder():
    env = {"HOME": "/h", "YARP_CONFIG_HOME": "/c", "YARP_DATA_HOME": "/d",
           "YARP_CONFIG_DIRS": "/cd1:/cd2", "YARP_DATA_DIRS": "/dd1"}
    exists = fake_tree("/d/robots/default/x", "/dd1/robots/default/x")
    assert auth.candidates(env, "/work", exists) == [
        "/work/auth.conf", "/d/robots/default/auth.conf", "/dd1/robots/default/auth.conf",
        "/c/auth.conf", "/d/auth.conf", "/cd1/auth.conf", "/cd2/auth.conf", "/dd1/auth.conf"]


def test_xdg_fallbacks_get_yarp_appended_and_set_but_empty_counts():
    env = {"HOME": "/h", "XDG_CONFIG_HOME": "/xc", "YARP_DATA_HOME": "",
           "XDG_DATA_DIRS": "/x1:/x2"}
    assert auth.candidates(env, "/w", fake_tree()) == [
        "/w/auth.conf", "/xc/yarp/auth.conf", "/etc/xdg/yarp/auth.conf",
        "/x1/yarp/auth.conf", "/x2/yarp/auth.conf"]


def test_robot_name_and_path_d_bundles():
    env = {"HOME": "/h", "YARP_ROBOT_NAME": "walkman", "YARP_DATA_DIRS": "/dd"}
    tree = fake_tree("/dd/config/path.d/a.ini", "/bundle/robots/walkman/x")
    read = {"/dd/config/path.d": "[search wm]\n[wm]\npath /bundle\n"}.__getitem__
    found = auth.candidates(env, "/w", tree, read)
    assert found[:2] == ["/w/auth.conf", "/bundle/robots/walkman/auth.conf"]
    assert found[-1] == "/bundle/auth.conf"


def test_load_finds_the_key_and_names_the_file(tmp_path, caplog):
    (tmp_path / "config").mkdir()
    (tmp_path / "config" / "auth.conf").write_text("[AUTH]\nkey s3cr3t\n")
    env = {"HOME": str(tmp_path), "YARP_CONFIG_HOME": str(tmp_path / "config"),
           "YARP_CONFIG_DIRS": "", "YARP_DATA_DIRS": ""}
    with caplog.at_level(logging.INFO, logger="yarp_lite.auth"):
        config = auth.load(env, str(tmp_path))
    assert config.key == b"s3cr3t" and config.path == tmp_path / "config" / "auth.conf"
    assert config.note == f"key from {config.path}"
    assert f"Authentication enabled (key from {config.path})" in caplog.text
    # the current directory comes first, as for real YARP
    (tmp_path / "auth.conf").write_text("[AUTH]\nkey local\n")
    assert auth.load(env, str(tmp_path)).key == b"local"


def test_load_with_a_numeric_key_warns_and_stays_off(tmp_path, caplog):
    (tmp_path / "auth.conf").write_text("[AUTH]\nkey 1234\n")
    env = {"HOME": str(tmp_path), "YARP_CONFIG_DIRS": "", "YARP_DATA_DIRS": ""}
    with caplog.at_level(logging.WARNING, logger="yarp_lite.auth"):
        config = auth.load(env, str(tmp_path))
    assert not config.enabled and str(tmp_path / "auth.conf") in config.note
    assert any("authentication disabled" in record.message for record in caplog.records)


def test_load_without_a_file_says_where_it_looked(tmp_path):
    env = {"HOME": str(tmp_path), "YARP_CONFIG_DIRS": "", "YARP_DATA_DIRS": ""}
    config = auth.load(env, str(tmp_path))
    assert not config.enabled
    assert config.note.startswith("no auth.conf found") and str(tmp_path) in config.note


# -- a peer that authenticates when we do not ------------------------------------------------


def test_text_check():
    assert auth.is_text(b"registration name /x ip 1.2.3.4\r\n\t*** end \xc3\xa9")
    assert not auth.is_text(b"\x01" * 8)
    assert auth.is_text("an answer cut in a character: \u00e9".encode()[:-1])
    # a real server's challenge that a CI run took for text: printable, not UTF-8
    assert not auth.is_text(b"EU\xb9\xfa\x9b\t#\xea&J\x95 \x05\xd5\xae\t\n")
    assert not auth.is_text(bytes(range(0xa0, 0xc8)))


def test_unexpected_answer_blames_the_missing_key_only_when_we_have_none():
    without = auth.unexpected_answer(auth.AuthConfig(None, None, "no auth.conf found (...)"),
                                     "name server", "40 bytes that are not text")
    assert isinstance(without, AuthenticationError)
    assert "requires authentication" in str(without) and "no auth.conf found" in str(without)
    with_key = auth.unexpected_answer(KEY, "name server", "40 bytes that are not text")
    assert type(with_key) is RemoteProtocolError

