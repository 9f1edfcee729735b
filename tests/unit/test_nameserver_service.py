"""The name server's command language, registry allocation and persistent connections."""

from __future__ import annotations

import pytest

from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import parse
from yarp_lite.nameserver.registry import MAX_PROPERTY_BYTES, Registry, RegistryFull
from yarp_lite.nameserver.service import NameService, OldReply
from yarp_lite.nameserver.subscriptions import Action, Subscriptions


@pytest.fixture
def service():
    return NameService(Registry(":memory:", 10000), Subscriptions(":memory:"), "10.0.0.1", 10000,
                       silent=True)


def apply(service, text, remote="10.0.0.7"):
    return service.apply(parse(text), remote)


def lines(outcome):
    assert isinstance(outcome.reply, OldReply)
    return outcome.reply.lines


def test_register_allocates_from_server_port_plus_two(service):
    assert lines(apply(service, "register /a")) == [
        "registration name /a ip 10.0.0.7 port 10002 type tcp", "*** end of message"]
    assert lines(apply(service, "register /b udp 1.2.3.4 5555"))[0] == \
        "registration name /b ip 1.2.3.4 port 5555 type udp"
    assert lines(apply(service, "register ..."))[0].startswith("registration name /tmp/port/1 ")


def test_reregistering_keeps_the_number_and_emits_events(service):
    first = apply(service, "register /a")
    assert first.events == [Bottle([Vocab("add"), "/a"])]
    apply(service, "register /b")
    again = apply(service, "register /a")
    assert "port 10002" in lines(again)[0]
    assert Bottle([Vocab("del"), "/a"]) in again.events


def test_query_list_unregister(service):
    apply(service, "register /z")
    apply(service, "register /a")
    assert [line.split()[2] for line in lines(apply(service, "list"))[:-1]] == ["/a", "/z"]
    assert lines(apply(service, "query /nope")) == ["*** end of message"]
    assert lines(apply(service, "unregister /a")) == ["*** end of message"]
    assert lines(apply(service, "NAME_SERVER query /a")) == ["*** end of message"]


def test_properties_sorted_like_yarpserver(service):
    apply(service, "register /p")
    assert lines(apply(service, "set /p accepts tcp udp fast_tcp"))[0] == \
        "port /p property accepts = fast_tcp tcp udp"
    assert lines(apply(service, "check /p accepts udp"))[0] == \
        "port /p property accepts value udp present true"
    assert apply(service, "bot get /p accepts").reply == ["fast_tcp", "tcp", "udp"]


def test_properties_of_one_port_are_bounded(service, caplog):
    apply(service, "register /a")
    apply(service, "set /a small 1")
    chunk = "x" * 1000
    stored = 0
    while lines(apply(service, f"set /a key{stored} {chunk}"))[0].startswith("port /a"):
        stored += 1
        assert stored < 100, "no limit"
    assert stored == (MAX_PROPERTY_BYTES - len("small1")) // (len("key00") + 1000)
    assert "refused set /a key" in caplog.text and "limit 65536" in caplog.text
    # Nothing was half-stored, and what is there can still be replaced.
    assert lines(apply(service, f"get /a key{stored}"))[0] == f"port /a property key{stored} ="
    assert lines(apply(service, "set /a small 2"))[0] == "port /a property small = 2"


def test_bot_mode(service):
    apply(service, "register /p tcp 1.1.1.1 7")
    assert apply(service, "bot query /p").reply == Bottle([
        "port", ["name", "/p"], ["ip", "1.1.1.1"], ["port_number", 7], ["carrier", "tcp"]])
    assert apply(service, "bot query /x").reply == Bottle(["port", ["error", -2, "port not known"]])
    assert apply(service, "bot list").reply[0] == "ports"


def test_unknown_commands_get_an_empty_old_reply(service):
    assert lines(apply(service, "frobnicate")) == ["*** end of message"]
    assert lines(apply(service, "")) == ["*** end of message"]


