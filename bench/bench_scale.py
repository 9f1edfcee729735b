#!/usr/bin/env python3
"""Name-server scale: 10 000 ports and 1 000 registrations at once, yarp-lite beside yarpserver.

The DRC had a few dozen ports; labs run far more.  For each name server
(``yarp-lite server`` and, when the reference YARP is built, the real
``yarpserver``), ports are registered as real YARP ports do it (``register``
with a contact, then the ``offers``/``accepts``/``ips``/``process``
properties) until 10 000 are there.  At each size the script measures, from
one client on loopback:

* ``register``: the median time to register one more port with its properties;
* ``query``: the median round trip of ``query`` for random registered names;
* ``list``: one ``list`` of every port;
* the server's resident memory.

Then 1 000 clients (threads, one connection each) register at once: the wall
time and how many failed.  A cost that grows with the count shows in the
``register`` and ``query`` columns (they should stay flat; ``list`` grows
linearly, as it must).

Every name-server request is a new TCP connection (as in YARP), so the full
run makes about 100 000 connections in a few minutes; with Linux's default
local port range and TIME_WAIT the machine can run out of local ports ("Cannot
assign requested address") before 10 000: ``--quick`` stops at 2 000.

Usage: ``.venv/bin/python bench/bench_scale.py [--quick]``.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Dict, List

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from bench_yarp_lite import Bench  # noqa: E402
from host import say_machine  # noqa: E402
from yarp_lite.freeport import free_port  # noqa: E402
from yarp_lite.nameclient import NameClient  # noqa: E402
from yarp_lite.nameconfig import read_server_address  # noqa: E402

PROPERTIES = (("offers", ["tcp", "fast_tcp", "text", "udp"]),
              ("accepts", ["tcp", "fast_tcp", "text", "udp"]),
              ("ips", ["127.0.0.1"]), ("process", ["4242"]))


def rss_kib(pid: int) -> int:
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def register_like_a_port(client: NameClient, index: int) -> None:
    name = f"/scale/port/{index:05d}"
    client.register(name, "tcp", "127.0.0.1", 20000 + index % 40000)
    for key, values in PROPERTIES:
        client.set(name, key, values)


def grow(bench: Bench, real: bool, sizes: List[int]) -> List[Dict[str, float]]:
    server = bench.start_name_server(real=real, socket_number=free_port())
    address = read_server_address("/root", bench.env)
    client = NameClient(address=address, environ=bench.env)
    rows, registered = [], 0
    rng = random.Random(1)
    for size in sizes:
        costs = []
        while registered < size:
            started = time.perf_counter()
            register_like_a_port(client, registered)
            costs.append(time.perf_counter() - started)
            registered += 1
        queries = []
        for _ in range(200):
            name = f"/scale/port/{rng.randrange(registered):05d}"
            started = time.perf_counter()
            client.query(name)
            queries.append(time.perf_counter() - started)
        started = time.perf_counter()
        listed = len(client.list_lines())
        listing = time.perf_counter() - started
        rows.append({"ports": registered, "listed": listed,
                     "register_ms": statistics.median(costs[-500:]) * 1e3,
                     "query_us": statistics.median(queries) * 1e6,
                     "list_ms": listing * 1e3, "rss_mib": rss_kib(server.pid) / 1024})
        print(f"    {'yarpserver' if real else 'yarp-lite'}: {registered} ports", flush=True)
    rows.append(at_once(address, bench, 1000))
    server.kill()
    server.wait()
    bench.children.remove(server)
    return rows


def at_once(address, bench: Bench, count: int) -> Dict[str, float]:
    """``count`` clients, each on its own connection, register one port each at once."""
    errors: List[Exception] = []
    gate = threading.Barrier(count + 1)

    def one(index: int) -> None:
        client = NameClient(address=address, environ=bench.env)
        gate.wait()
        try:
            client.register(f"/scale/at_once/{index:04d}", "tcp", "127.0.0.1", 30000 + index)
        except Exception as exc:  # noqa: BLE001 -- counted and reported
            errors.append(exc)

    threads = [threading.Thread(target=one, args=(i,)) for i in range(count)]
    for thread in threads:
        thread.start()
    gate.wait()
    started = time.perf_counter()
    for thread in threads:
        thread.join()
    return {"at_once": count, "wall_s": time.perf_counter() - started, "failed": len(errors),
            "first_error": str(errors[0])[:80] if errors else ""}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="up to 2 000 ports (a smoke run)")
    options = parser.parse_args()
    say_machine()
    sizes = [250, 1000, 2000] if options.quick else [1000, 2500, 5000, 10000]
    bench = Bench(options.quick)
    results: Dict[str, List[Dict[str, float]]] = {}
    try:
        print("name servers growing to", sizes[-1], "ports (registered as YARP ports do)",
              flush=True)
        results["yarp-lite"] = grow(bench, False, sizes)
        if bench.prefix:
            results["yarpserver"] = grow(bench, True, sizes)
        else:
            print("  (no reference YARP: yarpserver column empty)")
    finally:
        bench.close()
    print()
    print(f"  {'ports':>6} | {'register ms':>23} | {'query us':>21} | {'list ms':>19} | "
          f"{'RSS MiB':>17}")
    print(f"  {'':>6} | {'lite':>11} {'yarpserver':>11} | {'lite':>10} {'yarpserver':>10} | "
          f"{'lite':>9} {'yarpserver':>9} | {'lite':>8} {'yarpserver':>8}")
    lite = results["yarp-lite"]
    real = results.get("yarpserver") or [{} for _ in lite]
    nan = float("nan")
    for a, b in zip(lite[:-1], real[:-1]):
        print(f"  {a['ports']:>6} | {a['register_ms']:>11.2f} {b.get('register_ms', nan):>11.2f} "
              f"| {a['query_us']:>10.0f} {b.get('query_us', nan):>10.0f} "
              f"| {a['list_ms']:>9.1f} {b.get('list_ms', nan):>9.1f} "
              f"| {a['rss_mib']:>8.1f} {b.get('rss_mib', nan):>8.1f}")
    a, b = lite[-1], real[-1]
    print(f"\n  1000 registrations at once: yarp-lite {a['wall_s']:.2f} s, {a['failed']} failed"
          f"{' (' + a['first_error'] + ')' if a['failed'] else ''}; yarpserver "
          f"{b.get('wall_s', nan):.2f} s, {b.get('failed', 0)} failed"
          f"{' (' + b.get('first_error', '') + ')' if b.get('failed') else ''}")
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
