"""``walkman-chaos``: kill -9 the DRC system's programs and cut its link while a pilot commands it.

Theory of operation
-------------------
The ``drc`` topology (:class:`~system.topology.Topology`: robot PC and pilot PC,
each with its yarp-lite server and roscore, the HAL, the modules, both bridges,
the pilot gateway) runs on two emulated hosts (:mod:`bridge.emulation`,
namespaces ``wmchaos_*``) or, with ``--loopback`` or without root, on this
host.  Two more programs make it measurable:

* the **witness**, the bridge tests' counting module
  (``tests/bridge/counting_module.py``) as a GYM module ``/counter`` on the
  robot, added to the bridge configuration: it appends (and fsyncs) the
  sequence number of every command it executes to ``executed.log``;
* the **pilot** (:mod:`system.chaos_pilot`), a ROS node on the pilot PC that
  keeps ``counter``, ``gaze_control`` and ``temperature`` running and sends
  ``count N`` to ``counter`` through the gateway's ``send_command`` service,
  as a pilot does, N after N, trying again until the gateway accepts it.

A seeded schedule (:func:`system.chaos_figures.schedule`) then plays rounds:
some normal work, a fault -- SIGKILL to one program with its children (either
name server, either roscore, the HAL, a module, either bridge, the gateway) or
a link cut (``ip link down`` or 100 % loss) --, a short random delay, the
program started again as its launcher would (the link restored), and then
the tool waits until the pilot *sees* every module again (a status newer than
the last one before the fault ended: the recovery time) and until the pilot
can *use* them again (every module running, a command accepted after the
fault executed).  A program that exits by itself is reported and started again.

At the end the pilot stops, the commands in flight drain, and the figures come
from three records (:mod:`system.chaos_figures`): what the gateway logged as
sent (every incarnation's log), what the witness executed, what the pilot saw.
Then everything is stopped -- also on Ctrl-C or a failure -- and what is left
is counted: every program of the run carries ``WALKMAN_CHAOS_RUN=<id>`` in its
environment, so a process still alive with it is a leak, and so is every
socket it holds; the emulated hosts must be gone.  Leaks are killed after
being counted.

``--soak MINUTES`` plays no kills: the pilot works for that long while the
link (``--profile degraded``: 9600 bit/s) blacks out for 1-30 s now and then,
and every few seconds the resident memory and open files of every process
(from /proc) and the size of both bridges' journals are sampled.

The report (figures, every round, the schedule, the samples, every program's
log) goes to ``out/chaos-<time>/``; the command line ends with the table of
figures against their goals, and exits 1 when one is missed.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import sys
import tempfile
import time
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from bridge.emulation import EmulatedLink, EmulationError
from system import chaos_figures as figures
from system.chaos_figures import LINK, Fault
from system.processes import (REPO, ROSCORE_READY, Proc, WaitTimeout, descendants, usage,
                              wait_until)
from system.topology import (BRIDGE_CONFIG, PYTHON, YARP_SERVER_READY, Component, Topology,
                             add_link_arguments, components)

MARKER = "WALKMAN_CHAOS_RUN"
WITNESS = Component("counter", "robot", (PYTHON, "-m", "walkman.gym.supervisor",
                                         "tests.bridge.counting_module:Module", "--name",
                                         "/counter"), r"ready for the pilot")
WITNESS_ID = 12                     # a free id of models/bridge_drc.xml
MODULES = ("counter", "gaze_control", "temperature")
PILOT = "chaos_pilot"
NAME_SERVERS = {"yarp-server": YARP_SERVER_READY, "roscore": ROSCORE_READY}
#: Programs of the topology never killed: not on the command path, or (rosbag) only a recorder.
NOT_VICTIMS = ("perception", "joint_state", "joint_state_pilot", "rosbag")
DEFAULT_SKIP = ("rosbag",)          # a 30-minute bag of everything is not what is measured
GOALS = {"lost": 0, "duplicated": 0, "out_of_order": 0, "seen_p99_s": 10.0,
         "leaked_processes": 0, "leaked_ports": 0, "growth_percent": 10.0}
READY_TIMEOUT = 120.0    # s for a restarted program to say it is up
RECOVERY_TIMEOUT = 120.0  # s for the pilot to see, then use, every module again
SENT = re.compile(r"gateway: sent to /counter/command:i: \(count (\S+)\) (\d+)")
EXECUTED = re.compile(r"^executed count (\d+)$")


class ChaosError(Exception):
    """The run cannot go on (the machine, or the system did not recover); the text says why."""


def say(text: str) -> None:
    """A progress line, stamped like the programs' logs (``logs/<pc>/<program>.log``)."""
    print(f"[chaos] {time.strftime('%H:%M:%S')} {text}", flush=True)


def chaos_config(path: Path) -> Path:
    """``models/bridge_drc.xml`` plus the witness module, written to ``path``."""
    from bridge.config import ConfigError, load

    text = BRIDGE_CONFIG.read_text()
    if text.count("</modules>") != 1:
        raise ChaosError(f"{BRIDGE_CONFIG} has no single <modules> section for the witness")
    module = f'  <module name="counter" id="{WITNESS_ID}" statuses="idle counting"/>\n  '
    path.write_text(text.replace("</modules>", module + "</modules>"))
    try:
        load(path)  # an id taken since, say
    except ConfigError as exc:
        raise ChaosError(f"the witness does not fit {BRIDGE_CONFIG}: {exc}") from None
    return path


