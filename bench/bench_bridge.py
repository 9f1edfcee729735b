#!/usr/bin/env python3
"""The bridge's benchmarks, on emulated robot and pilot PCs (needs root).

1. **Table 1 bandwidth** -- robot to pilot at T = 1 s: 33 joints (a synthetic
   HAL streaming stateSI, standing still or moving every joint), 7
   temperatures per second, 5 GYM module statuses (real modules).  Bits per
   second of bridge frames (payload and framing, no TCP/IP), then on the veth
   with TCP/IP headers.  References: the paper's 2400 bit/s, and YARP's tcp
   carrier carrying the same messages once a second directly between the PCs,
   counted on the same veth.
2. **Perception completeness** at delta-t = 0.4 s versus random loss, for a
   320x240 image and an 80x60 organized cloud at 2 Hz, without FEC, with a
   fixed repair fraction of 0.3 and with ``fec="auto"`` (repairs per frame shown),
   counted by a ROS subscriber on the pilot side from the pixels and points it
   gets (``tests/bridge/cloud_probe.py``: missing regions are black or NaN), against
   the whole-message baseline measured through YARP's udp carrier on the same link
   (a message counts only if every datagram arrived).
3. **Pilot command latency** through the bridge on the lab and drc profiles
   (median, p99), against a direct YARP connection over the same link.
4. **All 256 ids in use** (lab profile): 256 GYM modules (1024 flows, 512 ports a
   side) against 8, each module's status written once a second on the robot; per
   size, interleaved: seconds from a bridge's start to its ports registered (and
   of that, opening its ports and connecting to the modules' ports), each bridge's
   CPU and memory and the robot name server's CPU once linked, the link's bit/s, and the
   one-way latency of commands to the module with the highest id.
5. **Presence** (lab and drc profiles): a GYM module's four ports opened and
   closed on the robot again and again; how long until the pilot's name server
   shows them (the bridge's stand-ins) and stops showing them, against one name
   server both PCs use (the lab topology over the same link).
6. **The pilot's loop** (lab and drc profiles): a pilot's command to a GYM module
   on the robot until the pilot reads the module's status that answers it (median,
   p99), through the bridge and with one name server over the same link.

Usage: ``.venv/bin/python bench/bench_bridge.py [--quick] [--only 1,2,3,4,5,6]``.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path
from contextlib import contextmanager
from typing import Dict, Iterator, List, Tuple

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
# The tests' process harness (TwoPCs, YarpWorld, cloud_probe.py) drives the emulated PCs: a
# source-tree bench may borrow it.  What runs on the robot comes from the package (the GYM
# modules are ``walkman-module witness``), so an installed tree needs nothing from tests/.
sys.path.append(str(ROOT / "tests"))
sys.path.append(str(ROOT / "tests" / "bridge"))

from netem import emulation  # noqa: E402
from netem.emulation import EmulatedLink  # noqa: E402
from bridge_harness import HERE as TEST_HELPERS, PYTHON, TwoPCs  # noqa: E402
from harness import YarpWorld, lite_implementation, wait_until  # noqa: E402
from system.processes import descendants, usage  # noqa: E402
from host import cpu_seconds, say_machine  # noqa: E402  (bench/ is the script's folder)
from walkman import MODELS_DIR  # noqa: E402

ROLES = str(HERE / "bridge_roles.py")
LITE = lite_implementation()
PAPER_TABLE_1 = 2400


def say(text: str) -> None:
    print(text, flush=True)


def status_numbers(pcs: TwoPCs, side) -> Dict[str, float]:
    text = side.world.run_tool(LITE, "rpc", f"/bridge/{side.name}/rpc:i",
                               input_text="status\n").stdout
    return {key: float(value) for key, value in re.findall(r"\((\w+) (-?[\d.]+)\)", text)}


def flows(pcs: TwoPCs, side) -> Dict[str, Dict[str, float]]:
    text = side.world.run_tool(LITE, "rpc", f"/bridge/{side.name}/rpc:i",
                               input_text="status\n").stdout
    out = {}
    for name, body in re.findall(r'\("(/[^"]+)" \(((?:\(\w+ [-\d.e+]+\) ?)+)\)\)', text):
        out[name] = {k: float(v) for k, v in re.findall(r"\((\w+) ([-\d.e+]+)\)", body)}
    return out


@contextmanager
def bridged(link: EmulatedLink, config: str) -> Iterator[TwoPCs]:
    """The bridged topology: name servers on both PCs, stopped and removed afterwards."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        os.environ["COUNTER_LOG"] = str(root / "executed.log")
        path = root / "bridge.xml"
        path.write_text(config)
        pcs = TwoPCs(root, LITE, path, link=link)
        try:
            pcs.start_name_servers()
            yield pcs
        finally:
            pcs.close()


