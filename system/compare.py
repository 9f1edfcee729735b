"""``walkman-compare``: one pilot session in the lab topology and in the DRC topology, compared.

Theory of operation
-------------------
The same scripted session (:mod:`system.session`) runs twice: ``lab`` (one
name-server pair, direct connections) and ``drc`` (two pairs and the bridge,
on the emulated network with a link profile when run as root, else on
loopback).  For each run we keep what the pilot side could observe (ports,
topics, services: :func:`system.topology.observe_here`), what it received and
when, and what the robot's modules executed.  The analysis is pure functions
over those records; the report is Markdown with PNG plots.

The verdict is about what processes can observe.  The pilot's *contract* --
the ports and topics the pilot-side programs use (:data:`CONTRACT_TOPICS`,
:data:`CONTRACT_PORTS`) -- must exist with the same types in both topologies,
every session step must have its effect, and the robot must execute the same
commands in the same order.  Latency, rates and completeness are measured and
reported as degradation, not as failure.  Names only the lab shows (robot
internals the configuration does not bridge) and the bridge's own names in the
DRC topology are listed as expected; any other name only the DRC topology shows
is a difference (the bridge shows a module's ports on the pilot side only while
the module runs on the robot: :mod:`bridge.gym.presence`).
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import re
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

from system.session import CANCELLED_COMMAND, MODULES, SessionRecord
from system.session import run as run_session
from system.topology import BRIDGE_CONFIG, REPO, Topology, add_link_arguments
from walkman.gym.interfaces import GYM_PORTS

CONTRACT_TOPICS = {
    "/gaze_control/status": "walkman_msgs/Status", "/gaze_control/switch": "walkman_msgs/Switch",
    "/gaze_control/command": "walkman_msgs/Command",
    "/gaze_control/warning": "walkman_msgs/Warning",
    "/gaze_control/countdown": "walkman_msgs/Countdown",
    "/temperature/status": "walkman_msgs/Status", "/temperature/switch": "walkman_msgs/Switch",
    "/pilot/sent_commands": "walkman_msgs/SentCommand",
    "/joint_states": "sensor_msgs/JointState", "/tf": "tf2_msgs/TFMessage",
    "/multisense/left/image_color": "sensor_msgs/Image",
    "/multisense/points": "sensor_msgs/PointCloud2",
    "/multisense/left/camera_info": "sensor_msgs/CameraInfo",
}
CONTRACT_PORTS = [port.of(m) for m in MODULES for port in GYM_PORTS] + \
    ["/walkman/rpc:i"] + [f"/walkman/{chain}/stateSI:o" for chain in
                          ("torso", "head", "left_arm", "right_arm", "left_leg", "right_leg",
                           "left_hand", "right_hand")]
CONTRACT_SERVICES = [f"/{m}/{s}" for m in MODULES
                     for s in ("switch_and_wait", "send_command", "get_status")]
PAPER_TABLE_1_BITS = 2400


# -- analysis (pure) ------------------------------------------------------------------------


def contract(observed: dict) -> Dict[str, str]:
    """For each contract name: its type (topics), "present", or "missing"."""
    out = {}
    for topic, kind in CONTRACT_TOPICS.items():
        entry = observed["topics"].get(topic)
        if entry is None or not entry["pub"] and not entry["sub"]:
            out[topic] = "missing"
        elif entry["type"] != kind:
            out[topic] = f"type {entry['type']}"
        elif topic.endswith(("/switch", "/command")):
            out[topic] = kind if entry["sub"] else "nobody listens"
        else:
            out[topic] = kind if entry["pub"] else "nobody publishes"
    for port in CONTRACT_PORTS:
        out[port] = "present" if port in observed["ports"] else "missing"
    for service in CONTRACT_SERVICES:
        out[service] = "present" if service in observed["services"] else "missing"
    return out


#: Names the pilot's bridge has whatever runs: its status and rpc ports, its ROS node's
#: services, and the session's reader of its status.
BRIDGE_OWN_PREFIXES = ("/bridge/pilot/", "/walkman_bridge_pilot/", "/session/bridge/")
#: The port a gateway reads the pilot bridge's status on (``--link bridge``), for /bridge/link,
#: as observed: :func:`system.topology.normalize` has made its pid ``N``.
GATEWAY_LINK_PORT = re.compile(r"^/pilot_gateway/(\d+|N)/bridge:i$")
DRC_ONLY = "drc only, the bridge's own"


def bridge_own_ports(config: Path = BRIDGE_CONFIG) -> List[str]:
    """The ports the configuration has the pilot's bridge open for pilot programs to connect
    to (a custom connection's ``port_to_open``), which no lab program opens."""
    from bridge.config import PILOT, load
    from bridge.gym.presence import stand_ins

    loaded = load(config)
    shown = stand_ins(loaded, PILOT)
    return sorted(c.opened_on(PILOT) for c in loaded.channels
                  if c.middleware == "yarp" and c.key not in shown)


def bridge_own_names(config: Path = BRIDGE_CONFIG) -> List[str]:
    """Every name only a bridged topology has by design: :func:`bridge_own_ports` and the
    pilot bridge's arrival report beside each image and cloud (``<topic>/arrived``)."""
    from bridge.config import PILOT, load
    from bridge.endpoints.ros import arrival_topic

    loaded = load(config)
    arrivals = [arrival_topic(c.label) for c in loaded.channels
                if c.middleware == "ros" and c.destination == PILOT and
                c.ros_type in ("sensor_msgs/Image", "sensor_msgs/PointCloud2")]
    return bridge_own_ports(config) + sorted(arrivals)


def extras(lab: dict, drc: dict, own_ports: Sequence[str] = ()) -> Dict[str, List[str]]:
    """Names one topology shows and the other does not, outside the contract."""
    names = lambda o: set(o["ports"]) | set(o["topics"]) | set(o["services"])  # noqa: E731
    contract_names = set(CONTRACT_TOPICS) | set(CONTRACT_PORTS) | set(CONTRACT_SERVICES)
    drc_only = names(drc) - names(lab) - contract_names
    own = {n for n in drc_only if n.startswith(BRIDGE_OWN_PREFIXES) or n in own_ports or
           GATEWAY_LINK_PORT.match(n)}
    return {"lab only": sorted(names(lab) - names(drc) - contract_names),
            DRC_ONLY: sorted(own), "drc only": sorted(drc_only - own)}


def window(record: SessionRecord) -> Tuple[float, float]:
    if not record.steps:
        return record.started, record.ended
    return record.steps[0]["start"], record.steps[-1]["end"]


def rates(record: SessionRecord) -> Dict[str, float]:
    start, end = window(record)
    span = max(end - start, 1e-6)
    counts: Dict[str, int] = {}
    for r in record.records:
        if start <= r["t"] <= end:
            counts[r["topic"]] = counts.get(r["topic"], 0) + 1
    return {topic: count / span for topic, count in sorted(counts.items())}


#: The receipts that end a command's trip: the module took it (or said why not).
ANSWERED = ("accepted", "refused")


class CommandLatency(NamedTuple):
    """One command the gateway sent: until the module answered it (s), or why no figure."""

    name: str
    seconds: Optional[float]
    why_none: str = ""

    def shown(self) -> str:
        return f"{self.seconds * 1000:.0f}" if self.seconds is not None else self.why_none


def command_latencies(record: SessionRecord) -> List[CommandLatency]:
    """For each command the gateway sent: the time until the module's receipt for *that*
    command (by module, port and sequence number) said accepted or refused.

    Both ends are the gateway's own stamps (``/pilot/sent_commands``, taken before the
    send; ``/pilot/command_states``), one clock, not when the recorder heard of them: ROS
    does not order messages across topics.  A command with no such receipt gets no figure.
    """
    answers: Dict[Tuple[str, str, int], float] = {}
    for r in record.records:
        if r["topic"] == "/pilot/command_states" and r.get("state") in ANSWERED:
            key = (r["module"], r["port"], r["seq"])
            answers[key] = min(answers.get(key, math.inf), r["stamp"])
    out = []
    for sent in sorted((r for r in record.records if r["topic"] == "/pilot/sent_commands"),
                       key=lambda r: r["stamp"]):
        name = f"{sent['module']} {sent['text']}"
        answered = answers.get((sent["module"], sent.get("port", ""), sent.get("seq", 0)))
        if answered is None:
            out.append(CommandLatency(name, None, "no receipt"))
        elif answered < sent["stamp"]:
            out.append(CommandLatency(name, None, "answered before its stamp"))
        else:
            out.append(CommandLatency(name, answered - sent["stamp"]))
    return out


LatencyRow = Tuple[str, Optional[CommandLatency], Optional[CommandLatency]]


def paired_latencies(lab: List[CommandLatency], drc: List[CommandLatency]) -> List[LatencyRow]:
    """The two runs' commands side by side: the n-th sending of a command (its words,
    without the run's own sequence number) beside the n-th sending of the same words in the
    other run, in the order they were sent; a command only one run sent has its row, the
    other side None.  Zipping the lists in order paired fc140's commands one row off when
    the lab's recorder missed the first."""
    def keys(latencies: List[CommandLatency]) -> List[Tuple[str, int]]:
        seen: Dict[str, int] = {}
        out = []
        for latency in latencies:
            words = command_words(latency.name)
            seen[words] = seen.get(words, 0) + 1
            out.append((words, seen[words]))
        return out

    lab_keys, drc_keys = keys(lab), keys(drc)
    rows: List[LatencyRow] = []
    matcher = difflib.SequenceMatcher(a=lab_keys, b=drc_keys, autojunk=False)
    for tag, i1, i2, j1, j2 in matcher.get_opcodes():
        if tag == "equal":
            rows += [(lab_keys[i][0], lab[i], drc[j]) for i, j in zip(range(i1, i2),
                                                                      range(j1, j2))]
        else:
            rows += [(lab_keys[i][0], lab[i], None) for i in range(i1, i2)]
            rows += [(drc_keys[j][0], None, drc[j]) for j in range(j1, j2)]
    return rows


def command_words(name: str) -> str:
    """A command's module and words without the sequence number the gateway gave it."""
    head, _, last = name.rpartition(" ")
    return head if head and last.isdigit() else name


def valid_points(record: SessionRecord) -> List[Tuple[float, float]]:
    """(time, share of the cloud's points that are valid) per cloud the pilot received.

    The scene itself leaves some points invalid (sky, out of range), so this is
    plotted next to the lab's series; the bridge's own count of what arrived is
    :attr:`SessionRecord.completeness`.
    """
    return [(r["t"], 1.0 - r["nan"]) for r in record.records if r["topic"] == "/multisense/points"]


def bandwidth_by_id(record: SessionRecord, window_s: float = 5.0
                    ) -> Dict[int, List[Tuple[float, float]]]:
    """Bits per second per 8-bit id (TCP and UDP), averaged over ``window_s``.

    Perception frames come about once a second, so a shorter window shows the
    frames rather than the bandwidth.
    """
    out: Dict[int, List[Tuple[float, float]]] = {}
    samples = record.bridge_samples
    first = 0
    for b in samples[1:]:
        while first < len(samples) - 1 and b["t"] - samples[first + 1]["t"] >= window_s:
            first += 1
        a = samples[first]
        if a is b:
            continue
        dt = max(b["t"] - a["t"], 1e-3)
        for table in ("tcp_by_id", "udp_by_id"):
            for ident, total in b[table].items():
                rate = (total - a[table].get(ident, 0)) * 8 / dt
                out.setdefault(ident, []).append((b["t"] - samples[0]["t"], rate))
    return out


def mean_bandwidth(record: SessionRecord) -> Dict[Tuple[str, int], float]:
    """(channel, id) -> bits per second over the whole session."""
    samples = record.bridge_samples
    if len(samples) < 2:
        return {}
    first, last = samples[0], samples[-1]
    span = max(last["t"] - first["t"], 1e-3)
    out = {}
    for channel in ("tcp", "udp"):
        table = f"{channel}_by_id"
        for ident, total in last[table].items():
            out[(channel, int(ident))] = (total - first[table].get(ident, 0)) * 8 / span
    return out


def id_names(config: Path = BRIDGE_CONFIG) -> Dict[int, str]:
    """What each 8-bit id carries, from the bridge configuration."""
    from bridge.config import load

    names: Dict[int, List[str]] = {}
    loaded = load(config)
    if loaded.robot_state is not None:
        names[loaded.robot_state.id] = [f"robot state ({loaded.robot_state.robot})"]
    for channel in loaded.channels:
        labels = names.setdefault(channel.id, [])
        if channel.label not in labels:
            labels.append(channel.label)
    return {ident: ", ".join(labels) for ident, labels in names.items()}


def verdict(lab: dict, drc: dict, lab_record: SessionRecord,
            drc_record: SessionRecord) -> List[str]:
    """Every difference a process could observe; empty when the topologies agree."""
    problems = [f"{name}: only in the drc topology (not the bridge's own)"
                for name in extras(lab, drc, bridge_own_names())["drc only"]]
    lab_contract, drc_contract = contract(lab), contract(drc)
    for name in lab_contract:
        if lab_contract[name] != drc_contract[name]:
            problems.append(f"{name}: lab {lab_contract[name]}, drc {drc_contract[name]}")
        elif lab_contract[name] in ("missing", "nobody publishes", "nobody listens"):
            problems.append(f"{name}: {lab_contract[name]} in both topologies")
    for record in (lab_record, drc_record):
        for step in record.steps:
            if not step["ok"]:
                problems.append(f"{record.topology}: step '{step['label']}' had no effect")
    module, cancelled = CANCELLED_COMMAND
    for record in (lab_record, drc_record):
        if cancelled in record.executed.get(module, []):
            problems.append(f"{record.topology}: the cancelled '{cancelled}' reached {module}")
    for module in MODULES:
        if lab_record.executed.get(module) != drc_record.executed.get(module):
            problems.append(f"{module} executed {lab_record.executed.get(module)} in the lab, "
                            f"{drc_record.executed.get(module)} through the bridge")
    return problems


# -- running and reporting ------------------------------------------------------------------


def run_one(kind: str, root: Path, link, profile: str, loss: Optional[float],
            progress, bag: Optional[Path] = None) -> Tuple[SessionRecord, dict]:
    """One topology up, the session played, what the pilot saw; its rosbag kept at ``bag``."""
    topology = Topology(kind, root / kind, link=link if kind == "drc" else None,
                        profile=profile, loss=loss)
    try:
        started = time.monotonic()
        progress(f"{kind}: starting the name servers"
                 f"{' on the emulated robot and pilot hosts' if topology.link else ''}")
        topology.start_name_servers()
        progress(f"{kind}: starting {', '.join(topology.table)}")
        topology.start_all()
        topology.wait_ready(240)
        progress(f"{kind}: everything up in {time.monotonic() - started:.0f} s; the pilot "
                 f"session begins")
        record = run_session(topology, progress=lambda text: progress(f"{kind}: {text}"))
        observed = topology.observe(topology.pilot)
        return record, observed
    finally:
        topology.close()
        if bag is not None and topology.bag_path.exists():
            bag.parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(topology.bag_path), bag)