def victims(table: Sequence[Component], link: bool) -> List[str]:
    """Every program a round may kill, as ``<pc>:<name>``, and the link when there is one."""
    names = [f"{side}:{server}" for server in NAME_SERVERS for side in ("robot", "pilot")]
    names += [f"{c.pc}:{c.name}" for c in table if c.name not in NOT_VICTIMS]
    return names + ([LINK] if link else [])


# -- records ----------------------------------------------------------------------------------


@dataclass
class RoundResult:
    fault: Fault
    pid: Optional[int] = None
    killed_at: float = 0.0
    back_at: float = 0.0
    up_s: Optional[float] = None        # the restarted program's ready line
    seen_s: Optional[float] = None      # every module's news on the pilot side
    usable_s: Optional[float] = None    # every module running, a new command executed
    seen_by_module: Dict[str, float] = field(default_factory=dict)
    problem: str = ""
    finished: bool = False              # False: interrupted in the middle


@dataclass
class Record:
    """Everything the run observed, appended as it happens."""

    statuses: Dict[str, List[dict]] = field(default_factory=dict)   # module -> pilot's view
    accepted: List[dict] = field(default_factory=list)               # n, seq, t
    pilot_errors: List[dict] = field(default_factory=list)           # refused / failed calls
    switches: List[dict] = field(default_factory=list)
    executed: List[int] = field(default_factory=list)
    rounds: List[RoundResult] = field(default_factory=list)
    exits: List[dict] = field(default_factory=list)                  # programs that died alone
    samples: List[dict] = field(default_factory=list)                # soak: /proc and journals
    cuts: List[dict] = field(default_factory=list)                   # soak: blackouts
    soak_s: float = 0.0                                              # soak: time played


