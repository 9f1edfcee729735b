"""The HAL's joint arbitration as pure logic (clock passed in), and its configuration."""

import pytest

from walkman.inifile import IniError
from walkman.hal.arbitration import JointArbiter, owner_of
from walkman.hal.config import load_config
from walkman import MODELS_DIR

JOINTS = ["WaistLat", "WaistSag", "LShSag", "LHipSag"]


def test_owner_is_the_module_behind_the_command_port():
    assert owner_of("/drc_door/robot/torso/command:o") == "/drc_door"
    assert owner_of("/me/cmd") == "/me/cmd"  # not a module's robot port: the port itself
    # A YARP remote_controlboard opened with local=/gui/head: its rpc and command ports.
    assert owner_of("/gui/head/command:o") == owner_of("/gui/head/rpc:o") == "/gui/head"
    assert owner_of("/command:o") == "/command:o"


def test_refuse_keeps_the_first_holder_and_applies_the_rest():
    arbiter = JointArbiter(JOINTS)
    assert arbiter.filter("/walking", [0, 1, 3], now=0.0).allowed == [0, 1, 3]
    decision = arbiter.filter("/drc_door", [0, 1, 2], now=0.1)
    assert decision.allowed == [2]
    [conflict] = decision.conflicts
    assert (conflict.owner, conflict.holder, conflict.action) == ("/drc_door", "/walking",
                                                                  "refused")
    assert conflict.joints == ("WaistLat", "WaistSag")
    assert "held by /walking" in conflict.text()
    assert arbiter.holders(0.1) == {"WaistLat": "/walking", "WaistSag": "/walking",
                                    "LShSag": "/drc_door", "LHipSag": "/walking"}


def test_a_silent_holder_lets_its_joints_go():
    arbiter = JointArbiter(JOINTS, release_after=0.5)
    arbiter.filter("/walking", [0, 1], now=0.0)
    assert arbiter.filter("/drc_door", [0, 1], now=0.4).allowed == []
    assert arbiter.filter("/drc_door", [0, 1], now=0.6).allowed == [0, 1]  # walking paused
    assert arbiter.filter("/walking", [0], now=0.7).allowed == []          # resumed too early


def test_warnings_are_rate_limited_per_pair():
    arbiter = JointArbiter(JOINTS, warn_every=5.0)
    warned = []
    for tick in range(60):  # /a streams, /b keeps trying, every 0.1 s
        arbiter.filter("/a", [0], now=tick / 10)
        warned.append(bool(arbiter.filter("/b", [0], now=tick / 10 + 0.01).conflicts))
    assert [tick for tick, said in enumerate(warned) if said] == [0, 50]
    assert arbiter.refused == 60


def test_priority_takes_over_and_refuses_the_lower():
    arbiter = JointArbiter(JOINTS, "priority", {"drc_door": 2, "/walking": 1})
    arbiter.filter("/walking", [0, 1], now=0.0)
    decision = arbiter.filter("/drc_door", [0, 1], now=0.1)
    assert decision.allowed == [0, 1] and decision.conflicts[0].action == "took over"
    assert arbiter.filter("/walking", [0, 1], now=0.2).allowed == []
    assert arbiter.filter("/unlisted", [0], now=0.3).allowed == []  # priority 0


def test_share_applies_everything_but_says_so():
    arbiter = JointArbiter(JOINTS, "share")
    arbiter.filter("/a", [0], now=0.0)
    decision = arbiter.filter("/b", [0], now=0.1)
    assert decision.allowed == [0] and decision.conflicts[0].action == "shared"


def test_bad_arbiter_arguments_are_refused():
    with pytest.raises(ValueError, match="policy must be one of refuse, priority, share"):
        JointArbiter(JOINTS, "loudest")
    with pytest.raises(ValueError, match="release_after must be positive"):
        JointArbiter(JOINTS, release_after=0)


def _ini(tmp_path, text):
    path = tmp_path / "hal.ini"
    chains = (MODELS_DIR / "hal_chains.ini")
    path.write_text(chains.read_text() + text)
    return path


def test_arbitration_section_is_read(tmp_path):
    config = load_config(_ini(tmp_path, "[arbitration]\npolicy priority\nrelease_after 0.3\n"
                                        "priority walking 1 drc_door 2\n"))
    assert (config.policy, config.release_after) == ("priority", 0.3)
    assert config.priorities == {"walking": 1, "drc_door": 2}
    assert load_config(None).policy == "refuse"


@pytest.mark.parametrize("section, message", [
    ("policy loudest", "policy must be one of refuse, priority, share, got 'loudest'"),
    ("release_after soon", "release_after must be a number"),
    ("release_after 0", "release_after must be 0.01..60 s"),
    ("priority walking high", "priority of walking must be an integer"),
    ("priority walking", "does not understand priority walking"),
    ("volume 11", "does not understand volume 11"),
])
def test_bad_arbitration_sections_name_the_problem(tmp_path, section, message):
    path = _ini(tmp_path, f"[arbitration]\n{section}\n")
    with pytest.raises(IniError, match=message) as caught:
        load_config(path)
    assert str(path) in str(caught.value)