def _save(figure, path: Path) -> str:
    import matplotlib.pyplot as plt

    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path.name


def _plots(out: Path, lab_record: SessionRecord, drc_record: SessionRecord) -> List[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    bandwidth = bandwidth_by_id(drc_record)
    if bandwidth:
        figure, axes = plt.subplots(figsize=(8, 4))
        for ident, series in sorted(bandwidth.items()):
            axes.plot([t for t, _ in series], [r / 1000 for _, r in series], label=f"id {ident}")
        axes.set_xlabel("session time (s)")
        axes.set_yscale("log")
        axes.set_ylabel("kbit/s over 5 s (robot to pilot, no IP headers)")
        axes.set_title("Bridge bandwidth per 8-bit id")
        axes.legend(fontsize=7, ncol=3)
        files.append(_save(figure, out / "bandwidth_by_id.png"))
    figure, axes = plt.subplots(figsize=(8, 4))
    for record, color in ((lab_record, "tab:blue"), (drc_record, "tab:orange")):
        values = [1000 * c.seconds for c in command_latencies(record) if c.seconds is not None]
        if values:
            axes.hist(values, bins=20, alpha=0.6, color=color,
                      label=f"{record.topology} (median {statistics.median(values):.0f} ms)")
    axes.set_xlabel("command sent -> status changed (ms)")
    axes.set_ylabel("commands")
    axes.set_title("Command latency seen by the pilot")
    axes.legend()
    files.append(_save(figure, out / "command_latency.png"))
    figure, axes = plt.subplots(figsize=(8, 4))
    for record, color in ((lab_record, "tab:blue"), (drc_record, "tab:orange")):
        series = valid_points(record)
        if series:
            t0 = series[0][0]
            axes.plot([t - t0 for t, _ in series], [c for _, c in series], ".-", color=color,
                      label=record.topology)
    axes.set_ylim(0, 1.05)
    axes.set_xlabel("session time (s)")
    axes.set_ylabel("valid points in the cloud")
    axes.set_title("Point clouds at the pilot (missing regions arrive as NaN)")
    axes.legend()
    files.append(_save(figure, out / "cloud_completeness.png"))
    return files


#: What the bridge is designed to give each stream at the pilot (the report's last column).
DESIGNED_RATES = {"/joint_states": "1/T = 2 (bridge period 0.5 s)",
                  "/gaze_control/status": "2 a second, and each change (GYM; bridge: "
                                          "latest per T, changes as events)",
                  "/temperature/status": "2 a second, and each change",
                  "/multisense/points": "1 (camera rate)",
                  "/multisense/left/image_color": "1", "/tf": "TF at 10 Hz on new state"}


def report(out: Path, lab: dict, drc: dict, lab_record: SessionRecord,
           drc_record: SessionRecord, profile: str, loss: Optional[float],
           emulated: bool) -> Tuple[str, List[str]]:
    """Write ``report.md``, the plots and ``sessions.json`` into ``out``; the summary a
    user reads on the terminal, and the observable differences (none: the verdict)."""
    out.mkdir(parents=True, exist_ok=True)
    problems = verdict(lab, drc, lab_record, drc_record)
    plots = _plots(out, lab_record, drc_record)
    link = f"{profile} profile{f', {loss:g} % loss' if loss is not None else ''}" \
        if emulated else "loopback (no emulated network: needs root)"
    latency_rows = paired_latencies(command_latencies(lab_record),
                                    command_latencies(drc_record))
    lines = ["# Lab versus DRC topology", "",
             f"Generated {time.strftime('%Y-%m-%d %H:%M:%S')}; DRC link: {link}.", "",
             "**Verdict: " + ("no observable difference**" if not problems else
                              f"{len(problems)} observable difference(s)**"), ""]
    lines += [f"* {p}" for p in problems]
    lines += _observable_section(lab, drc) + _session_section(lab_record, drc_record)
    lines += _latency_section(latency_rows) + _link_section(drc_record)
    bags = [name for name in ("lab.bag", "drc.bag") if (out / name).exists()]
    if bags:
        lines += ["", "## Recordings", "", "What the pilot's roscore carried, for `rosbag info` "
                  "and `rosbag play`: " + ", ".join(f"`{name}`" for name in bags) + "."]
    lines += ["", "## Plots", ""] + [f"![{p}]({p})" for p in plots]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "sessions.json").write_text(json.dumps(
        {"lab": asdict(lab_record), "drc": asdict(drc_record), "observed_lab": lab,
         "observed_drc": drc}, default=str))
    return _summary(problems, latency_rows, lab_record, drc_record), problems