class Chaos:
    """One run: the topology, the witness, the pilot, the faults, and the cleanup."""

    def __init__(self, options: argparse.Namespace, out: Path,
                 progress: Callable[[str], None] = say) -> None:
        self.options = options
        self.out = out
        self.progress = progress
        self.marker = uuid.uuid4().hex[:12]
        self.record = Record(statuses={m: [] for m in MODULES})
        self.root = Path(tempfile.mkdtemp(prefix="walkman-chaos-"))
        self.link = None
        self.topology: Optional[Topology] = None
        self.history: List[Tuple[str, Proc]] = []     # every program started, in order
        self.ran: set = set()                          # the witness's executed seqs
        self._pilot_cursor = 0
        self._executed_at = 0
        self.witness_log = out / "executed.log"

    # -- bringing it up ----------------------------------------------------------------

    def start(self) -> None:
        from system.compare import open_link

        self.link = open_link(self.options.loopback, self.progress,
                              prefix=self.options.netns_prefix, subnet=self.options.subnet)
        config = chaos_config(self.root / "bridge_chaos.xml")
        self.topology = Topology("drc", self.root, link=self.link, profile=self.options.profile,
                                 loss=self.options.loss, bridge_config=config, extra=[WITNESS],
                                 extra_env={MARKER: self.marker,
                                            "COUNTER_LOG": str(self.witness_log)})
        for name in self.options.skip:
            self.topology.table.pop(name)
        for pc in self.topology.unique_pcs():
            pc.log_dir = self.out / "logs" / pc.name
        where = (f"emulated hosts {self.link.namespace('robot')}/{self.link.namespace('pilot')} "
                 f"({self.options.profile} link)" if self.link else "loopback")
        self.progress(f"starting the drc topology on {where}; logs in {self.out / 'logs'}")
        began = time.monotonic()
        self.topology.start_name_servers()
        for pc in self.topology.unique_pcs():
            self.history += [(f"{pc.name}:{name}", proc) for name, proc in pc.processes.items()]
        for name in self.topology.table:
            self._started(name, self.topology.start(name))
        self.topology.wait_ready(240)
        pilot = self.topology.pilot.start(PILOT, [
            PYTHON, "-m", "system.chaos_pilot", "--modules", ",".join(MODULES),
            "--command", "counter", "--interval", str(self.options.interval)])
        self.history.append((f"pilot:{PILOT}", pilot))
        pilot.wait_for(r'"ev": "ready"', 60)
        self.progress(f"everything up in {time.monotonic() - began:.0f} s; the pilot starts "
                      f"{', '.join(MODULES)} and sends count 1, 2, 3 ... to counter")
        self.wait_usable(time.time(), 240, "the pilot to start every module and command counter")

    def _started(self, name: str, proc: Proc) -> None:
        self.history.append((f"{self.topology.table[name].pc}:{name}", proc))

    # -- what the pilot and the witness say --------------------------------------------

    def poll(self) -> None:
        """Take in the pilot's new lines and the witness's new executions."""
        pilot = self.topology.pilot.processes.get(PILOT)
        lines = pilot.lines[self._pilot_cursor:] if pilot is not None else []
        self._pilot_cursor += len(lines)
        for line in lines:
            if not line.startswith("{"):
                continue
            event = json.loads(line)
            kind = event.pop("ev")
            if kind == "status":
                self.record.statuses[event["module"]].append(event)
            elif kind == "sent":
                self.record.accepted.append(event)
            elif kind in ("refused", "failed"):
                self.record.pilot_errors.append({"ev": kind, **event})
            elif kind == "switch":
                self.record.switches.append(event)
        if self.witness_log.exists():
            with open(self.witness_log) as log:
                log.seek(self._executed_at)
                text = log.read()
            complete = text[:text.rfind("\n") + 1]   # a line being written waits for the next poll
            self._executed_at += len(complete)
            for line in complete.splitlines():
                match = EXECUTED.match(line)
                if match:
                    self.record.executed.append(int(match.group(1)))
                    self.ran.add(int(match.group(1)))

    def pause(self, seconds: float) -> None:
        """Let the system work for ``seconds`` (the schedule's time), taking in what it says."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.poll()
            time.sleep(min(0.2, max(0.0, end - time.monotonic())))

    def wait(self, condition: Callable[[], bool], timeout: float, what: str) -> float:
        """Poll until ``condition()``; the seconds it took.  Raises WaitTimeout."""
        began = time.monotonic()
        while True:
            self.poll()
            if condition():
                return time.monotonic() - began
            if time.monotonic() - began > timeout:
                raise WaitTimeout(f"no {what} within {timeout:.0f} s")
            time.sleep(0.2)

    def seen_since(self, back: float) -> Dict[str, float]:
        """For each module the pilot had news of after ``back``: when."""
        seen = {}
        for module, statuses in self.record.statuses.items():
            start = len(statuses)
            while start > 0 and statuses[start - 1]["t"] >= back:
                start -= 1
            at = figures.first_fresh(statuses[max(0, start - 1):], module, back)
            if at is not None:
                seen[module] = at
        return seen

    def usable(self, back: float) -> bool:
        """Every module shows a running state after ``back`` and a command accepted after
        ``back`` was executed."""
        from rosnodes.gateway import lifecycle_of

        for statuses in self.record.statuses.values():
            if not statuses or statuses[-1]["t"] < back or \
                    lifecycle_of(statuses[-1]["state"]) != "running":
                return False
        accepted = self.record.accepted
        first = len(accepted)
        while first > 0 and accepted[first - 1]["t"] >= back:
            first -= 1
        return first < len(accepted) and accepted[first]["seq"] in self.ran

    def wait_usable(self, back: float, timeout: float, what: str) -> float:
        return self.wait(lambda: self.usable(back), timeout, what)

    # -- the faults --------------------------------------------------------------------

    def play(self, fault: Fault) -> RoundResult:
        """One round: work, the fault, the restart, the recovery as the pilot sees it."""
        result = RoundResult(fault)
        self.record.rounds.append(result)
        self._play(result)
        result.finished = True
        return result

    def _play(self, result: RoundResult) -> None:
        fault = result.fault
        self.pause(fault.lead)
        if fault.victim == LINK:
            result.killed_at = time.time()
            self.cut_link(fault.how, True)
            self.pause(fault.down)
            self.cut_link(fault.how, False)
            result.back_at = time.time()
        else:
            side, name = fault.victim.split(":", 1)
            proc = self.topology.pcs[side].processes[name]
            result.pid = proc.popen.pid
            result.killed_at = time.time()
            proc.kill(signal.SIGKILL)
            self.pause(fault.down)
            proc, ready = self.restart(side, name)
            result.back_at = time.time()
            try:
                result.up_s = self.wait(lambda: bool(re.search(ready, proc.output())),
                                        READY_TIMEOUT, f"ready line from {fault.victim}")
            except WaitTimeout as exc:
                result.problem = f"{fault.victim} did not come back: {exc}"
                return
        back = result.back_at
        try:
            self.wait(lambda: len(self.seen_since(back)) == len(MODULES), RECOVERY_TIMEOUT,
                      "news of every module on the pilot side")
            result.seen_by_module = {m: round(t - back, 3)
                                     for m, t in self.seen_since(back).items()}
            result.seen_s = max(result.seen_by_module.values())
            self.wait_usable(back, RECOVERY_TIMEOUT, "running modules executing new commands")
            result.usable_s = round(time.time() - back, 3)
        except WaitTimeout as exc:
            seen = self.seen_since(back)
            missing = [m for m in MODULES if m not in seen] or \
                [f"{m} ({s[-1]['state'] if s else 'no status'})"
                 for m, s in self.record.statuses.items()]
            result.problem = f"{exc}; modules: {', '.join(missing)}"
        self.restart_exited()

    def restart(self, side: str, name: str) -> Tuple[Proc, str]:
        """Start a program again as its launcher would; the line that says it is up."""
        pc = self.topology.pcs[side]
        if name == "yarp-server":
            proc, ready = pc.start_yarp_server(), YARP_SERVER_READY
        elif name == "roscore":
            proc, ready = pc.start_roscore(), ROSCORE_READY
        else:
            proc, ready = self.topology.start(name), self.topology.table[name].ready
        self.history.append((f"{side}:{name}", proc))
        return proc, ready

    def cut_link(self, how: str, cut: bool) -> None:
        if how == "flap":
            self.link.flap(cut)
        elif cut:
            self.link.blackout(True)
        else:  # back to the profile's loss, not to a clean wire
            self.link.apply(self.options.profile, loss=self.options.loss)

    def restart_exited(self) -> None:
        """A program that died without being killed is a finding; start it again."""
        for pc in self.topology.unique_pcs():
            for name, proc in list(pc.processes.items()):
                code = proc.popen.poll()
                if code is None:
                    continue
                if name == PILOT:
                    raise ChaosError(f"the pilot exited ({code}):\n" + proc.output()[-2000:])
                last = proc.lines[-15:]
                self.record.exits.append({"program": f"{pc.name}:{name}", "code": code,
                                          "after_round": len(self.record.rounds),
                                          "last_lines": last})
                self.progress(f"{pc.name}:{name} exited by itself ({code}); its last lines:\n"
                              + "\n".join(f"    {line}" for line in last))
                self.restart(pc.name, name)

    # -- soak --------------------------------------------------------------------------

    def soak(self, minutes: float) -> None:
        duration = minutes * 60.0
        cuts = figures.blackouts(self.options.seed, duration) if self.link else []
        began, next_sample, next_line = time.monotonic(), 0.0, 60.0
        cut: Optional[dict] = None
        with open(self.out / "samples.jsonl", "w") as samples:
            while (elapsed := time.monotonic() - began) < duration:
                if cut is None and cuts and elapsed >= cuts[0][0]:
                    _, seconds = cuts.pop(0)
                    self.cut_link("blackout", True)
                    cut = {"at": time.time(), "seconds": seconds, "ends": elapsed + seconds}
                    self.record.cuts.append(cut)
                    self.progress(f"blackout for {seconds:.0f} s")
                if cut is not None and elapsed >= cut["ends"]:
                    self.cut_link("blackout", False)
                    cut["back"] = time.time()
                    cut = None
                if elapsed >= next_sample:
                    self.restart_exited()
                    self.record.samples.append(sample := self.sample())
                    samples.write(json.dumps(sample) + "\n")
                    samples.flush()
                    next_sample += self.options.sample_every
                if elapsed >= next_line:
                    next_line += 60.0
                    self.progress(self.soak_line(elapsed, duration))
                self.pause(0.5)
                self.record.soak_s = time.monotonic() - began
            if cut is not None:
                self.cut_link("blackout", False)
                cut["back"] = time.time()

    def sample(self) -> dict:
        """Resident KiB and open files of every process of every program; journal bytes."""
        procs: Dict[str, List[int]] = {}
        for pc in self.topology.unique_pcs():
            for name, proc in pc.processes.items():
                if name == PILOT:
                    continue
                top = proc.popen.pid
                for pid in [top, *descendants(top)]:
                    found = usage(pid)
                    if found is None:
                        continue
                    key = f"{pc.name}:{name}"
                    if pid != top:
                        key += f"/{_comm(pid)}:{pid}"
                    procs[key] = list(found)
        return {"t": time.time(), "procs": procs, "journal": self.journal_bytes()}

    def journal_bytes(self) -> Dict[str, Dict[str, int]]:
        """Each bridge's journal: the database and its write-ahead log (which SQLite lets
        grow to about 4 MB before it starts again at its beginning)."""
        sizes = {}
        for side in ("robot", "pilot"):
            path = self.topology.pcs[side].root / "state" / "walkman-bridge" / side \
                / "journal.sqlite"
            sizes[side] = {part: file.stat().st_size if file.is_file() else 0
                           for part, file in (("db", path), ("wal", path.with_name(
                               "journal.sqlite-wal")))}
        return sizes

    def soak_line(self, elapsed: float, duration: float) -> str:
        soak = soak_figures(self.record.samples, self.options.sample_every)
        worst = max(soak["processes"].items(), key=lambda kv: kv[1]["rss_percent"],
                    default=(None, None))
        journal = self.record.samples[-1]["journal"] if self.record.samples else {}
        grown = (f"most grown {worst[0]} {worst[1]['rss_percent']:+.1f} % RSS"
                 if worst[0] else "no samples yet")
        sizes = ", ".join(f"{side} {sum(parts.values()) // 1024} KiB"
                          for side, parts in journal.items())
        return (f"soak {elapsed / 60:.0f}/{duration / 60:.0f} min: "
                f"{len(self.record.executed)} commands executed, {len(self.record.cuts)} "
                f"blackouts; {grown}; journals {sizes}")

    # -- the end -----------------------------------------------------------------------

    def drain(self, timeout: float) -> None:
        """Stop the pilot, then give the commands already sent time to run."""
        pilot = self.topology.pilot.processes[PILOT]
        pilot.interrupt()
        self.poll()
        sent = {seq for _, seq in self.sent()}
        try:
            self.wait(lambda: sent <= set(self.record.executed), timeout,
                      "execution of every command sent")
        except WaitTimeout:
            self.progress(f"{len(sent - set(self.record.executed))} command(s) sent were not "
                          f"executed {timeout:.0f} s after the pilot stopped")

    def sent(self) -> List[Tuple[int, int]]:
        """``(N, seq)`` the gateways wrote to the witness's port, in the order they did."""
        out = []
        for name, proc in self.history:
            if name == "pilot:gateway":
                out += [(int(float(m.group(1))), int(m.group(2)))
                        for m in map(SENT.search, list(proc.lines)) if m]
        return out

    def close(self) -> Dict[str, list]:
        """Stop everything, then count (and kill) what is left.  Safe to call on any failure."""
        if self.topology is not None:
            self.topology.close()
        if self.link is not None:
            self.link.down()
        found = leaks(self.marker, self.link)
        for process in found["processes"]:
            try:
                os.kill(process["pid"], signal.SIGKILL)
            except ProcessLookupError:
                pass
        shutil.rmtree(self.root, ignore_errors=True)
        return found


