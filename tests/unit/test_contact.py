"""Contacts, port-name rules and YARP's renaming environment."""

import pytest

from yarp_lite.contact import Contact, apply_environment, check_port_name, is_valid_port_name
from yarp_lite.errors import LocalProtocolError


@pytest.mark.parametrize("text, contact", [
    ("/read", Contact("/read")), ("tcp://read", Contact("/read", "tcp")),
    ("udp:/read", Contact("/read", "udp")),
    ("tcp://10.0.0.1:10002/", Contact("", "tcp", "10.0.0.1", 10002)),
    ("/10.0.0.1:99/x", Contact("/x", "tcp", "10.0.0.1", 99)),
    # not socket numbers: names (int() raised ValueError on these before)
    ("tcp://h:1\u00b2/", Contact("/h:1\u00b2/", "tcp")),
    ("tcp://h:" + "9" * 5000 + "/", Contact("/h:" + "9" * 5000 + "/", "tcp")),
    ("tcp://h:123456/", Contact("/h:123456/", "tcp")),
])
def test_parse(text, contact):
    assert Contact.parse(text) == contact


def test_text_forms():
    assert str(Contact("/r", "tcp")) == "tcp://r"
    assert Contact("/r", "tcp", "1.2.3.4", 5).uri() == "tcp://1.2.3.4:5/"


@pytest.mark.parametrize("name, valid", [("/a", True), ("...", True), ("a", False),
                                         ("/a/", False), ("/a b", False), ("", False)])
def test_validity(name, valid):
    assert is_valid_port_name(name) == valid
    if not valid:
        with pytest.raises(LocalProtocolError, match="invalid port name"):
            check_port_name(name)


def test_rename_then_prefix():
    env = {"YARP_RENAME_arm_state": "/robot/arm", "YARP_PORT_PREFIX": "/sim"}
    assert apply_environment("/arm/state", env) == "/sim/robot/arm"
    assert apply_environment("...", env) == "..."