def _observable_section(lab: dict, drc: dict) -> List[str]:
    """What the pilot can observe in each topology, and the differences expected."""
    lines = ["", "## What the pilot can observe", "", "| name | lab | drc |", "|---|---|---|"]
    lab_contract, drc_contract = contract(lab), contract(drc)
    lines += [f"| `{name}` | {lab_contract[name]} | {drc_contract[name]} |"
              for name in lab_contract]
    for title, names in extras(lab, drc, bridge_own_names()).items():
        lines += ["", f"Expected differences, {title} ({len(names)}): " +
                  (", ".join(f"`{n}`" for n in names[:60]) or "none") +
                  (" ..." if len(names) > 60 else "")]
    return lines


def _session_section(lab_record: SessionRecord, drc_record: SessionRecord) -> List[str]:
    """The session's steps, the commands the robot ran, the streams' rates."""
    lines = ["", "## The session", "", "| step | lab (s) | drc (s) |", "|---|---|---|"]
    for a, b in zip(lab_record.steps, drc_record.steps):
        mark = lambda s: f"{s['end'] - s['start']:.1f}" + ("" if s["ok"] else " FAILED")  # noqa
        lines.append(f"| {a['label']} | {mark(a)} | {mark(b)} |")
    lines += ["", "## Commands executed on the robot, in order", ""]
    for module in MODULES:
        same = lab_record.executed.get(module) == drc_record.executed.get(module)
        lines.append(f"* `{module}` ({'same' if same else 'DIFFERENT'}): " +
                     "; ".join(drc_record.executed.get(module, [])))
    lines += ["", "## Streams at the pilot (messages per second during the session)", "",
              "| topic | lab | drc | designed (drc) |", "|---|---|---|---|"]
    lab_rates, drc_rates = rates(lab_record), rates(drc_record)
    for topic in sorted(set(lab_rates) | set(drc_rates)):
        lines.append(f"| `{topic}` | {lab_rates.get(topic, 0):.2f} | "
                     f"{drc_rates.get(topic, 0):.2f} | {DESIGNED_RATES.get(topic, '')} |")
    return lines


