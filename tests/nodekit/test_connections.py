"""The connection keeper against a ``yarp-lite server``: connections made when both ends
exist, in either direction, and what a round costs the name server."""

from __future__ import annotations

from typing import List

from harness import wait_until
from nodekit import connections
from nodekit.connections import ConnectionKeeper
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.registration import RegistrationKeeper


class CountingClient(NameClient):
    """A name client that remembers the first word of each request it sends."""

    def __init__(self) -> None:
        super().__init__()
        self.requests: List[str] = []

    def text(self, command: str, multi: bool = True) -> List[str]:
        self.requests.append(command.split()[0])
        return super().text(command, multi)


def asked_in_a_round(client: CountingClient, keeper: ConnectionKeeper) -> List[str]:
    """What one round of ``keeper`` asks through ``client``.  The ports' registration keeper
    asks about one of them every 2 s through the same client (fc74: ['list', 'query',
    'query'], the second about /keeper/out8): it is held off meanwhile."""
    with RegistrationKeeper.instance().held():
        client.requests.clear()
        keeper.check_now()
        return list(client.requests)


def test_connections_are_made_whichever_end_comes_first_and_remade(lite_world):
    keeper = ConnectionKeeper(period=0.1)
    ours_in = Port("/keeper/in", reader=lambda bottle: None)
    ours_out = Port("/keeper/out")
    feed = keeper.want("/module/out", ours_in.name, ours_in, ours_is_source=False)
    delivery = keeper.want(ours_out.name, "/module/in", ours_out, ours_is_source=True)
    keeper.start()
    module: List[Port] = []
    try:
        keeper.check_now()
        assert not keeper.connected(feed) and not keeper.connected(delivery)
        module = [Port("/module/out"), Port("/module/in", reader=lambda bottle: None)]
        wait_until(lambda: keeper.connected(feed) and keeper.connected(delivery), 5,
                   message="both connections")
        for port in module:  # the module restarts
            port.close()
        wait_until(lambda: not keeper.connected(feed) and not keeper.connected(delivery), 5,
                   message="both gone")
        module = [Port("/module/out"), Port("/module/in", reader=lambda bottle: None)]
        wait_until(lambda: keeper.connected(feed) and keeper.connected(delivery), 5,
                   message="both made again")
    finally:
        keeper.stop()
        for port in [*module, ours_in, ours_out]:
            port.close()


def test_a_round_with_many_missing_asks_the_name_server_once(lite_world):
    client = CountingClient()
    keeper = ConnectionKeeper()
    count = connections.LIST_ABOVE * 3
    ours = [Port(f"/keeper/out{i}", nameclient=client) for i in range(count)]
    for index, port in enumerate(ours):
        keeper.want(port.name, f"/absent/in{index}", port, ours_is_source=True)
    there = Port("/absent/in5", reader=lambda bottle: None)
    try:
        requests = asked_in_a_round(client, keeper)
        # one list, then one query for the one that is there (not one per missing port)
        assert requests == ["list", "query"], requests
        assert ours[5].output_count == 1
        assert sum(port.output_count for port in ours) == 1
    finally:
        there.close()
        for port in ours:
            port.close()


def test_a_few_missing_are_each_tried_without_a_list(lite_world):
    client = CountingClient()
    keeper = ConnectionKeeper()
    ours = [Port(f"/keeper/few{i}", nameclient=client) for i in range(2)]
    for index, port in enumerate(ours):
        keeper.want(port.name, f"/absent/few{index}", port, ours_is_source=True)
    try:
        requests = asked_in_a_round(client, keeper)
        assert requests == ["query", "query"], requests
    finally:
        for port in ours:
            port.close()
