"""The shared scene's objects and merge: any order of edits gives every station one scene."""

import itertools
import math

import pytest
from hypothesis import given, strategies as st

from nodekit.scene import (KINDS, Scene, SceneError, SceneObject, checked, from_bottle,
                            to_bottle)
from yarp_lite.bottle import Bottle, decode, encode

poses = st.lists(st.floats(-3, 3, allow_nan=False), min_size=6, max_size=6)
objects = st.builds(checked, st.sampled_from(["drc_valve", "drc_door", "footstep_1"]),
                    st.sampled_from(KINDS), poses, st.sampled_from(["pi_main", "pi_perception"]),
                    st.integers(1, 3), st.floats(0, 1e10), st.booleans())


@given(objects)
def test_a_record_crosses_yarp_and_comes_back_the_same(obj):
    assert from_bottle(decode(encode(to_bottle(obj)))) == obj


@pytest.mark.parametrize("values, field", [
    (["9valve", "valve", [0] * 6], "name"),
    (["drc_valve", "teapot", [0] * 6], "kind: one of valve"),
    (["drc_valve", "valve", [0] * 5], "pose: 6 finite numbers"),
    (["drc_valve", "valve", [0, 0, math.nan, 0, 0, 0]], "pose: 6 finite numbers"),
    (["drc_valve", "valve", [30, 0, 0, 0, 0, 0]], "pose: 30.0 m from the pelvis"),
    (["drc_valve", "valve", [0] * 6, "pi", -1], "station: 0..999"),
    (["drc_valve", "valve", [0] * 6, "pi", 1, -5.0], "stamp"),
])
def test_a_bad_object_is_refused_naming_the_field(values, field):
    with pytest.raises(SceneError, match=field):
        checked(*values)


def test_a_record_that_is_not_one_is_refused_not_crashed_on():
    good = list(to_bottle(checked("drc_valve", "valve", [0.6, 0.2, 0, 0, 0, 0], "pi", 1, 5.0)))
    for bad, why in ((good[:-1], "12 values"), (good[:11] + [2], "removed: 0 or 1"),
                     (good[:9] + ["one"] + good[10:], "station")):
        with pytest.raises(SceneError, match=why):
            from_bottle(Bottle(bad))


@given(st.lists(st.one_of(st.integers(), st.floats(), st.text(max_size=8)), max_size=14))
def test_any_bottle_is_a_record_or_a_scene_error(values):
    try:
        from_bottle(Bottle(values))
    except SceneError:
        pass


@given(st.lists(objects, max_size=6))
def test_every_order_of_the_same_edits_ends_in_the_same_scene(edits):
    outcomes = set()
    for order in itertools.islice(itertools.permutations(edits), 24):
        scene = Scene()
        for edit in order + order:                   # each twice: repeats change nothing
            scene.apply(edit)
        outcomes.add(tuple(scene.records()))
    assert len(outcomes) <= 1


def test_the_latest_edit_wins_and_a_removal_is_not_undone_by_an_older_placement():
    scene = Scene()
    placed = checked("drc_valve", "valve", [0.6, 0.2, 0.0, 0, 0, 0], "pi_main", 1, 10.0)
    moved = checked("drc_valve", "valve", [0.7, 0.2, 0.0, 0, 0, 0], "pi_perception", 2, 11.0)
    removed = SceneObject("drc_valve", "valve", moved.pose, "pi_main", 1, 12.0, True)
    assert scene.apply(moved) and not scene.apply(placed)
    assert scene.get("drc_valve").pose[0] == 0.7
    assert scene.apply(removed) and scene.get("drc_valve") is None and scene.objects() == []
    assert not scene.apply(placed) and scene.records() == [removed]