def _latency_section(rows: List[LatencyRow]) -> List[str]:
    lines = ["", "## Command latency (sent by the gateway -> the module's receipt for it: "
                 "accepted or refused)", "",
             "| command | lab (ms) | drc (ms) |", "|---|---|---|"]
    for words, a, b in rows:
        lines.append(f"| {words} | {a.shown() if a else 'not sent'} | "
                     f"{b.shown() if b else 'not sent'} |")
    return lines


def _link_section(drc_record: SessionRecord) -> List[str]:
    """What the bridge carried: bandwidth per id, and perception's completeness."""
    lines: List[str] = []
    if bandwidth_by_id(drc_record):
        means = mean_bandwidth(drc_record)
        names = id_names()
        lines += ["", "## Bridge bandwidth, robot to pilot (no IP headers)", "",
                  "| id | carries | channel | mean bit/s |", "|---|---|---|---|"]
        for (channel, ident), rate in sorted(means.items(), key=lambda item: item[0][1]):
            lines.append(f"| {ident} | {names.get(ident, '')} | {channel} | {rate:.0f} |")
        tcp_total = sum(rate for (channel, _), rate in means.items() if channel == "tcp")
        lines += ["", f"TCP channel (commands, statuses, robot state at T = 0.5 s): "
                      f"{tcp_total:.0f} bit/s of entries; the paper's Table 1 counts "
                      f"{PAPER_TABLE_1_BITS} bit/s at T = 1 s."]
    if drc_record.completeness:
        lines += ["", "## Perception through the UDP channel (pilot side, share of each frame "
                      "that arrived, lost frames count 0)", "", "| flow | completeness |",
                  "|---|---|"]
        lines += [f"| {name} | {value:.3f} |" for name, value in
                  sorted(drc_record.completeness.items())]
    return lines


