"""Name servers first, then every program in any order: always the same connected system."""

import random

import pytest

from harness import dump_outputs_if_failed
from system.processes import WaitTimeout, wait_until
from system.topology import Topology


def observe_both(topology: Topology) -> dict:
    return {pc.name: topology.observe(pc) for pc in topology.unique_pcs()}


def differences(reference: dict, seen: dict, path: str = "") -> list:
    """Readable differences between two observations (nested dicts of lists)."""
    if isinstance(reference, dict) and isinstance(seen, dict):
        out = []
        for key in sorted(set(reference) | set(seen)):
            if key not in seen:
                out.append(f"{path}/{key}: missing")
            elif key not in reference:
                out.append(f"{path}/{key}: unexpected {str(seen[key])[:120]}")
            else:
                out += differences(reference[key], seen[key], f"{path}/{key}")
        return out
    return [] if reference == seen else [f"{path}: {reference} != {seen}"]


def settled(topology: Topology, timeout: float = 90.0) -> dict:
    """The observation once two in a row agree (connections are made in the background)."""
    previous = {}

    def stable() -> bool:
        nonlocal previous
        current = observe_both(topology)
        same, previous = current == previous, current
        return same

    wait_until(stable, timeout, interval=2.0, message="the system to settle")
    return previous


@pytest.mark.parametrize("kind,runs", [("drc", 3), ("lab", 2)])
def test_every_start_order_converges_to_the_same_graph(tmp_path, request, kind, runs):
    reference, orders = None, []
    for run in range(runs):
        topology = Topology(kind, tmp_path / f"run{run}")
        rng = random.Random(1000 * run + 7)
        try:
            topology.start_name_servers()
            if run == 1:  # the table reversed: consumers before producers
                order = topology.start_all(order=list(reversed(topology.table)), delay=0.5)
            else:
                order = topology.start_all(rng=rng, delay=1.0)
            orders.append(order)
            topology.wait_ready(240)
            seen = settled(topology)
            if reference is None:
                reference = seen
                # The reference itself is the connected system, not an empty one.
                pilot = seen["pilot" if kind == "drc" else "lab"]
                assert pilot["topics"]["/gaze_control/status"]["pub"], pilot["topics"]
                assert "/gaze_control/send_command" in pilot["services"]
                assert "/walkman/head/stateSI:o" in pilot["ports"]
            else:
                try:
                    wait_until(lambda: observe_both(topology) == reference, 60, interval=2.0,
                               message=f"the same graph as the first run, order {order}")
                except WaitTimeout:
                    diff = differences(reference, observe_both(topology))
                    raise AssertionError(f"start order {order} (first: {orders[0]}) gives a "
                                         f"different system:\n" + "\n".join(diff[:40]))
        finally:
            for pc in topology.unique_pcs():
                dump_outputs_if_failed(request, pc.processes.values())
            topology.close()
