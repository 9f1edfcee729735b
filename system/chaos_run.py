"""One chaos run's orchestration: the topology, the witness, the pilot, the faults, the cleanup.

Theory of operation
-------------------
:class:`Chaos` brings up the ``drc`` topology (:class:`~system.topology.Topology`)
with two more programs: the **witness** (:mod:`walkman.modules.witness`, the
GYM module ``/counter`` on the robot, added to the bridge configuration as id
:data:`WITNESS_ID`) and the **pilot** (:mod:`system.chaos_pilot`, a ROS node on
the pilot PC).  Every program gets the run's marker
(:data:`system.chaos_proc.MARKER`) in its environment and its log under
``logs/<pc>/``.

A round (:meth:`Chaos.play`) is some normal work, the fault -- SIGKILL to a
program with its children, or a link cut --, the program started again as its
launcher would (the link restored), then two waits measured as the pilot
lives them: until it *sees* every module again (a status newer than the last
one before the fault ended) and until it can *use* them (every module
running, and the first plain command -- neither short-lived nor cancelled --
accepted after the fault executed).  A program that exits by itself is
recorded and started again.

Meanwhile :meth:`Chaos.poll` takes in the pilot's lines and the witness's log
(:mod:`system.chaos_record`).  At the end :meth:`Chaos.drain` tells the pilot
to send no more, waits until every command sent has ended -- run, expired or
cancelled --, and :meth:`Chaos.close` stops everything and counts what is left
(:mod:`system.chaos_proc`).  The soak is :mod:`system.chaos_soak`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import tempfile
import time
import uuid
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from system import chaos_figures as figures
from system.chaos_figures import LINK, Fault
from system.chaos_proc import MARKER, leaks
from system.chaos_record import (WITNESS_MODULE, Record, RoundResult, cancelled_by_bridge,
                                 expired_at_module, seqs_of_numbers, sent_commands)
from system.processes import ROSCORE_READY, Proc, WaitTimeout
from system.topology import BRIDGE_CONFIG, PYTHON, YARP_SERVER_READY, Component, Topology
from walkman.modules import witness
from walkman.modules.witness import LOG_VARIABLE, parse_line

#: ``walkman-module witness``: the package's own witness, never the source tree's tests.
WITNESS = Component(WITNESS_MODULE, "robot", (PYTHON, "-m", "walkman.gym.supervisor", "witness",
                                              "--name", f"/{WITNESS_MODULE}"),
                    r"ready for the pilot")
WITNESS_ID = 12                     # a free id of models/bridge_drc.xml
MODULES = (WITNESS_MODULE, "gaze_control", "temperature")
PILOT = "chaos_pilot"
NAME_SERVERS = {"yarp-server": YARP_SERVER_READY, "roscore": ROSCORE_READY}
#: Programs of the topology never killed: not on the command path, or (rosbag) only a recorder.
NOT_VICTIMS = ("perception", "joint_state", "joint_state_pilot", "rosbag")
READY_TIMEOUT = 120.0    # s for a restarted program to say it is up
RECOVERY_TIMEOUT = 120.0  # s for the pilot to see, then use, every module again
DRAINED_TIMEOUT = 30.0   # s for the pilot to finish the call it is in and stop sending


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
    module = (f'  <module name="{WITNESS_MODULE}" id="{WITNESS_ID}" '
              f'statuses="{" ".join(witness.Module.statuses)}"/>\n  ')
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
                                            LOG_VARIABLE: str(self.witness_log)})
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
        options = self.options
        pilot = self.topology.pilot.start(PILOT, [
            PYTHON, "-m", "system.chaos_pilot", "--modules", ",".join(MODULES),
            "--command", WITNESS_MODULE, "--interval", str(options.interval),
            "--short-every", str(options.short_every),
            "--short-validity", str(options.short_validity),
            "--cancel-every", str(options.cancel_every)])
        self.history.append((f"pilot:{PILOT}", pilot))
        pilot.wait_for(r'"ev": "ready"', 60)
        short = (f"1 in {options.short_every} valid {options.short_validity:g} s"
                 if options.short_every else "none short-lived")
        cancel = f"1 in {options.cancel_every} cancelled" if options.cancel_every else \
            "none cancelled"
        self.progress(f"everything up in {time.monotonic() - began:.0f} s; the pilot starts "
                      f"{', '.join(MODULES)} and sends count 1, 2, 3 ... to {WITNESS_MODULE}"
                      f" ({short}, {cancel})")
        self.wait_usable(time.time(), 240, "the pilot to start every module and command "
                         f"{WITNESS_MODULE}")

    def _started(self, name: str, proc: Proc) -> None:
        self.history.append((f"{self.topology.table[name].pc}:{name}", proc))

    # -- what the pilot and the witness say --------------------------------------------

    def poll(self) -> None:
        """Take in the pilot's new lines and the witness's new executions."""
        pilot = self.topology.pilot.processes.get(PILOT)
        lines = pilot.lines[self._pilot_cursor:] if pilot is not None else []
        self._pilot_cursor += len(lines)
        for line in lines:
            if line.startswith("{"):
                self.record.take_pilot_event(json.loads(line))
        if self.witness_log.exists():
            with open(self.witness_log) as log:
                log.seek(self._executed_at)
                text = log.read()
            complete = text[:text.rfind("\n") + 1]   # a line being written waits for the next poll
            self._executed_at += len(complete)
            for execution in filter(None, map(parse_line, complete.splitlines())):
                self.record.take_execution(execution)
                if execution.seq is not None:
                    self.ran.add(execution.seq)

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
        """Every module shows a running state after ``back`` and the first plain command
        accepted after ``back`` was executed (a short-lived or cancelled one may rightly
        never run)."""
        from rosnodes.module_link import lifecycle_of

        for statuses in self.record.statuses.values():
            if not statuses or statuses[-1]["t"] < back or \
                    lifecycle_of(statuses[-1]["state"]) != "running":
                return False
        accepted = self.record.accepted
        first = len(accepted)
        while first > 0 and accepted[first - 1]["t"] >= back:
            first -= 1
        plain = [a for a in accepted[first:] if not a.get("validity") and not a.get("cancel")]
        return bool(plain) and plain[0]["seq"] in self.ran

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

    # -- the end -----------------------------------------------------------------------

    def drain(self, timeout: float) -> None:
        """Have the pilot send no more (it goes on watching), then give every command sent
        ``timeout`` s to end: run, or refused as expired, cancelled, or interrupted."""
        pilot = self.topology.pilot.processes[PILOT]
        if pilot.popen.poll() is None:
            pilot.popen.send_signal(signal.SIGUSR1)
            try:
                self.wait(lambda: self.record.drained, DRAINED_TIMEOUT,
                          "word from the pilot that it sends no more")
            except WaitTimeout as exc:
                self.progress(f"{exc}: counting what was sent so far")
        sent = self.sent()

        def unfinished() -> set:
            return {seq for _, seq in sent} - self.ran - set(self.ended(sent))

        try:
            self.wait(lambda: not unfinished(), timeout, "end of every command sent")
        except WaitTimeout:
            self.progress(f"{len(unfinished())} command(s) sent had neither run nor ended "
                          f"{timeout:.0f} s after the pilot stopped")
        pilot.interrupt()

    def lines_of(self, program: str) -> List[str]:
        """Every line of every incarnation of ``<pc>:<name>``, in order."""
        return [line for name, proc in self.history if name == program
                for line in list(proc.lines)]

    def sent(self) -> List[Tuple[int, int]]:
        """``(N, seq)`` the gateways wrote to the witness's port, in the order they did."""
        return sent_commands(self.lines_of("pilot:gateway"))

    def ended(self, sent: Sequence[Tuple[int, int]]) -> Dict[int, str]:
        """seq -> expired, cancelled or interrupted, for the commands that ended without
        running: what the pilot heard, and what the pilot bridge and the witness logged."""
        cancelled = self.record.cancelled() | \
            cancelled_by_bridge(self.lines_of("pilot:bridge_pilot"))
        expired = self.record.expired() | seqs_of_numbers(
            expired_at_module(self.lines_of(f"robot:{WITNESS_MODULE}")), sent, self.ran)
        return figures.endings(expired, cancelled, self.record.interrupted())

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
                pass  # already exited: nothing to kill
        shutil.rmtree(self.root, ignore_errors=True)
        return found