def _summary(problems: List[str], latency_rows: List[LatencyRow], lab_record: SessionRecord,
             drc_record: SessionRecord) -> str:
    """The terminal's lines: the verdict, the table's median latencies, what arrived."""
    summary = [f"verdict: {'no observable difference' if not problems else 'DIFFERENT'}"]
    summary += [f"  - {p}" for p in problems]
    # the medians of the figures the table shows, nothing else
    lab_figures = [a.seconds for _, a, _ in latency_rows if a and a.seconds is not None]
    drc_figures = [b.seconds for _, _, b in latency_rows if b and b.seconds is not None]
    if lab_figures and drc_figures:
        summary.append(f"command -> receipt latency, median: lab "
                       f"{statistics.median(lab_figures) * 1000:.0f} ms, drc "
                       f"{statistics.median(drc_figures) * 1000:.0f} ms")
    for name, value in sorted(drc_record.completeness.items()):
        summary.append(f"through the bridge, {name}: {value:.3f} of each frame arrived")
    lab_rates, drc_rates = rates(lab_record), rates(drc_record)
    summary.append(f"joint states at the pilot: lab {lab_rates.get('/joint_states', 0):.1f} Hz,"
                   f" drc {drc_rates.get('/joint_states', 0):.1f} Hz")
    return "\n".join(summary)