def _comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return "?"


# -- leaks ------------------------------------------------------------------------------------


def marked(marker: str) -> List[dict]:
    """Living processes (not zombies) whose environment carries this run's marker."""
    needle = f"{MARKER}={marker}".encode()
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            if needle not in Path(f"/proc/{entry}/environ").read_bytes().split(b"\0"):
                continue
            state = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0]
            command = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ")
        except (FileNotFoundError, ProcessLookupError, PermissionError, IndexError):
            continue
        if state != "Z":
            found.append({"pid": int(entry), "cmdline": command.decode(errors="replace")[:300]})
    return found


def sockets(pid: int) -> List[str]:
    """The listening TCP and bound UDP sockets a process holds, in its network namespace."""
    inodes = set()
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return []
    for fd in fds:
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except (FileNotFoundError, ProcessLookupError):
            continue  # closed meanwhile
        if link.startswith("socket:["):
            inodes.add(link[len("socket:["):-1])
    out = []
    for proto in ("tcp", "tcp6", "udp", "udp6"):
        try:
            rows = Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            cols = row.split()
            listening = cols[3] == "0A" if proto.startswith("tcp") else cols[3] == "07"
            if listening and cols[9] in inodes:
                out.append(f"{proto} port {int(cols[1].rsplit(':', 1)[1], 16)} (pid {pid})")
    return out


