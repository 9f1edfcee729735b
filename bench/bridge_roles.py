"""Processes the bridge benchmark runs on the emulated robot and pilot hosts.

``python bridge_roles.py ROLE ARGS...``:

* ``hal MODE [RATE]`` -- a synthetic HAL: answers ``/walkman/rpc:i [get] chains``
  with the grouping of ``models/hal_chains.ini`` and streams every chain's
  ``stateSI:o`` at RATE Hz (default 100); MODE ``still`` (a robot standing, sensor
  noise below one encoder step) or ``moving`` (every joint swinging);
* ``readers PORT...`` -- a reader port ``/bench/read<i>`` per PORT, connected from
  it over tcp (as ``yarp connect`` would); prints ``ready`` once all are;
* ``ping-sender TARGET COUNT RATE`` -- writes ``(ping <time>) seq`` over tcp;
* ``ping-receiver PORT`` -- prints ``latency_ms <x>`` for each ping;
* ``statuses N RATE`` -- N GYM-like modules' ``/m<i>/status:o``, each written
  ``(seq idle 0.0)`` RATE times a second (spread over the period);
* ``blob-sender TARGET SIZE COUNT RATE CARRIER`` / ``blob-receiver PORT`` -- the
  whole-message baseline: Bottles holding SIZE bytes over YARP's udp carrier;
* ``module-cycle NAME ROUNDS UP DOWN`` -- a GYM module's four ports, opened for UP
  seconds and closed for DOWN, ROUNDS times; prints ``opened <time>`` once all four
  are registered and ``closed <time>`` once all are gone (wall clock);
* ``port-watch PORT`` -- asks its name server for PORT every 10 ms; prints
  ``shown <time>`` and ``gone <time>`` when the answer changes;
* ``loop-probe MODULE COUNT RATE`` -- the pilot's loop: starts the counting GYM
  module MODULE (``walkman-module witness``), then sends it COUNT numbered
  commands at RATE Hz and prints ``loop_ms <x>`` when the module's status shows each
  (``lost <n>`` after 5 s without it).
"""

from __future__ import annotations

import random
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from walkman.gym.interfaces import GYM_PORTS  # noqa: E402
from walkman.hal import protocol  # noqa: E402
from walkman.hal.config import load_config  # noqa: E402
from walkman.hal.protocol import ChainState  # noqa: E402
from yarp_lite.bottle import Bottle  # noqa: E402
from yarp_lite.port import Port  # noqa: E402
from yarp_lite.rpc import RpcServer  # noqa: E402
from walkman import MODELS_DIR  # noqa: E402


def hal(mode: str, rate: float = 100.0) -> None:
    config = load_config(MODELS_DIR / "hal_chains.ini")
    chains = config.chains
    RpcServer(protocol.robot_rpc_name("walkman"),
              handler=lambda _: Bottle([Bottle([name, *joints]) for name, joints in chains.items()]))
    ports = {name: Port(protocol.port_names("walkman", name)["state_si"]) for name in chains}
    rng = np.random.default_rng(0)
    started, seq = time.monotonic(), 0
    print("ready", flush=True)
    while True:
        t = time.monotonic() - started
        seq += 1
        offset = 0
        for name, joints in chains.items():
            n = len(joints)
            index = np.arange(offset, offset + n)
            if mode == "moving":
                q = 0.8 * np.sin(0.5 * t + index)
                qdot = 0.4 * np.cos(0.5 * t + index)
                tau = 40 * np.sin(1.3 * t + index) + rng.normal(0, 0.5, n)
            else:
                q = 0.1 * np.ones(n) + rng.normal(0, 1e-5, n)
                qdot = np.zeros(n)
                tau = 5 * np.ones(n) + rng.normal(0, 0.01, n)
            temperature = 35 + 0.05 * t / 60 + 0.1 * index % 3 + rng.normal(0, 0.002, n)
            ports[name].write(protocol.encode_state_si(ChainState(
                seq, t, tuple(q), tuple(qdot), tuple(tau), tuple(temperature))))
            offset += n
        time.sleep(1.0 / rate)


def readers(sources: list) -> None:
    from yarp_lite.network import connect

    ports = [Port(f"/bench/read{i}", reader=lambda bottle: None) for i in range(len(sources))]
    for source, port in zip(sources, ports):
        while port.input_count == 0:
            connect(source, port.name, "tcp")
            time.sleep(0.2)
    print("ready", flush=True)
    time.sleep(3600)


def ping_sender(target: str, count: int, rate: float) -> None:
    port = Port("/bench/pinger")
    while port.output_count == 0:
        port.add_output(target, quiet=True)
        time.sleep(0.2)
    time.sleep(1.0)
    for seq in range(2, count + 2):
        port.write(Bottle([Bottle(["ping", time.time()]), seq]))
        time.sleep(1.0 / rate)
    print("done", flush=True)


