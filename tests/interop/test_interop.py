"""yarp_lite and real YARP 3.5 on one network, in both directions.

Every test runs with each name server (``yarpserver`` and ``yarp-lite
server``) and each pairing of companion tools (real ``yarp`` and
``yarp-lite``), so the same suite proves yarp_lite against the reference and
against itself.  Without the reference build, the real-YARP cases skip with
the reason and the yarp_lite-only cases still run.
"""

from __future__ import annotations

import itertools
import re

import pytest

from harness import pair_id, pick, wait_until
from yarp_lite.bottle import (Bottle, Dict, Float32, Int8, Int16, Int64, Vocab, encode)

IMPLS = ["yarp", "yarp_lite"]
PAIRS = list(itertools.product(IMPLS, IMPLS))
CARRIERS = ["tcp", "fast_tcp", "udp", "text", "text_ack"]
LINES = ["1 2 3", 'hello "a b" 3.5 (x y) [vo] {1 2}', "(nested (list 1.5)) [ok] last"]




@pytest.fixture(params=IMPLS, ids=lambda name: f"server={name}")
def world(request, make_world, implementations):
    return make_world(pick(implementations, request.param))


@pytest.mark.parametrize("writer, reader", PAIRS, ids=[pair_id(p) for p in PAIRS])
@pytest.mark.parametrize("carrier", CARRIERS)
def test_read_write_every_carrier(world, implementations, writer, reader, carrier):
    write_impl, read_impl = pick(implementations, writer), pick(implementations, reader)
    read_proc = world.tool(read_impl, "read", "/r")
    read_proc.wait_for("Port /r active")
    write_proc = world.tool(write_impl, "write", "/w", stdin=True)
    write_proc.wait_for("Port /w active")
    connect = world.run_tool(read_impl, "connect", "/w", "/r", carrier)
    assert connect.returncode == 0, connect.stdout + connect.stderr
    read_proc.wait_for(f"Receiving input from /w to /r using {carrier}")
    for line in LINES:
        write_proc.send(line + "\n")
        read_proc.wait_for(line.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                           .replace("]", r"\]").replace("{", r"\{").replace("}", r"\}"))
    write_proc.close_stdin()
    assert write_proc.wait() == 0


@pytest.mark.parametrize("tool", IMPLS)
def test_name_list_and_query_see_the_other_implementation(world, implementations, tool):
    other = "yarp" if tool == "yarp_lite" else "yarp_lite"
    port_proc = world.tool(pick(implementations, other), "read", "/seen")
    port_proc.wait_for("Port /seen active")
    listing = world.run_tool(pick(implementations, tool), "name", "list")
    assert "registration name /seen ip" in listing.stdout
    assert listing.stdout.rstrip().endswith("*** end of message")
    query = world.run_tool(pick(implementations, tool), "name", "query", "/seen")
    assert re.search(r"registration name /seen ip [0-9.]+ port \d+ type tcp",
                     query.stdout + query.stderr)
    assert world.run_tool(pick(implementations, tool), "exists", "/seen").returncode == 0
    assert world.run_tool(pick(implementations, tool), "exists", "/nobody").returncode == 1
    ping = world.run_tool(pick(implementations, tool), "ping", "/seen")
    assert "/seen" in ping.stdout and "There are no outgoing connections" in ping.stdout


@pytest.mark.parametrize("client, server", PAIRS, ids=[pair_id(p) for p in PAIRS])
def test_rpc(world, implementations, client, server):
    server_proc = world.tool(pick(implementations, server), "rpcserver", "--echo", "/echo")
    server_proc.wait_for("Port /echo active|Waiting for a message")
    result = world.run_tool(pick(implementations, client), "rpc", "/echo",
                            input_text="hello 1 2\n(a b) 2.5\n")
    assert "Response: hello 1 2" in result.stdout, result.stdout + result.stderr
    assert "Response: (a b) 2.5" in result.stdout


@pytest.mark.parametrize("tool, port", PAIRS, ids=[pair_id(p) for p in PAIRS])
def test_admin_rpc(world, implementations, tool, port):
    port_proc = world.tool(pick(implementations, port), "read", "/adm")
    port_proc.wait_for("Port /adm active")
    result = world.run_tool(pick(implementations, tool), "admin", "rpc", "/adm",
                            input_text="[ver]\n[list] [in]\n")
    assert "Response: [ver] 1 2 3" in result.stdout, result.stdout + result.stderr