def leaks(marker: str, link) -> Dict[str, list]:
    """What outlived the cleanup: processes, their sockets, the emulated hosts."""
    try:  # the cleanup's last SIGKILLs take a moment to land
        wait_until(lambda: not marked(marker), 5.0, interval=0.1)
    except WaitTimeout:
        pass  # counted below
    processes = marked(marker)
    ports = [s for p in processes for s in sockets(p["pid"])]
    namespaces = [link.namespace(side) for side in ("robot", "pilot")
                  if link is not None and link.exists()]
    return {"processes": processes, "ports": ports, "namespaces": namespaces}


# -- figures and report -----------------------------------------------------------------------


def soak_figures(samples: Sequence[dict], every: float) -> dict:
    """Growth of RSS and open files per process, journal sizes, from the samples."""
    if not samples:
        return {"processes": {}, "journal": {}}
    span = samples[-1]["t"] - samples[0]["t"]
    warm_up = min(120.0, 0.2 * span)
    series: Dict[str, List[Tuple[float, List[int]]]] = {}
    for sample in samples:
        for key, values in sample["procs"].items():
            series.setdefault(key, []).append((sample["t"], values))
    processes = {}
    for key, points in sorted(series.items()):
        rss = figures.growth([(t, v[0]) for t, v in points], warm_up)
        # the floor: a name server's count goes 5, 6, 5 with each query; a leak raises it
        fds = figures.growth([(t, v[1]) for t, v in points], warm_up, statistic=min)
        processes[key] = {"rss_kib": [rss.start, rss.end], "rss_percent": rss.percent,
                          "files": [fds.start, fds.end], "files_percent": fds.percent,
                          "samples": len(points)}
    journal = {}
    for side in ("robot", "pilot"):
        parts = [s["journal"][side] for s in samples]
        sizes = [(s["t"], sum(part.values())) for s, part in zip(samples, parts)]
        journal[side] = {"first": sizes[0][1], "max": max(v for _, v in sizes),
                         "last": sizes[-1][1], "max_db": max(p["db"] for p in parts),
                         "max_wal": max(p["wal"] for p in parts),
                         "bounded": figures.bounded(sizes)}
    return {"processes": processes, "journal": journal, "span_s": span, "every_s": every}


def summarize(chaos: Chaos, leaked: Dict[str, list], elapsed: float,
              interrupted: bool, failure: str) -> dict:
    record = chaos.record
    sent = chaos.sent()
    counted = figures.commands(sent, [a["seq"] for a in record.accepted], record.executed)
    seen = [r.seen_s for r in record.rounds if r.seen_s is not None]
    # the whole outage as the pilot lived it: the fault's own length plus the recovery
    outage = [r.back_at - r.killed_at + r.seen_s for r in record.rounds if r.seen_s is not None]
    for cut in record.cuts:
        if "back" in cut:
            times = [figures.first_fresh(record.statuses[m], m, cut["back"]) for m in MODULES]
            cut["seen_s"] = (max(times) - cut["back"]) if None not in times else None
            if cut["seen_s"] is not None:
                seen.append(cut["seen_s"])
                outage.append(cut["back"] - cut["at"] + cut["seen_s"])
    soak = soak_figures(record.samples, chaos.options.sample_every) if record.samples else None
    options = chaos.options
    completed = (record.soak_s >= options.soak * 60.0 - 1.0 if options.soak else
                 len([r for r in record.rounds if r.finished]) == options.rounds)
    figures_ = {
        "sent": counted.sent, "accepted": counted.accepted, "executed": counted.executed,
        "lost": len(counted.lost), "duplicated": len(counted.duplicated),
        "out_of_order": len(counted.out_of_order),
        "unacknowledged": len(counted.unacknowledged),
        "retried_twice": len(counted.retried_twice),
        "faults": len(record.rounds) + len(record.cuts),
        "seen_median_s": figures.percentile(seen, 0.5),
        "seen_p99_s": figures.percentile(seen, 0.99),
        "outage_median_s": figures.percentile(outage, 0.5),
        "outage_p99_s": figures.percentile(outage, 0.99),
        "unrecovered_rounds": len([r for r in record.rounds if r.problem]),
        "unexpected_exits": len(record.exits),
        "leaked_processes": len(leaked["processes"]), "leaked_ports": len(leaked["ports"]),
        "leaked_namespaces": len(leaked["namespaces"]),
    }
    if soak:
        figures_["max_rss_growth_percent"] = max(
            (p["rss_percent"] for p in soak["processes"].values()), default=0.0)
        figures_["max_files_growth_percent"] = max(
            (p["files_percent"] for p in soak["processes"].values()), default=0.0)
        figures_["journals_bounded"] = all(j["bounded"] for j in soak["journal"].values())
    return {
        "tool": "walkman-chaos", "interrupted": interrupted, "failure": failure,
        "elapsed_s": elapsed, "soak_s": record.soak_s,
        "options": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(options).items()},
        "emulated": chaos.link is not None, "figures": figures_,
        "goals": {**verdicts(figures_),
                  "run_completed": completed and not failure and not interrupted},
        "commands": {k: v[:100] if isinstance(v, list) else v
                     for k, v in asdict(counted).items()},
        "where": where_commands(counted, record, sent),
        "rounds": [asdict(r) for r in record.rounds], "exits": record.exits,
        "pilot_errors": record.pilot_errors[-200:], "cuts": record.cuts, "soak": soak,
        "leaks": leaked,
    }