def test_persistent_connection_lifecycle(service):
    assert apply(service, "subscribe /src /dst").reply == [Vocab("ok")]
    apply(service, "register /src")
    assert apply(service, "announce /src").actions == []      # /dst not there yet
    apply(service, "register /dst")
    assert apply(service, "announce /dst").actions == [Action("/src", "/dst", True)]
    listing = apply(service, "subscribe").reply
    assert listing == Bottle(["subscriptions",
                              ["subscription", ["src", "/src"], ["dest", "/dst"]]])
    # /dst went away: the surviving source is asked to drop its output.
    assert apply(service, "unregister /dst").actions == [Action("/src", "/dst", False)]
    assert apply(service, "unsubscribe /src /dst").reply == [Vocab("ok")]
    assert apply(service, "subscribe").reply == ["subscriptions"]


def test_a_break_decided_when_a_port_left_is_stale_once_it_is_back(service):
    """A module restarted under the same names: the break queued when its old port left must
    not leave it unconnected (the connector, after breaking, makes a wanted one again)."""
    apply(service, "subscribe /hal/state:o fast_tcp://m/state:i")
    for name in ("/hal/state:o", "/m/state:i"):
        apply(service, f"register {name}")
        apply(service, f"announce {name}")
    [stale] = apply(service, "unregister /m/state:i").actions
    assert not stale.connect and not service.subscriptions.wanted(stale.source, stale.target)
    apply(service, "register /m/state:i")
    assert apply(service, "announce /m/state:i").actions == [
        Action("/hal/state:o", "fast_tcp://m/state:i", True)]
    assert service.subscriptions.wanted(stale.source, stale.target)     # the break is stale
    apply(service, "unsubscribe /hal/state:o /m/state:i")
    assert not service.subscriptions.wanted(stale.source, stale.target)


def test_persistent_connection_with_carrier_and_topics(service):
    apply(service, "subscribe /a udp://b")
    for name in ("/a", "/b"):
        apply(service, f"register {name}")
    apply(service, "announce /a")
    assert apply(service, "announce /b").actions == [Action("/a", "udp://b", True)]
    apply(service, "subscribe /c topic://t")
    apply(service, "subscribe topic://t /d")
    for name in ("/c", "/d"):
        apply(service, f"register {name}")
        outcome = apply(service, f"announce {name}")
    assert Action("/c", "/d", True) in outcome.actions
    assert apply(service, "topic").reply == ["/t"]


def test_persist_from_expires_with_its_source(service):
    apply(service, "register /s")
    apply(service, "announce /s")
    apply(service, "subscribe /s /t from")
    apply(service, "unregister /s")
    assert apply(service, "subscribe").reply == ["subscriptions"]


def test_registry_full_is_reported_not_fatal():
    registry = Registry(":memory:", 10000)
    registry.max_number = registry.min_number + 1
    registry.register("/a", "tcp", "h", -1)
    registry.register("/b", "tcp", "h", -1)
    with pytest.raises(RegistryFull):
        registry.register("/c", "tcp", "h", -1)
    registry.unregister("/a")
    assert registry.register("/c", "tcp", "h", -1).port == 10002  # freed number reused


@pytest.mark.parametrize("command", [
    Bottle(["register", "/a\udcff"]),                      # fuzz: registry.py:76
    Bottle(["set", "/a", "ips", Bottle(["\udcc3"])]),      # nested text reaches SQLite too
    Bottle(["subscribe", Vocab(0xE9), "/b"]),               # a vocab of a non-UTF-8 byte
])
def test_text_that_is_not_utf8_is_a_peer_error_not_a_database_crash(service, command):
    from yarp_lite.errors import RemoteProtocolError

    with pytest.raises(RemoteProtocolError, match="is not UTF-8"):
        service.apply(command, "10.0.0.7")  # UnicodeEncodeError from sqlite3 before
    assert lines(apply(service, "register /a"))[0].startswith("registration name /a ")