@pytest.mark.parametrize("connector, ports", PAIRS, ids=[pair_id(p) for p in PAIRS])
def test_persistent_connection_made_when_ports_appear_and_after_restart(
        world, implementations, connector, ports):
    port_impl = pick(implementations, ports)
    made = world.run_tool(pick(implementations, connector), "connect", "--persist", "/pw", "/pr")
    assert made.returncode == 0, made.stdout + made.stderr
    reader = world.tool(port_impl, "read", "/pr")
    writer = world.tool(port_impl, "write", "/pw", stdin=True)
    reader.wait_for("Receiving input from /pw to /pr", timeout=20)
    wait_until(lambda: world.run_tool(port_impl, "exists", "/pw", "/pr").returncode == 0,
               message="writer connected")
    writer.send("first\n")
    reader.wait_for("^first$")
    reader.kill()

    # A writer notices a dead reader when it next writes (real YARP as well); until then the
    # name server's reconnection finds the old connection and counts it as already present.
    def writer_dropped_the_dead_connection() -> bool:
        writer.send("into the void\n")
        return world.run_tool(port_impl, "exists", "/pw", "/pr").returncode != 0

    wait_until(writer_dropped_the_dead_connection, timeout=20, interval=0.2,
               message="the writer to drop its connection to the dead reader")
    reader2 = world.tool(port_impl, "read", "/pr")
    reader2.wait_for("Receiving input from /pw to /pr", timeout=20)
    # The writer knows of the new connection once its handshake is done.
    wait_until(lambda: world.run_tool(port_impl, "exists", "/pw", "/pr").returncode == 0,
               message="writer connected again")
    writer.send("second\n")
    reader2.wait_for("^second$")
    listing = world.run_tool(pick(implementations, connector), "connect", "--persist")
    assert "Persistent connection /pw -> /pr" in listing.stdout + listing.stderr


@pytest.mark.parametrize("tool", IMPLS)
def test_connect_failures_are_reported(world, implementations, tool):
    result = world.run_tool(pick(implementations, tool), "connect", "/nothing", "/nowhere")
    assert result.returncode != 0
    assert "Failure: could not find source port /nothing" in result.stdout + result.stderr


# -- bit-identical round trips through a real YARP port ------------------------------------

EVERY_TYPE = Bottle([
    Int8(-7), Int16(-300), 123456, Int64(1 << 40), Float32(0.25), 1e-300, -0.0,
    Vocab("ok"), "text with \"quotes\" and \\", b"\x00\x01\xfe\xff", Bottle([]),
    Bottle([1, 2, 3]), Bottle([Int8(1), Int8(2)]), Bottle([Float32(1.5), Float32(-2)]),
    Bottle([Vocab("a"), Vocab("bc")]), Bottle(["s1", "s2"]), Bottle([b"x", b""]),
    Bottle([Bottle([1, "mixed", 2.5]), Bottle([])]),
    Dict.from_mapping({"alpha": 1, "beta": "two"}),
])


@pytest.mark.parametrize("carrier", ["tcp", "fast_tcp"])
@pytest.mark.parametrize("echo_impl", IMPLS)
def test_every_bottle_type_round_trips_bit_identically(world, implementations, monkeypatch,
                                                       echo_impl, carrier):
    from yarp_lite.rpc import RpcClient

    world.apply_to_process(monkeypatch)
    echo = world.tool(pick(implementations, echo_impl), "rpcserver", "--echo", "/bits")
    echo.wait_for("Port /bits active|Waiting for a message")
    client = RpcClient("/bits/client")
    try:
        assert client.connect("/bits", carrier)
        reply = client.call(EVERY_TYPE, timeout=10)
        assert encode(reply) == encode(EVERY_TYPE)
        assert isinstance(reply[0], Int8) and isinstance(reply[18], Dict)
        big = Bottle([b"\xab" * 2_000_000, "after"])
        assert encode(client.call(big, timeout=20)) == encode(big)
    finally:
        client.close()


@pytest.mark.parametrize("reader", IMPLS)
@pytest.mark.parametrize("carrier", ["tcp", "fast_tcp", "udp", "text"])
def test_an_envelope_written_by_yarp_lite_reaches_either_reader(world, implementations,
                                                                monkeypatch, reader, carrier):
    """``Port.write(bottle, envelope)``: what ``Port::setEnvelope`` + ``write`` send in YARP."""
    from yarp_lite.port import Port

    world.apply_to_process(monkeypatch)
    read_impl = pick(implementations, reader)
    read_proc = world.tool(read_impl, "read", "/r", "envelope")
    read_proc.wait_for("Port /r active")
    port = Port()
    port.open("/w")
    try:
        assert port.add_output("/r", carrier)
        read_proc.wait_for(f"Receiving input from /w to /r using {carrier}")
        port.write(Bottle([1.5, 2.5]), "17 1795456583.25")
        # Real YARP prints the envelope on a line of its own, yarp-lite before the data.
        read_proc.wait_for(r"^17 1795456583\.25")
        read_proc.wait_for(r"1\.5 2\.5$")
    finally:
        port.close()