def verdicts(values: dict) -> Dict[str, bool]:
    """Each goal of the brief: met or not."""
    out = {name: values[name] <= GOALS[name]
           for name in ("lost", "duplicated", "out_of_order", "leaked_processes",
                        "leaked_ports")}
    out["leaked_namespaces"] = values["leaked_namespaces"] == 0
    if values["faults"]:  # a soak on loopback cuts nothing: no recovery to time
        out["seen_p99_s"] = values["seen_p99_s"] is not None and \
            values["seen_p99_s"] <= GOALS["seen_p99_s"]
    out["every_round_recovered"] = values["unrecovered_rounds"] == 0
    if "max_rss_growth_percent" in values:
        out["max_rss_growth_percent"] = values["max_rss_growth_percent"] < GOALS["growth_percent"]
        out["max_files_growth_percent"] = \
            values["max_files_growth_percent"] < GOALS["growth_percent"]
        out["journals_bounded"] = values["journals_bounded"]
    return out


def where_commands(counted: figures.Commands, record: Record,
                   sent: Sequence[Tuple[int, int]]) -> List[dict]:
    """For each lost, duplicated or out-of-order command: its N and the round around it."""
    number = {seq: n for n, seq in sent}
    when = {a["seq"]: a["t"] for a in record.accepted}
    out = []
    for kind in ("lost", "duplicated", "out_of_order"):
        for seq in getattr(counted, kind)[:50]:
            at = when.get(seq)
            near = [r.fault.round for r in record.rounds
                    if at is not None and r.killed_at - 10 <= at <= r.back_at +
                    (r.usable_s or RECOVERY_TIMEOUT)]
            out.append({"kind": kind, "seq": seq, "n": number.get(seq), "accepted_at": at,
                        "rounds": near})
    return out


def _fmt(value, unit: str = "") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.1f}{unit}"
    return f"{value}{unit}"


def table(summary: dict) -> str:
    """The figures against their goals, for the terminal and the report."""
    f, goals = summary["figures"], summary["goals"]

    def mark(key: str) -> str:
        return "n/a" if key not in goals else "ok" if goals[key] else "MISSED"

    options = summary["options"]
    if options.get("soak"):
        played = (f"{summary['soak_s'] / 60:.1f} / {options['soak']:g} min", "soak")
    else:
        done = len([r for r in summary["rounds"] if r["finished"]])
        played = (f"{done} / {options['rounds']}", "rounds played")
    rows = [(played[1], played[0], "all", mark("run_completed")),
            ("commands sent / executed", f"{f['sent']} / {f['executed']}", "", ""),
            ("lost", _fmt(f["lost"]), "0", mark("lost")),
            ("duplicated", _fmt(f["duplicated"]), "0", mark("duplicated")),
            ("out of order", _fmt(f["out_of_order"]), "0", mark("out_of_order")),
            ("pilot sees the modules again, median", _fmt(f["seen_median_s"], " s"), "", ""),
            ("pilot sees the modules again, p99", _fmt(f["seen_p99_s"], " s"), "<= 10 s",
             mark("seen_p99_s")),
            ("  (from the fault's start: median, p99)",
             f"{_fmt(f['outage_median_s'])}, {_fmt(f['outage_p99_s'], ' s')}", "", ""),
            ("rounds not recovered", _fmt(f["unrecovered_rounds"]), "0",
             mark("every_round_recovered")),
            ("leaked processes", _fmt(f["leaked_processes"]), "0", mark("leaked_processes")),
            ("leaked ports", _fmt(f["leaked_ports"]), "0", mark("leaked_ports")),
            ("leaked emulated hosts", _fmt(f["leaked_namespaces"]), "0",
             mark("leaked_namespaces"))]
    if "max_rss_growth_percent" in f:
        rows += [("largest RSS growth of a process", _fmt(f["max_rss_growth_percent"], " %"),
                  "< 10 %", mark("max_rss_growth_percent")),
                 ("largest open-files growth", _fmt(f["max_files_growth_percent"], " %"),
                  "< 10 %", mark("max_files_growth_percent")),
                 ("journals bounded", "yes" if f["journals_bounded"] else "no", "yes",
                  mark("journals_bounded"))]
    rows += [("programs that exited by themselves", _fmt(f["unexpected_exits"]), "", ""),
             ("executed, never acknowledged", _fmt(f["unacknowledged"]), "", ""),
             ("pilot retries that ran twice", _fmt(f["retried_twice"]), "", "")]
    width = max(len(r[0]) for r in rows)
    lines = [f"{'figure':<{width}}  {'value':>12}  goal",
             f"{'-' * width}  {'-' * 12}  {'-' * 8}  {'-' * 6}"]
    lines += [f"{name:<{width}}  {value:>12}  {goal:<8}  {verdict}".rstrip()
              for name, value, goal, verdict in rows]
    return "\n".join(lines)