def open_link(loopback: bool, progress, prefix: str = "wc", subnet: int = 60):
    """The emulated robot/pilot hosts when this machine can build them, else None (loopback)."""
    from netem import emulation

    if loopback:
        return None
    reason = emulation.available()
    if reason is not None:
        progress(f"no emulated network ({reason}); the two PCs share loopback")
        return None
    link = emulation.EmulatedLink(prefix, subnet)
    link.up()  # clears the leftovers of an interrupted run first
    return link


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-compare", description=__doc__.split("\n")[0])
    add_link_arguments(parser, "lab")
    parser.add_argument("--out", type=Path, help="report folder (default out/compare-<time>)")
    options = parser.parse_args(argv)
    out = options.out or REPO / "out" / f"compare-{time.strftime('%Y%m%d-%H%M%S')}"
    from nodekit.msgs import generate

    generate()
    progress = lambda text: print(f"[compare] {text}", flush=True)  # noqa: E731
    link = open_link(options.loopback, progress)
    try:
        with tempfile.TemporaryDirectory(prefix="walkman-compare-") as tmp:
            lab_record, lab = run_one("lab", Path(tmp), None, "lab", None, progress,
                                      out / "lab.bag")
            drc_record, drc = run_one("drc", Path(tmp), link, options.profile, options.loss,
                                      progress, out / "drc.bag")
    finally:
        if link is not None:
            link.down()
    summary, problems = report(out, lab, drc, lab_record, drc_record, options.profile,
                               options.loss, link is not None)
    print(summary)
    print(f"[compare] full report: {out / 'report.md'}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