# -- 1: Table 1 ----------------------------------------------------------------------------

TABLE_1_CONFIG = """<bridge period="1.0" gather="0.4">
  <modules>{modules}</modules>
  <robot_state id="20" robot="walkman" channel="tcp" rate="10"/>
</bridge>"""


def direct_table_1(link: EmulatedLink, mode: str, duration: float) -> Dict[str, float]:
    """The same messages once a second over YARP's tcp carrier, counted on the cable.

    The original topology: one name server on the robot, the synthetic HAL writing
    every chain's stateSI:o at 1 Hz and five statuses at 1 Hz, read on the pilot PC by
    ports connected over tcp.  Measured as the bridge is: the robot's veth counters.
    """
    from walkman.hal import protocol
    from walkman.hal.config import load_config

    chains = load_config(MODELS_DIR / "hal_chains.ini").chains
    sources = [protocol.port_names("walkman", name)["state_si"] for name in chains]
    sources += [f"/m{i}/status:o" for i in range(5)]
    with one_network(link) as (robot, pilot):
        robot.start([PYTHON, ROLES, "hal", mode, "1"], "synthetic hal").wait_for("ready", 30)
        robot.start([PYTHON, ROLES, "statuses", "5", "1"], "statuses").wait_for("ready", 30)
        pilot.start([PYTHON, ROLES, "readers", *sources], "readers").wait_for("ready", 60)
        time.sleep(3)
        before = link.tx_counters("robot")
        time.sleep(duration)
        after = link.tx_counters("robot")
    sent_bytes, packets = after[0] - before[0], after[1] - before[1]
    return {"with_tcp_ip": (sent_bytes - 14 * packets) * 8 / duration,
            "packets": packets / duration}


def table_1(link: EmulatedLink, mode: str, duration: float) -> Dict[str, float]:
    modules = "".join(f'<module name="m{i}" id="{i}"/>' for i in range(1, 6))
    with bridged(link, TABLE_1_CONFIG.format(modules=modules)) as pcs:
        pcs.robot.python(ROLES, "hal", mode, name="synthetic hal").wait_for("ready", 30)
        for i in range(1, 6):
            pcs.robot.start([PYTHON, "-m", "walkman.gym.supervisor",
                             "witness", "--name", f"/m{i}"], f"m{i}")
        pcs.start_bridge(pcs.robot)
        pcs.start_bridge(pcs.pilot)
        pcs.wait_linked(60)
        time.sleep(8)
        before = status_numbers(pcs, pcs.robot)
        wire_before = link.tx_counters("robot")
        time.sleep(duration)
        after = status_numbers(pcs, pcs.robot)
        wire_after = link.tx_counters("robot")
    payload = (after["payload_out"] - before["payload_out"]) * 8 / duration
    frames = (after["bytes_out"] - before["bytes_out"]) * 8 / duration
    sent_bytes = wire_after[0] - wire_before[0]
    packets = wire_after[1] - wire_before[1]
    return {"payload": payload, "framing": frames - payload, "total": frames,
            "with_tcp_ip": (sent_bytes - 14 * packets) * 8 / duration,
            "packets": packets / duration}


# -- 2: completeness -----------------------------------------------------------------------

PERCEPTION_CONFIG = """<bridge period="0.5" gather="0.4">
  <ros_topics>
    <topic name="/multisense/left/image_color" type="sensor_msgs/Image" id="30"
           direction="robot_to_pilot" channel="udp" quality="80" fec="{fec}"/>
    <topic name="/multisense/points" type="sensor_msgs/PointCloud2" id="31"
           direction="robot_to_pilot" channel="udp" fec="{fec}"/>
  </ros_topics>
</bridge>"""
IMAGE_BYTES, CLOUD_BYTES = 320 * 240 * 3, 80 * 60 * 16