def markdown(summary: dict) -> str:
    options = summary["options"]
    link = f"emulated `{options['profile']}` link" if summary["emulated"] else "loopback"
    kind = (f"{options['soak']}-minute soak" if options.get("soak")
            else f"{len(summary['rounds'])} rounds")
    out = [f"# walkman-chaos: {kind}, seed {options['seed']}, {link}", ""]
    if summary["interrupted"]:
        out += ["**Interrupted** before the end: the figures cover what ran.", ""]
    if summary.get("failure"):
        out += [f"**Failed**: {summary['failure']}", ""]
    out += ["```", table(summary), "```", "",
            "*Lost*: logged as sent by the gateway (the bridge acknowledged it), never executed "
            "by the witness; *duplicated*: executed twice; *out of order*: executed after a "
            "command sent later.  *Seen again*: from the end of the fault (the program started "
            "again, the link back) until the pilot has a status of every module newer than the "
            "last one before; the line below counts from the fault's start.  *Usable*: every "
            "module running and the first command accepted after the fault executed.", ""]
    if summary["rounds"]:
        out += ["## Rounds", "",
                "| # | at | fault | down s | pid | up s | seen s | usable s | problem |",
                "|---|---|---|---|---|---|---|---|---|"]
        for r in summary["rounds"]:
            fault = r["fault"]
            problem = r["problem"] or ("" if r["finished"] else "interrupted")
            at = time.strftime("%H:%M:%S", time.localtime(r["killed_at"])) \
                if r["killed_at"] else ""
            out.append(f"| {fault['round']} | {at} | {fault['how']} {fault['victim']} | "
                       f"{fault['down']:.1f} | {r['pid'] or ''} | {_fmt(r['up_s'])} | "
                       f"{_fmt(r['seen_s'])} | {_fmt(r['usable_s'])} | {problem} |")
        out += ["", "## Recovery by victim", "", "| victim | rounds | seen median s | seen max s |",
                "|---|---|---|---|"]
        by_victim: Dict[str, List[float]] = {}
        for r in summary["rounds"]:
            if r["seen_s"] is not None:
                by_victim.setdefault(r["fault"]["victim"], []).append(r["seen_s"])
        for victim, values in sorted(by_victim.items()):
            out.append(f"| {victim} | {len(values)} | "
                       f"{_fmt(figures.percentile(values, 0.5))} | {_fmt(max(values))} |")
    if summary["cuts"]:
        out += ["", "## Blackouts", "", "| at | seconds | seen s |", "|---|---|---|"]
        out += [f"| {time.strftime('%H:%M:%S', time.localtime(c['at']))} | {c['seconds']:.1f} | "
                f"{_fmt(c.get('seen_s'))} |" for c in summary["cuts"]]
    if summary["soak"]:
        soak = summary["soak"]
        out += ["", "## Soak: growth per process", "",
                "| process | RSS KiB start | end | growth % | open files start | end | growth % |",
                "|---|---|---|---|---|---|---|"]
        for key, p in soak["processes"].items():
            out.append(f"| {key} | {p['rss_kib'][0]:.0f} | {p['rss_kib'][1]:.0f} | "
                       f"{p['rss_percent']:+.1f} | {p['files'][0]:.0f} | {p['files'][1]:.0f} | "
                       f"{p['files_percent']:+.1f} |")
        out += ["", "| journal (db + wal) | first bytes | max | last | max db | max wal | "
                "bounded |", "|---|---|---|---|---|---|---|"]
        out += [f"| {side} | {j['first']} | {j['max']} | {j['last']} | {j['max_db']} | "
                f"{j['max_wal']} | {j['bounded']} |" for side, j in soak["journal"].items()]
    if summary["where"]:
        out += ["", "## Commands lost, duplicated or out of order", "",
                "| kind | seq | N | accepted at | rounds around it |", "|---|---|---|---|---|"]
        out += [f"| {w['kind']} | {w['seq']} | {w['n']} | {_fmt(w['accepted_at'])} | "
                f"{w['rounds']} |" for w in summary["where"]]
    if summary["exits"]:
        out += ["", "## Programs that exited by themselves", ""]
        for e in summary["exits"]:
            out += [f"* `{e['program']}` exited {e['code']} after round {e['after_round']}:",
                    "", "```", *e["last_lines"], "```", ""]
    leaked = summary["leaks"]
    if any(leaked.values()):
        out += ["", "## Leaks (killed after counting)", "", "```",
                *[f"pid {p['pid']}: {p['cmdline']}" for p in leaked["processes"]],
                *leaked["ports"], *[f"namespace {n}" for n in leaked["namespaces"]], "```"]
    out += ["", "Every program's log: `logs/<pc>/<program>.log`; the pilot's view: "
            "`logs/pilot/chaos_pilot.log`; the witness: `executed.log`."]
    return "\n".join(out) + "\n"


# -- running ----------------------------------------------------------------------------------


