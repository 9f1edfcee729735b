"""``walkman-chaos``: kill -9 the DRC system's programs and cut its link while a pilot commands it.

Theory of operation
-------------------
The ``drc`` topology (:class:`~system.topology.Topology`: robot PC and pilot PC,
each with its yarp-lite server and roscore, the HAL, the modules, both bridges,
the pilot gateway) runs on two emulated hosts (:mod:`netem.emulation`,
namespaces ``wmchaos_*``) or, with ``--loopback`` or without root, on this
host.  Two more programs make it measurable:

* the **witness** (:mod:`walkman.modules.witness`, shipped in the package), a
  GYM module ``/counter`` on the robot, added to the bridge configuration: it
  appends (and fsyncs) every command it executes, when, and with what
  lifetime, to ``executed.log``;
* the **pilot** (:mod:`system.chaos_pilot`), a ROS node on the pilot PC that
  keeps ``counter``, ``gaze_control`` and ``temperature`` running and sends
  ``count N`` to ``counter`` through the gateway's ``send_command`` service,
  as a pilot does, N after N, trying again until the gateway accepts it;
  every ``--short-every``-th with a validity of ``--short-validity`` seconds,
  every ``--cancel-every``-th taken back at once with ``/counter/cancel``, and
  it follows every command's life on ``/pilot/command_states``.

A seeded schedule (:func:`system.chaos_figures.schedule`) then plays rounds
(:mod:`system.chaos_run`): some normal work, a fault -- SIGKILL to one
program with its children (either name server, either roscore, the HAL, a
module, either bridge, the gateway) or a link cut (``ip link down`` or 100 %
loss) --, a short random delay, the program started again as its launcher
would (the link restored), and then the tool waits until the pilot *sees*
every module again and until the pilot can *use* them again.  ``--soak
MINUTES`` plays no kills: blackouts and /proc samples instead
(:mod:`system.chaos_soak`).

At the end the pilot stops sending, the commands in flight end (run, expired
or cancelled), and the figures come from the records
(:mod:`system.chaos_record`, :mod:`system.chaos_figures`): what the gateway
logged as sent, what the witness executed, what the pilot saw.  No command
may be lost, duplicated, reordered, run after its deadline, or run after it
was cancelled.  Then everything is stopped -- also on Ctrl-C or a failure --
and what is left is counted (:mod:`system.chaos_proc`: every program carries
``WALKMAN_CHAOS_RUN=<id>``, so a process still alive with it is a leak, and
so is every socket it holds; the emulated hosts must be gone).

The report (:mod:`system.chaos_report`: figures, every round, the schedule,
the samples, every program's log) goes to ``out/chaos-<time>/``; the command
line ends with the table of figures against their goals, and exits 1 when one
is missed.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional

from netem.emulation import EmulatedLink, EmulationError
from system import chaos_figures as figures
from system.chaos_figures import LINK
from system.chaos_report import fmt, markdown, summarize, table
from system.chaos_run import WITNESS, Chaos, ChaosError, say, victims
from system.chaos_soak import soak
from system.processes import REPO, WaitTimeout
from system.topology import add_link_arguments, components

DEFAULT_SKIP = ("rosbag",)          # a 30-minute bag of everything is not what is measured


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
            soak(chaos, options.soak)
        else:
            play_rounds(chaos, options, progress)
        progress("stopping the pilot's commands; commands in flight end")
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
    sent = chaos.sent()
    summary = summarize(chaos.record, sent, chaos.ended(sent), options, chaos.link is not None,
                        leaked, time.monotonic() - began, interrupted, failure)
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
                f" up in {fmt(result.up_s, ' s')}")
        record = chaos.record
        progress(f"round {fault.round:>3}/{len(faults)}  {what};  seen in "
                 f"{fmt(result.seen_s, ' s')}, usable in {fmt(result.usable_s, ' s')};  "
                 f"commands {len(record.accepted)} accepted, {len(record.executed)} run, "
                 f"{len(record.expired())} expired, {len(record.cancelled())} cancelled"
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
    parser.add_argument("--short-every", type=int, default=5, metavar="K",
                        help="every K-th command short-lived (default 5; 0: none)")
    parser.add_argument("--short-validity", type=float, default=3.0, metavar="SECONDS",
                        help="the validity of a short-lived command (default 3)")
    parser.add_argument("--cancel-every", type=int, default=7, metavar="K",
                        help="cancel every K-th command as soon as it is accepted "
                             "(default 7; 0: none)")
    parser.add_argument("--sample-every", type=float, default=5.0,
                        help="soak: seconds between two samples (default 5)")
    parser.add_argument("--drain", type=float, default=60.0,
                        help="seconds the last commands may take to end (default 60)")
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
    if options.short_every < 0 or options.cancel_every < 0 or \
            not 0 < options.short_validity <= 86400:
        parser.error("--short-every and --cancel-every must be 0 or more, --short-validity "
                     "in (0, 86400] seconds")
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
    from nodekit.msgs import generate

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