def completeness(link: EmulatedLink, loss: float, fec: "float | str", frames: int
                 ) -> Dict[str, float]:
    with bridged(link, PERCEPTION_CONFIG.format(fec=fec)) as pcs:
        for side in (pcs.robot, pcs.pilot):
            pcs.start_roscore(side)
        pcs.start_bridge(pcs.robot)
        pcs.start_bridge(pcs.pilot)
        pcs.wait_linked(60)
        probe = pcs.pilot.python(str(TEST_HELPERS / "cloud_probe.py"), name="probe")
        probe.wait_for("probe ready", 60)
        time.sleep(4)  # the ROS endpoints register
        link.set_loss(loss)
        camera = pcs.robot.python(str(TEST_HELPERS / "camera_publisher.py"), "2",
                                  str(frames), name="camera")
        camera.wait(frames / 2 + 60)
        time.sleep(2)
        link.set_loss(0)
        sent = flows(pcs, pcs.robot)
        arrived = list(probe.lines)
    # Completeness as a subscriber on the pilot side sees it (its own pixels and points, not
    # the bridge's counters): each frame the camera published counts, 0 if it never came.
    out = {}
    for topic, short in (("/multisense/left/image_color", "image"),
                         ("/multisense/points", "cloud")):
        shares = [1 - float(m.group(1)) for m in
                  map(re.compile(rf"^{short} \d+ ([\d.]+)").search, arrived) if m]
        out[short] = sum(shares) / frames
        total = sent.get(topic, {}).get("sent", 0)
        out[short + " repairs"] = sent.get(topic, {}).get("repairs_sent", 0) / total \
            if total else float("nan")
    return out


@contextmanager
def one_network(link: EmulatedLink) -> Iterator[Tuple[YarpWorld, YarpWorld]]:
    """The original direct topology: one name server on the robot, used by both PCs."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        robot = YarpWorld(root, LITE, wrap=link.exec_argv("robot", []),
                          ip=link.address("robot"))
        pilot = YarpWorld(root, LITE, wrap=link.exec_argv("pilot", []))
        try:
            robot.start_server()
            yield robot, pilot
        finally:
            pilot.close()
            robot.close()


def whole_message_baseline(link: EmulatedLink, loss: float, size: int, count: int) -> float:
    """Fraction of messages YARP's udp carrier delivers whole over the lossy link."""
    with one_network(link) as (robot, pilot):
        receiver = pilot.start([PYTHON, ROLES, "blob-receiver", "/bench/blob:i"], "blobs in")
        receiver.wait_for("ready", 30)
        link.set_loss(loss)
        sender = robot.start([PYTHON, ROLES, "blob-sender", "/bench/blob:i", str(size),
                              str(count), "2", "udp"], "blobs out")
        sender.wait_for("done", count + 60)
        time.sleep(1)
        link.set_loss(0)
        received = len([line for line in receiver.lines if line.startswith("blob ")])
    return received / count


# -- 3: latency ----------------------------------------------------------------------------

LATENCY_CONFIG = """<bridge period="0.5" gather="0.4">
  <modules><module name="lat" id="9"/></modules>
</bridge>"""


def latencies(proc) -> List[float]:
    return [float(line.split()[1]) for line in proc.lines if line.startswith("latency_ms ")]


def latency_bridge(link: EmulatedLink, count: int, *extra: str) -> List[float]:
    with bridged(link, LATENCY_CONFIG) as pcs:
        receiver = pcs.robot.python(ROLES, "ping-receiver", "/lat/command:i", name="pong")
        receiver.wait_for("ready", 30)
        pcs.start_bridge(pcs.robot, *extra)
        pcs.start_bridge(pcs.pilot, *extra)
        pcs.wait_linked(60)
        time.sleep(2)
        sender = pcs.pilot.python(ROLES, "ping-sender", "/lat/command:i", str(count), "20",
                                  name="ping")
        sender.wait_for("done", count / 20 + 60)
        wait_until(lambda: len(latencies(receiver)) >= count, 30, message="pings")
        return latencies(receiver)


def latency_direct(link: EmulatedLink, count: int) -> List[float]:
    with one_network(link) as (robot, pilot):
        receiver = robot.start([PYTHON, ROLES, "ping-receiver", "/direct/command:i"], "pong")
        receiver.wait_for("ready", 30)
        sender = pilot.start([PYTHON, ROLES, "ping-sender", "/direct/command:i", str(count),
                              "20"], "ping")
        sender.wait_for("done", count / 20 + 60)
        wait_until(lambda: len(latencies(receiver)) >= count * 0.99, 30, message="pings")
        return latencies(receiver)


