"""The fuzz campaign in miniature: every target, a few hundred fixed-seed inputs, every crasher.

The long coverage-guided campaign is ``python -m fuzz.run`` (see fuzz/README.md); this
keeps its invariant -- any input decodes or raises the layer's peer error -- in every
test run, and replays every input that ever crashed a decoder.
"""

from __future__ import annotations

import itertools
import random

import pytest

from bridge.errors import BridgeProtocolError
from fuzz.harness import Target, execute, join_records, split_records
from fuzz.mutator import campaign, mutations
from fuzz.run import replay
from fuzz.targets import TARGETS

SHORT_BUDGET = 1000


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_a_short_deterministic_campaign_finds_nothing(name):
    tally = campaign(TARGETS[name], SHORT_BUDGET, seed=0)
    assert tally.inputs == SHORT_BUDGET
    assert not tally.signatures, "\n\n".join(crash.report for crash in tally.first.values())


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_every_saved_crasher_now_decodes_or_raises_the_peer_error(name):
    assert replay([name]) == []


def test_seeds_are_valid_encodings_that_decode_without_any_error():
    for name in ("bottle_binary", "compact", "state_codec", "tiles", "config", "chain_board"):
        target = TARGETS[name]
        for seed in target.seeds():
            target.run(seed)  # a seed refused by its own decoder would seed nothing


def test_the_harness_tells_a_bug_from_a_peer_error():
    def decoder(data: bytes) -> None:
        if data == b"peer":
            raise BridgeProtocolError("refused")
        if data == b"bug":
            raise KeyError("oops")

    target = Target("toy", decoder, (BridgeProtocolError,), lambda: [b"ok"])
    assert execute(target, b"ok") is None and execute(target, b"peer") is None
    crash = execute(target, b"bug")
    assert crash is not None and crash.signature.startswith("KeyError@")
    assert "oops" in crash.report


def test_mutations_are_deterministic_per_seed_and_start_with_the_seeds():
    def first(seed: int):
        return list(itertools.islice(mutations([b"abc", b"defgh"], random.Random(seed), 64), 50))

    assert first(1) == first(1) and first(1) != first(2)
    assert first(1)[:2] == [b"abc", b"defgh"]


def test_records_round_trip():
    records = [b"", b"x", bytes(300)]
    assert split_records(join_records(records)) == records
