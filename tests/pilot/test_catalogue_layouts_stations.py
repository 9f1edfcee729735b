"""The Pilot Interface's Qt-free layers: catalogues, layouts, stations, frame decoding."""

from __future__ import annotations

import pytest

from pilot.catalogue import catalogue_of, legal_switches
from pilot.layouts import DEFAULT_LAYOUTS, LayoutError, load_layout, parse_layouts
from pilot.link import image_pixels
from rosnodes.stations import STATION_SPAN, SequenceNumbers, parse_sent, station_of
from yarp_lite.bottle import Bottle
from bridge import config as bridge_config
from walkman import MODELS_DIR

#: The GYM modules of the shipped drc configuration: the layouts must name only those.
MODULES = list(bridge_config.load(MODELS_DIR / "bridge_drc.xml").gym_modules)


def test_the_valve_widget_offers_the_task_in_its_order_and_only_legal_steps():
    valve = catalogue_of("drc_valve")
    assert list(valve.commands) == ["valvedatasent", "reach", "approach", "grasp", "turn",
                                    "ungrasp", "move_away", "home"]
    assert valve.legal("idle") == ["valvedatasent"]
    assert valve.legal("grasped") == ["turn", "ungrasp"]
    assert valve.commands["turn"].dangerous and not valve.commands["reach"].dangerous
    assert valve.commands["valvedatasent"].fields == ["X", "Y", "Z", "ROLL", "PITCH", "YAW",
                                                      "RADIUS"]
    assert "takes 7 numbers" in valve.commands["valvedatasent"].check([1.0, 2.0])
    assert catalogue_of("walking").commands["turn"].dangerous


def test_lifecycle_buttons_follow_figure_8():
    assert legal_switches(None) == []          # nothing heard: nothing to switch
    assert legal_switches("grasped") == ["pause", "stop", "quit"]
    assert legal_switches("paused") == ["resume", "stop", "quit"]
    assert legal_switches("stopped") == ["start", "quit"]


def test_an_unknown_module_gets_its_states_and_free_text():
    other = catalogue_of("another_teams_module", ["idle", "busy"])
    assert other.statuses == ["idle", "busy"] and other.commands == {}


def test_every_shipped_layout_parses_against_the_drc_configuration():
    for name in ("main-pilot", "perception-pilot", "status-pilot", "walking-developer",
                 "network-monitor"):
        assert load_layout(name, DEFAULT_LAYOUTS, MODULES).tabs


@pytest.mark.parametrize("text, message", [
    ("[layout x]\ntab A = view3d bogus\n", "f.ini: layout 'x', tab A: unknown widget 'bogus'"),
    ("[layout x]\ntab A = task:nowhere\n", "names module 'nowhere'"),
    ("[layout x]\nside = log\n", "layout 'x' has no tab"),
    ("[layout x]\ntab A = view3d\ntab B = view3d\n", "shows view3d more than once"),
    ("[window x]\ntab A = log\n", "must be [layout NAME]"),
    ("[layout x]\ntab A view3d\n", "[line 2]"),
])
def test_bad_layouts_are_refused_saying_where(text, message):
    with pytest.raises(LayoutError, match=None) as error:
        parse_layouts(text, "f.ini", MODULES)
    assert message in str(error.value)


def test_two_stations_in_the_same_millisecond_never_share_a_sequence_number():
    frozen = lambda: 1_700_000_000.123  # noqa: E731 -- one instant for both pilots
    first, second = SequenceNumbers(1, frozen), SequenceNumbers(2, frozen)
    a = [first.next() for _ in range(50)]
    b = [second.next() for _ in range(50)]
    assert not set(a) & set(b)
    assert a == sorted(a) and len(set(a)) == 50
    assert {station_of(s) for s in a} == {1} and {station_of(s) for s in b} == {2}
    assert max(a + b) < 2 ** 31 and STATION_SPAN == 16
    with pytest.raises(ValueError):
        SequenceNumbers(0)


def test_a_sent_record_is_parsed_or_refused():
    record = Bottle([3, "pi_a", "drc_valve", "command", "reach 123", 123])
    assert parse_sent(record) == (3, "pi_a", "drc_valve", "command", "reach 123", 123)
    assert parse_sent(Bottle(["x", 1])) is None


def test_frames_decode_to_rgb():
    bgr = image_pixels("bgr8", 1, 1, bytes([1, 2, 3]))
    assert bgr.tolist() == [[[3, 2, 1]]]
    assert image_pixels("mono8", 1, 2, bytes([0, 9])).tolist() == [[[0, 0, 0], [9, 9, 9]]]
    assert image_pixels("32FC1", 1, 1, bytes(4)) is None