def run(options: argparse.Namespace, progress: Callable[[str], None] = say) -> dict:
    """The whole run; the summary (also written to ``options.out``).  Cleans up on any exit."""
    out = options.out
    out.mkdir(parents=True, exist_ok=True)
    chaos = Chaos(options, out, progress)
    began = time.monotonic()
    interrupted, failure = False, ""
    leaked: Dict[str, list] = {"processes": [], "ports": [], "namespaces": []}
    try:
        chaos.start()
        if options.soak:
            progress(f"soak: {options.soak:g} minutes of piloting"
                     f"{' with blackouts' if chaos.link else ''}, sampling every "
                     f"{options.sample_every:g} s")
            chaos.soak(options.soak)
        else:
            play_rounds(chaos, options, progress)
        progress("stopping the pilot; commands in flight drain")
        chaos.drain(options.drain)
    except KeyboardInterrupt:
        interrupted = True
        progress("interrupted: stopping everything")
    except (ChaosError, EmulationError, WaitTimeout) as exc:
        # the machine (no emulated hosts), or a system that did not come up or back
        failure = str(exc)
        progress(f"FAILED: {failure}")
    finally:
        # A second Ctrl-C (or a SIGTERM) must not cut the cleanup short.
        previous = {sig: signal.signal(sig, signal.SIG_IGN)
                    for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            if chaos.topology is not None:
                chaos.poll()
            progress("stopping every program; then counting what is left")
            leaked = chaos.close()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
    summary = summarize(chaos, leaked, time.monotonic() - began, interrupted, failure)
    (out / "report.json").write_text(json.dumps(summary, indent=1, default=str))
    (out / "report.md").write_text(markdown(summary))
    return summary


def play_rounds(chaos: Chaos, options: argparse.Namespace,
                progress: Callable[[str], None]) -> None:
    pool = victims(chaos.topology.table.values(), chaos.link is not None)
    if options.victims:
        unknown = set(options.victims) - set(pool)
        if unknown:
            raise ChaosError(f"--victims: {', '.join(sorted(unknown))} not in this run "
                             f"({', '.join(pool)})")
        pool = list(options.victims)
    faults = figures.schedule(options.seed, options.rounds, pool)
    for fault in faults:
        result = chaos.play(fault)
        what = (f"{fault.how} for {fault.down:.1f} s" if fault.victim == LINK else
                f"kill -9 {fault.victim} (pid {result.pid}), restarted after {fault.down:.1f} s,"
                f" up in {_fmt(result.up_s, ' s')}")
        progress(f"round {fault.round:>3}/{len(faults)}  {what};  seen in "
                 f"{_fmt(result.seen_s, ' s')}, usable in {_fmt(result.usable_s, ' s')};  "
                 f"commands {len(chaos.record.accepted)} accepted, "
                 f"{len(chaos.record.executed)} run"
                 + (f"  PROBLEM: {result.problem}" if result.problem else ""))
        if result.problem:
            progress("a round did not recover: no further rounds (the logs say why)")
            return


def parse_args(argv: Optional[List[str]] = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="walkman-chaos", description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=1, help="seed of the schedule (default 1)")
    parser.add_argument("--rounds", type=int, default=100, help="rounds of faults (default 100)")
    parser.add_argument("--soak", type=float, metavar="MINUTES",
                        help="no kills: pilot for MINUTES with blackouts, sampling /proc")
    add_link_arguments(parser, "drc", " (no link cuts then)")
    parser.add_argument("--victims", default="",
                        help="only these (comma separated, e.g. pilot:gateway,link; default: "
                             "both name servers, both roscores, the HAL, the modules, both "
                             "bridges, the gateway and the link)")
    parser.add_argument("--skip", default=",".join(DEFAULT_SKIP),
                        help=f"programs not to start (default {','.join(DEFAULT_SKIP)})")
    parser.add_argument("--interval", type=float, default=0.5,
                        help="seconds between two commands of the pilot (default 0.5)")
    parser.add_argument("--sample-every", type=float, default=5.0,
                        help="soak: seconds between two samples (default 5)")
    parser.add_argument("--drain", type=float, default=60.0,
                        help="seconds the last commands may take to run (default 60)")
    parser.add_argument("--netns-prefix", default="wmchaos",
                        help="emulated hosts' namespace prefix (default wmchaos)")
    parser.add_argument("--subnet", type=int, default=40,
                        help="emulated link 169.254.SUBNET.x (default 40)")
    parser.add_argument("--out", type=Path, help="report folder (default out/chaos-<time>)")
    options = parser.parse_args(argv)
    if options.rounds < 1:
        parser.error("--rounds must be at least 1")
    if options.soak is not None and options.soak <= 0:
        parser.error("--soak must be a positive number of minutes")
    if options.loss is not None and not 0 <= options.loss <= 100:
        parser.error(f"--loss must be a percentage between 0 and 100, not {options.loss}")
    if options.interval <= 0 or options.sample_every <= 0 or options.drain < 0:
        parser.error("--interval and --sample-every must be positive, --drain not negative")
    options.victims = [v.strip() for v in options.victims.split(",") if v.strip()]
    options.skip = [s.strip() for s in options.skip.split(",") if s.strip()]
    known = [c.name for c in [*components("drc"), WITNESS]]
    unknown = [s for s in options.skip if s not in known]
    if unknown or WITNESS.name in options.skip:
        parser.error(f"--skip: cannot skip {', '.join(unknown or [WITNESS.name])} (programs: "
                     f"{', '.join(n for n in known if n != WITNESS.name)})")
    try:
        EmulatedLink(options.netns_prefix, options.subnet)
    except EmulationError as exc:
        parser.error(f"--netns-prefix/--subnet: {exc}")
    possible = victims([*components("drc"), WITNESS], link=True)
    wrong = [v for v in options.victims if v not in possible]
    if wrong:
        parser.error(f"--victims: unknown {', '.join(wrong)} (choose from {', '.join(possible)})")
    options.out = (options.out or REPO / "out" / f"chaos-{time.strftime('%Y%m%d-%H%M%S')}")
    return options


def main(argv: Optional[List[str]] = None) -> int:
    options = parse_args(argv)
    from rosnodes.msgs import generate

    generate()

    def stop(number, _frame) -> None:  # SIGTERM stops as Ctrl-C does
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):  # also where a shell starts us ignoring SIGINT
        signal.signal(sig, stop)
    summary = run(options)
    print(table(summary))
    print(f"[chaos] full report: {options.out / 'report.md'}")
    if summary["interrupted"]:
        return 130
    return 0 if all(summary["goals"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
