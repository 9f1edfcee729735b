"""Typing at a port (text carrier), the yarp-lite tool's own verbs, and namespaces."""

from __future__ import annotations

import socket

import pytest

from harness import YarpWorld, wait_until
from yarp_lite import network
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port


def _talk(port: Port, lines):
    with socket.create_connection(("127.0.0.1", port.address.port), timeout=5) as sock:
        sock.sendall("".join(line + "\n" for line in lines).encode())
        sock.settimeout(1.0)
        data = b""
        try:
            while chunk := sock.recv(4096):
                data += chunk
        except socket.timeout:
            pass
    return data.decode().split("\r\n")


def test_a_human_can_type_at_a_port(lite_world):
    received = []
    with Port("/typed", reader=received.append) as port, Port("/other", reader=lambda b: None):
        answer = _talk(port, ["CONNECT human", "*", "d", "1 (2 3) hello", "/other", "?",
                              "nonsense", "q"])
        assert answer[0] == "Welcome human"
        assert answer[1].startswith("This is /typed at tcp://")
        assert "Added connection from /typed to /other" in answer
        assert "This is a YARP port.  Here are the commands it responds to:" in answer
        assert "Port command not understood." in answer
        wait_until(lambda: received == [[1, [2, 3], "hello"]])
        assert port.output_count == 1


def test_text_ack_carrier_replies_and_acknowledges(lite_world):
    with Port("/rpc/typed", reader=lambda b: [len(b)]) as port:
        answer = _talk(port, ["CONNACK me", "d", "a b c"])
        assert answer[:3] == ["Welcome me", "3", "<ACK>"]


@pytest.mark.parametrize("options, stdin, replies", [
    (["--echo"], "", ["1 2", "hello"]),
    ([], "ten\n(20 30)\n", ["ten", "(20 30)"]),       # what the user types is the reply
    (["--stop", "--echo"], "", ["1 2"]),                # one request, then it exits
])
def test_rpcserver_answers_and_shows_each_message(lite_world, lite, options, stdin, replies):
    import subprocess

    server = subprocess.Popen([*lite.tool, "rpcserver", *options, "/cli/server"],
                              env=lite_world.env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True)
    try:
        server.stdin.write(stdin)
        server.stdin.flush()
        wait_until(lambda: NameClient().query("/cli/server") is not None)
        result = lite_world.run_tool(lite, "rpc", "/cli/server", input_text="1 2\nhello\n")
        answers = [line.split("Response:", 1)[1].strip() for line in result.stdout.splitlines()
                   if line.startswith("Response:")]
        assert answers == replies, result.stdout + result.stderr
        if "--stop" in options:
            assert server.wait(timeout=10) == 0
        server.kill()
        shown = server.communicate(timeout=10)[0].splitlines()
    finally:
        server.kill()
        server.wait()
    expected = ["Waiting for a message..."]
    for request in ["1 2", "hello"][:len(replies)]:
        expected += [f"Message: {request}", "Reply: "]
        if "--stop" not in options:
            expected.append("Waiting for a message...")
    assert [line for line in shown if not line.startswith("[")] == expected


def test_unknown_carrier_is_a_clear_error(lite_world):
    with Port("/u/in", reader=lambda b: None), Port("/u/out"):
        outcome = network.connect("/u/out", "/u/in", "carrier_pigeon")
        assert not outcome.ok and "Cannot connect to carrier_pigeon://u/in" in outcome.message


def test_two_name_servers_side_by_side_by_namespace(lite, monkeypatch, tmp_path):
    robot = YarpWorld(tmp_path / "shared", lite, namespace="/robot")
    pilot = YarpWorld(tmp_path / "shared", lite, namespace="/pilot")  # same config folder
    try:
        robot.start_server()
        pilot.start_server()
        assert (tmp_path / "shared" / "config" / "_robot.conf").is_file()
        assert (tmp_path / "shared" / "config" / "_pilot.conf").is_file()
        robot.apply_to_process(monkeypatch)
        robot_client, pilot_client = NameClient("/robot"), NameClient("/pilot")
        with Port("/arm", nameclient=robot_client), Port("/gui", nameclient=pilot_client):
            assert robot_client.query("/arm") and not robot_client.query("/gui")
            assert pilot_client.query("/gui") and not pilot_client.query("/arm")
    finally:
        robot.close()
        pilot.close()


def test_cli_conf_namespace_where_clean(lite_world, lite):
    result = lite_world.run_tool(lite, "conf")
    assert result.stdout.strip().endswith("yarp.conf")
    where = lite_world.run_tool(lite, "where")
    assert f"Name server /root is available at ip 127.0.0.1 port {lite_world.socket_number}" \
        in where.stdout
    assert lite_world.run_tool(lite, "name", "register", "/ghost").returncode == 0
    clean = lite_world.run_tool(lite, "clean", "--timeout", "0.5")
    assert "* No response, removing port /ghost" in clean.stdout
    assert "/ghost" not in lite_world.run_tool(lite, "name", "list").stdout
    namespace = lite_world.run_tool(lite, "namespace")
    assert "YARP namespace: /root" in namespace.stdout


@pytest.mark.parametrize("args, problem", [
    (["connect", "/only-one"], "give a sender port and a receiver port"),
    (["server", "--socket", "abc"], "--socket expects a number"),
    (["server", "--frobnicate"], "unknown option '--frobnicate'"),
    (["namespace", "root"], "starting with '/'"),
    (["no-such-verb"], "unknown command 'no-such-verb'"),
])
def test_cli_usage_errors(lite_world, lite, args, problem):
    result = lite_world.run_tool(lite, *args)
    assert result.returncode == 2
    assert problem in result.stderr


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_flags_print_the_usage_as_the_real_yarp_does(lite_world, lite, flag):
    result = lite_world.run_tool(lite, flag)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("Usage:") and "Here are commands you can use" in \
        result.stdout
