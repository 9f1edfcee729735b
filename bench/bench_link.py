#!/usr/bin/env python3
"""The emulated link itself, per profile (needs root): what a packet meets between the PCs.

1. **One-way latency of a small datagram**, robot -> pilot: a 58-byte payload (a 100-byte
   Ethernet frame), sent one at a time with room between them so none waits for another;
   both hosts read the same monotonic clock.  Min, median, p99 and how many were lost,
   against the floor the profile promises (airtime + one-way delay).
2. **Throughput**: one TCP stream robot -> pilot; payload bits per second from the
   sender's connect to the last byte read, and what the radio dropped meanwhile (its
   buffer's tail, its loss).

Profiles: lab, drc without loss, drc (5 % loss), degraded.  Runs against whichever
``netem.emulation`` is beside it, so the same script measures an older checkout too (the
radio's counters and floor are shown when it has them).

Usage: ``.venv/bin/python bench/bench_link.py [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path
from typing import Dict, List, Optional, Tuple

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from netem import emulation  # noqa: E402
from netem.emulation import EmulatedLink  # noqa: E402
from system.processes import Proc  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)

PYTHON = sys.executable
PROBE = str(ROOT / "tests" / "bridge" / "link_probe.py")
PORT = 9000
FRAME = 100
HEADERS = 42                       # UDP, IPv4, Ethernet
#: (label, profile, loss override, payload bytes of the TCP stream, datagrams spacing s)
ROWS = (("lab", "lab", None, 200_000_000, 0.02),
        ("drc, no loss", "drc", 0.0, 1_000_000, 0.05),
        ("drc (5 % loss)", "drc", None, 1_000_000, 0.05),
        ("degraded", "degraded", None, 12_000, 0.3))


def say(text: str) -> None:
    print(text, flush=True)


def probe(link: EmulatedLink, host: str, *args: str) -> Proc:
    return Proc(link.exec_argv(host, [PYTHON, PROBE, *args]), dict(os.environ),
                f"{host} {args[0]}")


def stamps(proc: Proc, word: str) -> Dict[int, float]:
    return {int(line.split()[1]): float(line.split()[-1]) for line in proc.lines
            if line.startswith(word + " ")}


def percentile(values: List[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def radio(link: EmulatedLink) -> Optional[Dict]:
    """The radio stage's status; None on a checkout that has none (tc tbf + nftables)."""
    return link.status() if hasattr(link, "status") else None


def one_way(link: EmulatedLink, count: int, gap: float) -> Tuple[List[float], int]:
    """One-way delays (ms) of ``count`` small datagrams, and how many never arrived."""
    receiver = probe(link, "pilot", "receive", link.address("pilot"), str(PORT))
    try:
        receiver.wait_for("^listening$", 20)
        # The robot learns the pilot's MAC first (retried: ARP is lost like anything else).
        for attempt in range(20):
            probe(link, "robot", "send", link.address("pilot"), str(PORT), "8", "1", "0",
                  str(10_000 + attempt)).wait(30)
            try:
                receiver.wait_for(r"^got 100\d\d ", 3)
                break
            except AssertionError:
                continue
        sender = probe(link, "robot", "send", link.address("pilot"), str(PORT),
                       str(FRAME - HEADERS), str(count), str(gap))
        sender.wait(count * gap + 120)
        sender.wait_for("^done$", 10)
        sent = stamps(sender, "sent")
        # The last one's time on the link is at most a few seconds, even on degraded.
        try:
            receiver.wait_for(rf"^got {count - 1} ", 10)
        except AssertionError:
            pass  # lost; the others are counted as they are
        got = stamps(receiver, "got")
    finally:
        receiver.kill()
    delays = [(got[seq] - sent[seq]) * 1000 for seq in sent if seq in got]
    return delays, len(sent) - len(delays)


def throughput(link: EmulatedLink, total: int) -> float:
    """Payload bit/s of one TCP stream of ``total`` bytes, connect to last byte."""
    sink = probe(link, "pilot", "sink", link.address("pilot"), str(PORT + 1), str(total))
    try:
        sink.wait_for("^listening$", 20)
        source = probe(link, "robot", "source", link.address("pilot"), str(PORT + 1),
                       str(total))
        source.wait(3600)
        last = sink.wait_for(r"^last ([\d.]+) (\d+)", 60)
        start = float(source.wait_for(r"^start ([\d.]+)").group(1))
    finally:
        sink.kill()
    return int(last.group(2)) * 8 / (float(last.group(1)) - start)


def floor_ms(link: EmulatedLink) -> str:
    status = radio(link)
    if status is None:
        return "-"
    settings = status["settings"]
    airtime = FRAME * 8 / settings["rate"] if settings["rate"] else 0.0
    return f"{(airtime + settings['delay']) * 1000:.1f}"


def dropped(before: Optional[Dict], after: Optional[Dict]) -> str:
    if before is None or after is None:
        return "-"
    out = []
    for direction in ("robot_to_pilot", "pilot_to_robot"):
        b, a = before["counters"][direction], after["counters"][direction]
        out.append(f"{a['queue_full'] - b['queue_full']}/{a['loss'] - b['loss']}")
    return " ".join(out)


def human_rate(bits: float) -> str:
    for scale, unit in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if bits >= scale:
            return f"{bits / scale:.3g} {unit}bit/s"
    return f"{bits:.0f} bit/s"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer datagrams, shorter streams")
    options = parser.parse_args()
    say_machine()
    reason = emulation.available()
    if reason:
        say(f"bench_link: {reason}")
        return 1
    count = 20 if options.quick else 60
    say(f"emulation: {Path(emulation.__file__).resolve()}")
    say(f"\n1. One-way latency, robot -> pilot, {count} datagrams of {FRAME - HEADERS} bytes "
        f"({FRAME}-byte frames), one at a time; ms")
    say("2. Throughput: one TCP stream robot -> pilot, payload bit/s from connect to the last "
        "byte; dropped: the radio's buffer tail / loss, robot->pilot then pilot->robot\n")
    say(f"   {'profile':<16} {'floor':>6} {'min':>7} {'median':>7} {'p99':>7} {'lost':>5}   "
        f"{'stream':>8} {'throughput':>14} {'dropped':>14}")
    link = EmulatedLink("wl", 43)
    link.up()
    try:
        for label, profile, loss, total, gap in ROWS:
            link.apply(profile, loss=loss)
            delays, lost = one_way(link, count, gap)
            before = radio(link)
            total = total // 4 if options.quick else total
            bits = throughput(link, total)
            after = radio(link)
            say(f"   {label:<16} {floor_ms(link):>6} {min(delays):>7.2f} "
                f"{statistics.median(delays):>7.2f} {percentile(delays, 0.99):>7.2f} "
                f"{lost:>5}   {total / 1000:>6.0f}kB {human_rate(bits):>14} "
                f"{dropped(before, after):>14}")
    finally:
        link.down()
    say_machine("after")
    return 0


if __name__ == "__main__":
    sys.exit(main())
