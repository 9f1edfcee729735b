"""Every listening socket of the drc topology under hostile peers (system/hostile.py).

The short version of ``python -m system.hostile run``: the same attacks, with
fewer silent connections and datagrams but the full 1 000-connection flood.
"""

from __future__ import annotations

import random

import pytest

from harness import dump_outputs_if_failed
from system import hostile


@pytest.fixture
def topology(tmp_path, request):
    topology = hostile.start_topology(tmp_path)
    yield topology
    for pc in topology.unique_pcs():
        dump_outputs_if_failed(request, pc.processes.values())
    topology.close()


def test_every_program_keeps_serving_under_hostile_peers(topology):
    rng = random.Random(7)
    found = hostile.targets(topology)
    assert {t.program for t in found} == {"yarp-server", "gaze_control", "hal", "bridge_robot",
                                          "bridge_pilot", "gateway"}
    outcomes = [hostile.attack(topology, target, rng, flood=1000, slow=20, datagrams=300,
                               say=lambda line: None) for target in found]
    assert all(o.ok for o in outcomes), hostile.table(outcomes)
    # Our own programs say what they refused (rospy's gateway logs to its own files).
    quiet = [o.target.label for o in outcomes if o.target.program != "gateway" and not o.refusals]
    assert not quiet, f"refused without a word: {quiet}\n{hostile.table(outcomes)}"


def test_the_attacks_are_shaped_like_their_protocols():
    assert hostile.opening("yarp").startswith(b"YA\x64\x1e\x00\x00RP")
    assert hostile.oversized("yarp")[8:12] == b"\xff\xff\xff\x7f"
    assert hostile.oversized("bridge")[:6] == b"\xff\xff\xff\xff\xff\x0f"
    assert int.from_bytes(hostile.oversized("tcpros")[:4], "little") == 0x7FFFFFFF
