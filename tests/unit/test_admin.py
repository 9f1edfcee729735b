"""Port commands and the admin protocol, against an in-memory port."""

from __future__ import annotations

from yarp_lite import admin
from yarp_lite.admin import Route
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.contact import Contact


class FakePort:
    name = "/p"

    def __init__(self):
        self.outputs = {"/out1": Route("/p", "/out1", "tcp")}
        self.inputs = [Route("/src", "/p", "udp", connectionless=True)]
        self.props = {}

    def address(self):
        return Contact("/p", "tcp", "1.2.3.4", 10002)

    def input_routes(self):
        return list(self.inputs)

    def output_routes(self):
        return list(self.outputs.values())

    def add_output(self, target):
        name = Contact.parse(target).name
        if name == "/missing":
            return False, f"Do not know how to connect to {target}"
        self.outputs[name] = Route("/p", name, Contact.parse(target).carrier or "tcp")
        return True, f"Added connection from /p to {target}"

    def remove_output(self, target):
        return self.outputs.pop(target, None) is not None

    def remove_input(self, source):
        before = len(self.inputs)
        self.inputs = [r for r in self.inputs if r.source != source]
        return len(self.inputs) != before

    def properties(self):
        return self.props

    def admin_fallback(self, command):
        return None


def test_describe_matches_yarp_text():
    assert admin.describe(FakePort()) == [
        "This is /p at tcp://1.2.3.4:10002/",
        "There is an output connection from /p to /out1 using tcp",
        "There is an input connection from /src to /p using udp"]


def test_port_commands():
    port = FakePort()
    assert admin.port_command(port, "/new") == ["Added connection from /p to /new"]
    assert admin.port_command(port, "!/new") == ["Removed connection from /p to /new"]
    assert admin.port_command(port, "!/new") == ["Could not find an outgoing connection to /new"]
    assert admin.port_command(port, "~/src") == ["Removing connection from /src to /p"]
    assert admin.port_command(port, "?")[0].startswith("This is a YARP port.")
    assert admin.port_command(port, "zzz") == admin.NOT_UNDERSTOOD


def test_admin_add_del_list():
    port = FakePort()
    assert admin.admin(port, Bottle([Vocab("add"), "/x", "udp"])) == \
        [0, "Added connection from /p to udp://x\r\n"]
    assert admin.admin(port, Bottle([Vocab("add"), "/missing"]))[0] == -1
    assert admin.admin(port, Bottle([Vocab("list"), Vocab("out")])) == ["/out1", "/x"]
    details = admin.admin(port, Bottle([Vocab("list"), Vocab("in"), "/src"]))
    assert details == [["from", "/src"], ["to", "/p"], ["carrier", "udp"], ["connectionless", 1]]
    assert admin.admin(port, Bottle([Vocab("del"), "/x"])) == \
        [0, "Removed connection from /p to /x\r\n"]
    assert admin.admin(port, Bottle([Vocab("del"), "/none"])) == [
        -1, "Could not find an outgoing connection to /none\r\n"
            "Could not find an incoming connection from /none\r\n"]


def test_admin_misc():
    port = FakePort()
    assert admin.admin(port, Bottle([Vocab("ver")])) == [Vocab("ver"), 1, 2, 3]
    assert admin.admin(port, Bottle([Vocab("help")]))[0] == Vocab("many")
    assert admin.admin(port, Bottle([Vocab("prop"), Vocab("set"), "k", 5])) == [Vocab("ok")]
    assert admin.admin(port, Bottle([Vocab("prop"), Vocab("get"), "k"])) == [5]
    assert admin.admin(port, Bottle(["nonsense"]))[0] == Vocab("fail")
    assert admin.admin(port, Bottle([]))[0] == Vocab("fail")


def test_properties_a_peer_stores_in_a_port_are_bounded():
    port = FakePort()
    chunk = b"\0" * 1000
    for index in range(100):
        reply = admin.admin(port, Bottle([Vocab("prop"), Vocab("set"), f"k{index}", chunk]))
        if reply != [Vocab("ok")]:
            break
    assert 50 < index < 70 and reply[0] == Vocab("fail")
    assert f"(limit {admin.MAX_PROPERTY_BYTES})" in reply[1]
    assert f"k{index}" not in port.props and len(port.props) == index
    assert admin.admin(port, Bottle([Vocab("prop"), Vocab("set"), "k0", 1])) == [Vocab("ok")]


def test_a_command_word_beyond_int32_reads_as_its_truncated_vocab():
    from yarp_lite.bottle import Int64

    port = FakePort()
    ver = Vocab("ver").code
    assert admin.admin(port, Bottle([Int64(ver + (1 << 32))])) == [Vocab("ver"), 1, 2, 3]
    assert admin.admin(port, Bottle([Int64(1 << 40)]))[0] == Vocab("fail")  # LocalProtocolError before