def percentile(values: List[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


# -- 4: all 256 ids -----------------------------------------------------------------------

def resident_mib(pid: int) -> float:
    return sum((usage(one) or (0, 0))[0] for one in [pid, *descendants(pid)]) / 1024


def many_ids(link: EmulatedLink, modules: int, count: int, duration: float) -> Dict[str, float]:
    config = ('<bridge period="0.5" gather="0.4"><modules>' +
              "".join(f'<module name="m{i}" id="{i}"/>' for i in range(modules)) +
              "</modules></bridge>")
    last = f"/m{modules - 1}/command:i"
    with bridged(link, config) as pcs:
        pcs.robot.python(ROLES, "statuses", str(modules), "1", name="statuses").wait_for(
            "ready", 120)
        receiver = pcs.robot.python(ROLES, "ping-receiver", last, name="pong")
        receiver.wait_for("ready", 30)
        started, phases = {}, {}
        for side in (pcs.robot, pcs.pilot):
            t0 = time.monotonic()
            pcs.start_bridge(side, wait=False)
            ready = side.bridge.wait_for(r"side ready.*opened in ([\d.]+) s.* in ([\d.]+) s", 300)
            started[side.name] = time.monotonic() - t0
            phases[side.name] = (float(ready.group(1)), float(ready.group(2)))
        pcs.wait_linked(120)
        time.sleep(10)
        pids = {side.name: side.bridge.popen.pid for side in (pcs.robot, pcs.pilot)}
        pids["robot server"] = pcs.robot.world.server.popen.pid
        cpu_before = {name: cpu_seconds(pid) for name, pid in pids.items()}
        bytes_before = status_numbers(pcs, pcs.robot)["bytes_out"]
        time.sleep(duration)
        cpu = {name: (cpu_seconds(pid) - cpu_before[name]) / duration * 100
               for name, pid in pids.items()}
        bits = (status_numbers(pcs, pcs.robot)["bytes_out"] - bytes_before) * 8 / duration
        memory = {name: resident_mib(pid) for name, pid in pids.items()}
        sender = pcs.pilot.python(ROLES, "ping-sender", last, str(count), "20", name="ping")
        sender.wait_for("done", count / 20 + 120)
        wait_until(lambda: len(latencies(receiver)) >= count, 60, message="pings")
        through = latencies(receiver)
    return {"ready robot": started["robot"], "ready pilot": started["pilot"],
            "open robot": phases["robot"][0], "connect robot": phases["robot"][1],
            "open pilot": phases["pilot"][0], "connect pilot": phases["pilot"][1],
            "cpu robot": cpu["robot"], "cpu pilot": cpu["pilot"],
            "cpu robot server": cpu["robot server"],
            "mib robot": memory["robot"], "mib pilot": memory["pilot"], "bits": bits,
            "median": statistics.median(through), "p99": percentile(through, 0.99)}


# -- 5: presence ---------------------------------------------------------------------------


def each_profile(link: EmulatedLink) -> Iterator[str]:
    """The lab profile, then drc at 5 % loss, applied to the link in turn; yields the label."""
    for profile, loss in (("lab", 0.0), ("drc", 5.0)):
        link.apply(profile, loss=loss)
        yield f"{profile} ({loss:g} % loss)"


PRESENCE_CONFIG = """<bridge period="0.5" gather="0.4">
  <modules><module name="pm" id="9"/></modules>
</bridge>"""


def presence_delays(cycler, watcher) -> Tuple[List[float], List[float]]:
    """(appear, disappear) delays in ms: each ``opened``/``closed`` of the cycler against the
    watcher's next ``shown``/``gone``."""
    def times(proc, word: str) -> List[float]:
        return [float(line.split()[1]) for line in proc.lines if line.startswith(word + " ")]

    def pair(starts: List[float], seen: List[float]) -> List[float]:
        """Each start with the first sighting after it and before the next start (a round
        the watcher missed has no delay, rather than the next round's)."""
        out = []
        for start, end in zip(starts, [*starts[1:], float("inf")]):
            within = [t for t in seen if start <= t < end]
            if within:
                out.append((within[0] - start) * 1000)
        return out

    return (pair(times(cycler, "opened"), times(watcher, "shown")),
            pair(times(cycler, "closed"), times(watcher, "gone")))


def presence(link: EmulatedLink, rounds: int, bridge: bool) -> Tuple[List[float], List[float]]:
    cycle = [ROLES, "module-cycle", "pm", str(rounds), "3", "3"]
    # The last of the four the bridge opens and closes: all are shown (gone) once it is.
    watch = [ROLES, "port-watch", "/pm/warning:o"]
    if bridge:
        with bridged(link, PRESENCE_CONFIG) as pcs:
            pcs.start_bridge(pcs.robot)
            pcs.start_bridge(pcs.pilot)
            pcs.wait_linked(60)
            watcher = pcs.pilot.python(*watch, name="watch")
            watcher.wait_for("ready", 30)
            cycler = pcs.robot.python(*cycle, name="module")
            cycler.wait_for("done", rounds * 6 + 60)
            time.sleep(2)
            return presence_delays(cycler, watcher)
    with one_network(link) as (robot, pilot):
        watcher = pilot.start([PYTHON, *watch], "watch")
        watcher.wait_for("ready", 30)
        cycler = robot.start([PYTHON, *cycle], "module")
        cycler.wait_for("done", rounds * 6 + 60)
        time.sleep(2)
        return presence_delays(cycler, watcher)


# -- 6: the pilot's loop --------------------------------------------------------------------

LOOP_CONFIG = """<bridge period="0.5" gather="0.4">
  <modules><module name="counter" id="3"/></modules>{copies}
</bridge>"""
#: the command and the status answering it also as two datagrams each (bridge/transport/copies.py)
LOOP_COPIES = '\n  <datagram_copies commands="2" statuses="2"/>'
COUNTER = ["-m", "walkman.gym.supervisor", "witness", "--name", "/counter"]


def loop_times(probe) -> Tuple[List[float], int]:
    values = [float(line.split()[1]) for line in probe.lines if line.startswith("loop_ms ")]
    return values, sum(line.startswith("lost ") for line in probe.lines)


def pilot_loop(link: EmulatedLink, count: int, rate: float,
               bridge: bool, copies: bool = False) -> Tuple[List[float], int]:
    probe_argv = [ROLES, "loop-probe", "counter", str(count), str(rate)]
    timeout = count / rate * 3 + 120
    if bridge:
        with bridged(link, LOOP_CONFIG.format(copies=LOOP_COPIES if copies else "")) as pcs:
            pcs.robot.python(*COUNTER, name="counter").wait_for("ready for the pilot", 60)
            pcs.start_bridge(pcs.robot)
            pcs.start_bridge(pcs.pilot)
            pcs.wait_linked(60)
            probe = pcs.pilot.python(*probe_argv, name="probe")
            probe.wait_for("done", timeout)
            return loop_times(probe)
    with one_network(link) as (robot, pilot):
        env = robot.env
        env["PYTHONPATH"] = os.pathsep.join([str(TEST_HELPERS), str(ROOT),
                                             env.get("PYTHONPATH", "")])
        env["COUNTER_LOG"] = str(robot.root / "executed.log")
        robot.start([PYTHON, *COUNTER], "counter", env=env).wait_for("ready for the pilot", 60)
        probe = pilot.start([PYTHON, *probe_argv], "probe")
        probe.wait_for("done", timeout)
        return loop_times(probe)


# -- main ----------------------------------------------------------------------------------


def _bench_1(link: EmulatedLink, options: argparse.Namespace) -> None:
    """Table 1's workload: the bridge's bit/s against YARP tcp's, still and moving."""
    duration = 15 if options.quick else 40
    say(f"\n1. Table 1 workload, robot -> pilot, T = 1 s ({duration:.0f} s per run)")
    say("   bridge: its frames' payload and framing (its counters), then on the cable "
        "(veth, TCP/IP without Ethernet); YARP tcp: the same messages once a second, "
        "direct, on the cable")
    say(f"   {'robot':<8} {'payload':>9} {'framing':>9} {'total':>9} "
        f"{'+TCP/IP':>9} {'packets/s':>9} {'YARP tcp':>9} {'packets/s':>9}   (bit/s)")
    link.apply("lab")
    for mode in ("still", "moving"):
        figures = table_1(link, mode, duration)
        direct = direct_table_1(link, mode, duration)
        say(f"   {mode:<8} {figures['payload']:>9.0f} {figures['framing']:>9.0f} "
            f"{figures['total']:>9.0f} {figures['with_tcp_ip']:>9.0f} "
            f"{figures['packets']:>9.1f} {direct['with_tcp_ip']:>9.0f} "
            f"{direct['packets']:>9.1f}")
    say(f"   paper Table 1 (no TCP/IP): {PAPER_TABLE_1} bit/s; goal <= 1200")


def _bench_2(link: EmulatedLink, options: argparse.Namespace) -> None:
    """Perception's completeness through loss: plain, fixed FEC, adaptive FEC, YARP udp."""
    frames = 20 if options.quick else 40
    say(f"\n2. Completeness at delta-t 0.4 s, 320x240 image + 80x60 cloud at 2 Hz, "
        f"{frames} frames each")
    say("   FEC 0.3: a fixed repair fraction; auto: sized from the loss the receiver "
        "reports (repairs per frame, image/cloud)")
    say(f"   {'loss':>5} {'limit':>6} {'image':>7} {'cloud':>7} {'img 0.3':>8} "
        f"{'cld 0.3':>8} {'img auto':>8} {'cld auto':>8} {'repairs':>9} "
        f"{'YARP udp img':>13} {'YARP udp cld':>13}")
    link.apply("lab")
    for loss in (int(x) for x in options.losses.split(",")):
        plain = completeness(link, loss, 0.0, frames)
        repaired = completeness(link, loss, 0.3, frames)
        auto = completeness(link, loss, "auto", frames)
        image_base = whole_message_baseline(link, loss, IMAGE_BYTES, frames)
        cloud_base = whole_message_baseline(link, loss, CLOUD_BYTES, frames)
        repairs = f"{auto['image repairs']:.0f}/{auto['cloud repairs']:.0f}"
        say(f"   {loss:>4}% {1 - loss / 100:>6.2f} {plain['image']:>7.3f} "
            f"{plain['cloud']:>7.3f} {repaired['image']:>8.3f} "
            f"{repaired['cloud']:>8.3f} {auto['image']:>8.3f} {auto['cloud']:>8.3f} "
            f"{repairs:>9} {image_base:>13.3f} {cloud_base:>13.3f}")


def _bench_3(link: EmulatedLink, options: argparse.Namespace) -> None:
    """A pilot command's one-way latency through the bridge and direct, per profile."""
    count = 200 if options.quick else 600
    say(f"\n3. Pilot command latency, one way ({count} commands at 20 Hz), ms")
    say(f"   {'profile':<22} {'bridge med':>10} {'bridge p99':>10} {'direct med':>10} "
        f"{'direct p99':>10}")
    for profile, loss, extra in (("lab", 0.0, ()), ("lab", 0.0, ("--fsync",)),
                                 ("drc", 0.0, ()), ("drc", 5.0, ())):
        link.apply(profile, loss=loss)
        through = latency_bridge(link, count, *extra)
        direct = latency_direct(link, count)
        label = f"{profile} ({loss:g} % loss){' --fsync' if extra else ''}"
        say(f"   {label:<22} {statistics.median(through):>10.2f} "
            f"{percentile(through, 0.99):>10.2f} {statistics.median(direct):>10.2f} "
            f"{percentile(direct, 0.99):>10.2f}")


def _bench_4(link: EmulatedLink, options: argparse.Namespace) -> None:
    """All 256 ids in use beside 8 modules: start-up, CPU, memory, command latency."""
    count, duration = (100, 10) if options.quick else (400, 30)
    say(f"\n4. All 256 ids in use (lab): 8 modules beside 256 (4 flows each), every "
        f"status once a second; CPU over {duration} s linked, {count} commands to the "
        f"last id")
    say(f"   {'modules':>7} {'ready s':>13} {'open s':>11} {'connect s':>11} "
        f"{'CPU %':>11} {'server %':>8} {'RSS MiB':>11} {'bit/s':>8} {'cmd med ms':>10} "
        f"{'p99':>7}   (robot/pilot; server: the robot's name server)")
    link.apply("lab")
    for modules in (8, 256, 8, 256):  # interleaved: each size twice
        f = many_ids(link, modules, count, duration)
        say(f"   {modules:>7} {f['ready robot']:>6.1f}/{f['ready pilot']:<6.1f} "
            f"{f['open robot']:>5.1f}/{f['open pilot']:<5.1f} "
            f"{f['connect robot']:>5.1f}/{f['connect pilot']:<5.1f} "
            f"{f['cpu robot']:>5.1f}/{f['cpu pilot']:<5.1f} "
            f"{f['cpu robot server']:>8.1f} "
            f"{f['mib robot']:>5.0f}/{f['mib pilot']:<5.0f} {f['bits']:>8.0f} "
            f"{f['median']:>10.2f} {f['p99']:>7.2f}")


def _bench_5(link: EmulatedLink, options: argparse.Namespace) -> None:
    """Presence: how soon the pilot's name server shows a module's ports come and go."""
    rounds = 5 if options.quick else 15
    say(f"\n5. Presence: a module's ports opened and closed on the robot ({rounds} "
        f"rounds, 3 s each way) until the pilot's name server shows them / stops, ms")
    say(f"   {'profile':<16} {'appear med':>10} {'max':>7} {'leave med':>10} {'max':>7}"
        f" {'1 server: appear':>17} {'leave':>7}")
    for label in each_profile(link):
        appear, leave = presence(link, rounds, bridge=True)
        appear_1, leave_1 = presence(link, rounds, bridge=False)
        if min(len(appear), len(leave)) < rounds:
            say(f"   {label}: the pilot saw {len(appear)} of {rounds} appearances "
                f"and {len(leave)} departures")
        if not appear or not leave:
            continue
        say(f"   {label:<16} {statistics.median(appear):>10.0f} "
            f"{max(appear):>7.0f} {statistics.median(leave):>10.0f} {max(leave):>7.0f}"
            f" {statistics.median(appear_1):>17.0f} {statistics.median(leave_1):>7.0f}")


def _bench_6(link: EmulatedLink, options: argparse.Namespace) -> None:
    """The pilot's loop: a command to the module's status answering it, per profile."""
    count = 100 if options.quick else 400
    say(f"\n6. The pilot's loop: command -> the module's status answering it, at the "
        f"pilot ({count} commands at 4 Hz), ms")
    say("   bridge: TCP only; + copies: commands and answering statuses also as two "
        "datagrams each")
    say(f"   {'profile':<16} {'bridge med':>10} {'p99':>7} {'lost':>5} "
        f"{'+ copies med':>12} {'p99':>7} {'lost':>5} "
        f"{'1 server med':>12} {'p99':>7} {'lost':>5}")
    for label in each_profile(link):
        through, lost = pilot_loop(link, count, 4.0, bridge=True)
        copied, lost_c = pilot_loop(link, count, 4.0, bridge=True, copies=True)
        direct, lost_1 = pilot_loop(link, count, 4.0, bridge=False)
        say(f"   {label:<16} {statistics.median(through):>10.1f} "
            f"{percentile(through, 0.99):>7.1f} {lost:>5} "
            f"{statistics.median(copied):>12.1f} {percentile(copied, 0.99):>7.1f} "
            f"{lost_c:>5} "
            f"{statistics.median(direct):>12.1f} {percentile(direct, 0.99):>7.1f} "
            f"{lost_1:>5}")
    say("   goal on drc: median <= 100 ms + the radio's round trip; with copies, "
        "p99 close to the median")


#: The benchmarks by number (``--only``).
BENCHES = {1: _bench_1, 2: _bench_2, 3: _bench_3, 4: _bench_4, 5: _bench_5, 6: _bench_6}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs (noisier figures)")
    parser.add_argument("--only", default="1,2,3,4,5,6",
                        help="which benchmarks (default 1,2,3,4,5,6)")
    parser.add_argument("--losses", default="0,5,10,20,30",
                        help="loss percentages of benchmark 2 (default 0,5,10,20,30)")
    options = parser.parse_args()
    try:
        only = {int(x) for x in options.only.split(",")}
    except ValueError:
        parser.error(f"--only takes benchmark numbers separated by commas, not {options.only!r}")
    if only - BENCHES.keys():
        parser.error(f"--only: no benchmark {', '.join(map(str, sorted(only - BENCHES.keys())))}"
                     f"; they are {', '.join(map(str, BENCHES))}")
    say_machine()
    reason = emulation.available()
    if reason:
        say(f"bench_bridge: {reason}")
        return 1
    link = EmulatedLink("wb", 41)
    link.up()
    try:
        for number in sorted(only):
            BENCHES[number](link, options)
    finally:
        link.down()
    return 0


if __name__ == "__main__":
    sys.exit(main())