def ping_receiver(name: str) -> None:
    def on_ping(bottle: Bottle) -> None:
        now = time.time()
        print(f"latency_ms {(now - float(bottle[0][1])) * 1000:.3f}", flush=True)

    Port(name, reader=on_ping)
    print("ready", flush=True)
    time.sleep(3600)


def statuses(count: int, rate: float) -> None:
    ports = [Port(f"/m{i}/status:o") for i in range(count)]
    print("ready", flush=True)
    seq, pause = 0, 1.0 / rate / count
    while True:
        seq += 1
        for port in ports:
            port.write(Bottle([seq, "idle", 0.0]))
            time.sleep(pause)


def blob_sender(target: str, size: int, count: int, rate: float, carrier: str) -> None:
    port = Port("/bench/blobs")
    while port.output_count == 0:
        port.add_output(target, carrier, quiet=True)
        time.sleep(0.2)
    time.sleep(1.0)
    for seq in range(count):
        port.write(Bottle([seq, bytes(size)]))
        time.sleep(1.0 / rate)
    print("done", flush=True)


def blob_receiver(name: str) -> None:
    Port(name, reader=lambda bottle: print(f"blob {bottle[0]}", flush=True))
    print("ready", flush=True)
    time.sleep(3600)


def module_cycle(name: str, rounds: int, up: float, down: float) -> None:
    for _ in range(rounds):
        ports = [Port(port.of(name), reader=(lambda b: None) if port.to_robot else None)
                 for port in GYM_PORTS]
        print(f"opened {time.time():.6f}", flush=True)
        time.sleep(up)
        for port in ports:
            port.close()
        print(f"closed {time.time():.6f}", flush=True)
        time.sleep(down)
    print("done", flush=True)


def port_watch(name: str) -> None:
    from yarp_lite.errors import YarpError
    from yarp_lite.nameclient import NameClient

    client, shown = NameClient(), False
    print("ready", flush=True)
    while True:
        try:
            now_shown = client.query(name) is not None
        except YarpError:
            now_shown = shown
        if now_shown != shown:
            shown = now_shown
            print(f"{'shown' if shown else 'gone'} {time.time():.6f}", flush=True)
        time.sleep(0.01)


def loop_probe(module: str, count: int, rate: float) -> None:
    import threading

    from yarp_lite.network import connect

    arrived = threading.Condition()
    latest: list = [None]

    def on_status(bottle: Bottle) -> None:
        with arrived:
            latest[0] = bottle
            arrived.notify_all()

    status = Port("/bench/loop/status:i", reader=on_status)
    command, switch = Port("/bench/loop/command:o"), Port("/bench/loop/switch:o")
    while not (status.input_count and command.output_count and switch.output_count):
        if not status.input_count:
            connect(f"/{module}/status:o", status.name, "tcp")
        for port, target in ((command, "command:i"), (switch, "switch:i")):
            if not port.output_count:
                port.add_output(f"/{module}/{target}", quiet=True)
        time.sleep(0.2)
    switch.write(Bottle(["start", 2]))
    time.sleep(2.0)
    print("ready", flush=True)
    for number in range(3, count + 3):
        started = time.monotonic()
        command.write(Bottle([Bottle(["count", number]), number]))
        with arrived:
            seen = arrived.wait_for(lambda: latest[0] is not None and len(latest[0]) > 2 and
                                    latest[0][-1] == number, timeout=5.0)
        if seen:
            print(f"loop_ms {(time.monotonic() - started) * 1000:.3f}", flush=True)
        else:
            print(f"lost {number}", flush=True)
        # Not a whole number of the module's 10 ms ticks: a fixed interval sent every command
        # just after a tick, so each waited a whole tick for run().
        time.sleep(1.0 / rate + random.uniform(0.0, 0.01))
    print("done", flush=True)


if __name__ == "__main__":
    role, args = sys.argv[1], sys.argv[2:]
    if role == "hal":
        hal(args[0], *(float(a) for a in args[1:2]))
    elif role == "readers":
        readers(args)
    elif role == "ping-sender":
        ping_sender(args[0], int(args[1]), float(args[2]))
    elif role == "ping-receiver":
        ping_receiver(args[0])
    elif role == "statuses":
        statuses(int(args[0]), float(args[1]))
    elif role == "blob-sender":
        blob_sender(args[0], int(args[1]), int(args[2]), float(args[3]), args[4])
    elif role == "blob-receiver":
        blob_receiver(args[0])
    elif role == "module-cycle":
        module_cycle(args[0], int(args[1]), float(args[2]), float(args[3]))
    elif role == "port-watch":
        port_watch(args[0])
    elif role == "loop-probe":
        loop_probe(args[0], int(args[1]), float(args[2]))
    else:
        raise SystemExit(f"unknown role {role}")
