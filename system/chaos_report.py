"""The chaos run's summary, its verdicts against the goals, and its two renderings.

Theory of operation
-------------------
:func:`summarize` gathers a run's records (:mod:`system.chaos_record`) into one
JSON-able dict through the pure figures of :mod:`system.chaos_figures`; the
verdicts compare each figure with its goal (:data:`GOALS`); :func:`table` is the
terminal's (and the report's) table of figures against goals and
:func:`markdown` the whole ``report.md``.  Nothing here touches a process or a
file.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path
from typing import Dict, List, Mapping, Sequence, Tuple

from system import chaos_figures as figures
from system.chaos_record import Record

GOALS = {"lost": 0, "duplicated": 0, "out_of_order": 0, "late": 0, "cancelled_ran": 0,
         "seen_p99_s": 10.0, "leaked_processes": 0, "leaked_ports": 0, "growth_percent": 10.0}
#: How long after a fault a command accepted then still counts as "around" it.
NEAR_ROUND_S = 120.0


def summarize(record: Record, sent: Sequence[Tuple[int, int]], ended: Mapping[int, str],
              options, emulated: bool, leaked: Dict[str, list], elapsed: float,
              interrupted: bool, failure: str) -> dict:
    """Everything the report says, from what the run recorded."""
    counted = figures.commands(sent, [a["seq"] for a in record.accepted], record.executed,
                               ended)
    asked = {a["seq"]: (a["t"], float(a.get("validity") or 0.0)) for a in record.accepted}
    checked = figures.deadlines(record.executions, asked, ended)
    seen = [r.seen_s for r in record.rounds if r.seen_s is not None]
    # the whole outage as the pilot lived it: the fault's own length plus the recovery
    outage = [r.back_at - r.killed_at + r.seen_s for r in record.rounds if r.seen_s is not None]
    modules = list(record.statuses)
    for cut in record.cuts:
        if "back" in cut:
            times = [figures.first_fresh(record.statuses[m], m, cut["back"]) for m in modules]
            cut["seen_s"] = (max(times) - cut["back"]) if None not in times else None
            if cut["seen_s"] is not None:
                seen.append(cut["seen_s"])
                outage.append(cut["back"] - cut["at"] + cut["seen_s"])
    soak = figures.soak_figures(record.samples, options.sample_every) if record.samples \
        else None
    completed = (record.soak_s >= options.soak * 60.0 - 1.0 if options.soak else
                 len([r for r in record.rounds if r.finished]) == options.rounds)
    values = {
        "sent": counted.sent, "accepted": counted.accepted, "executed": counted.executed,
        "short_lived": len([a for a in record.accepted if a.get("validity")]),
        "cancel_asked": len([a for a in record.accepted if a.get("cancel")]),
        "expired": len(counted.expired), "cancelled": len(counted.cancelled),
        "interrupted_commands": len(counted.interrupted),
        "lost": len(counted.lost), "duplicated": len(counted.duplicated),
        "out_of_order": len(counted.out_of_order),
        "late": len(checked.late), "cancelled_ran": len(checked.cancelled_ran),
        "deadline_checked": checked.checked, "closest_to_deadline_s": checked.closest_s,
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
        values["max_rss_growth_percent"] = max(
            (p["rss_percent"] for p in soak["processes"].values()), default=0.0)
        values["max_files_growth_percent"] = max(
            (p["files_percent"] for p in soak["processes"].values()), default=0.0)
        values["journals_bounded"] = all(j["bounded"] for j in soak["journal"].values())
    return {
        "tool": "walkman-chaos", "interrupted": interrupted, "failure": failure,
        "elapsed_s": elapsed, "soak_s": record.soak_s,
        "options": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(options).items()},
        "emulated": emulated, "figures": values,
        "goals": {**verdicts(values),
                  "run_completed": completed and not failure and not interrupted},
        "commands": {k: v[:100] if isinstance(v, list) else v
                     for k, v in asdict(counted).items()},
        "deadlines": {k: v[:100] if isinstance(v, list) else v
                      for k, v in asdict(checked).items()},
        "where": where_commands({**asdict(counted), **asdict(checked)}, record, sent),
        "rounds": [asdict(r) for r in record.rounds], "exits": record.exits,
        "pilot_errors": record.pilot_errors[-200:], "cuts": record.cuts, "soak": soak,
        "leaks": leaked,
    }


def verdicts(values: dict) -> Dict[str, bool]:
    """Each goal of the brief: met or not."""
    out = {name: values[name] <= GOALS[name]
           for name in ("lost", "duplicated", "out_of_order", "late", "cancelled_ran",
                        "leaked_processes", "leaked_ports")}
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


#: The kinds of command the report lists one by one: each must never happen.
WRONG = ("lost", "duplicated", "out_of_order", "late", "cancelled_ran")


def where_commands(wrong: Mapping[str, List[int]], record: Record,
                   sent: Sequence[Tuple[int, int]]) -> List[dict]:
    """For each command of a :data:`WRONG` kind: its N and the rounds around it."""
    number = {seq: n for n, seq in sent}
    when = {a["seq"]: a["t"] for a in record.accepted}
    out = []
    for kind in WRONG:
        for seq in wrong.get(kind, [])[:50]:
            at = when.get(seq)
            near = [r.fault.round for r in record.rounds
                    if at is not None and r.killed_at - 10 <= at <= r.back_at +
                    (r.usable_s or NEAR_ROUND_S)]
            out.append({"kind": kind, "seq": seq, "n": number.get(seq), "accepted_at": at,
                        "rounds": near})
    return out


def fmt(value, unit: str = "") -> str:
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
    short = f"valid {options.get('short_validity', 0):g} s"
    rows = [(played[1], played[0], "all", mark("run_completed")),
            ("commands sent / executed", f"{f['sent']} / {f['executed']}", "", ""),
            (f"  short-lived ({short}) / cancel asked",
             f"{f['short_lived']} / {f['cancel_asked']}", "", ""),
            ("  ended expired / cancelled / interrupted (not run)",
             f"{f['expired']} / {f['cancelled']} / {f.get('interrupted_commands', 0)}", "", ""),
            ("lost", fmt(f["lost"]), "0", mark("lost")),
            ("duplicated", fmt(f["duplicated"]), "0", mark("duplicated")),
            ("out of order", fmt(f["out_of_order"]), "0", mark("out_of_order")),
            ("ran after their deadline", fmt(f["late"]), "0", mark("late")),
            ("  (short-lived that ran: least time left)",
             f"{f['deadline_checked']}: {fmt(f['closest_to_deadline_s'], ' s')}", "", ""),
            ("cancelled, yet ran", fmt(f["cancelled_ran"]), "0", mark("cancelled_ran")),
            ("pilot sees the modules again, median", fmt(f["seen_median_s"], " s"), "", ""),
            ("pilot sees the modules again, p99", fmt(f["seen_p99_s"], " s"), "<= 10 s",
             mark("seen_p99_s")),
            ("  (from the fault's start: median, p99)",
             f"{fmt(f['outage_median_s'])}, {fmt(f['outage_p99_s'], ' s')}", "", ""),
            ("rounds not recovered", fmt(f["unrecovered_rounds"]), "0",
             mark("every_round_recovered")),
            ("leaked processes", fmt(f["leaked_processes"]), "0", mark("leaked_processes")),
            ("leaked ports", fmt(f["leaked_ports"]), "0", mark("leaked_ports")),
            ("leaked emulated hosts", fmt(f["leaked_namespaces"]), "0",
             mark("leaked_namespaces"))]
    if "max_rss_growth_percent" in f:
        rows += [("largest RSS growth of a process", fmt(f["max_rss_growth_percent"], " %"),
                  "< 10 %", mark("max_rss_growth_percent")),
                 ("largest open-files growth", fmt(f["max_files_growth_percent"], " %"),
                  "< 10 %", mark("max_files_growth_percent")),
                 ("journals bounded", "yes" if f["journals_bounded"] else "no", "yes",
                  mark("journals_bounded"))]
    rows += [("programs that exited by themselves", fmt(f["unexpected_exits"]), "", ""),
             ("executed, never acknowledged", fmt(f["unacknowledged"]), "", ""),
             ("pilot retries that ran twice", fmt(f["retried_twice"]), "", "")]
    width = max(len(r[0]) for r in rows)
    lines = [f"{'figure':<{width}}  {'value':>12}  goal",
             f"{'-' * width}  {'-' * 12}  {'-' * 8}  {'-' * 6}"]
    lines += [f"{name:<{width}}  {value:>12}  {goal:<8}  {verdict}".rstrip()
              for name, value, goal, verdict in rows]
    return "\n".join(lines)


DEFINITIONS = (
    "*Lost*: logged as sent by the gateway (the bridge acknowledged it), never executed by "
    "the witness, and neither expired nor cancelled nor interrupted; *duplicated*: executed "
    "twice; *out of order*: executed after a command sent later.  *Expired*: refused by the "
    "module as older than its validity (every few commands are sent short-lived); "
    "*cancelled*: taken back by the pilot (`/counter/cancel`) while the pilot bridge still "
    "held it; *interrupted*: the module's process was killed holding it, and its next process "
    "said so and did not run it -- all told by "
    "`/pilot/command_states`, the gateway's answer, or the bridge's and the module's logs.  "
    "*Ran after their deadline*: the witness started it with a lifetime already past its "
    "validity, or later than the pilot's send time + validity + "
    f"{figures.DEADLINE_SLACK:g} s (the hops a lifetime does not count); *cancelled, yet ran*: "
    "executed although the cancel said it was taken back.  *Seen again*: from the end of the "
    "fault (the program started again, the link back) until the pilot has a status of every "
    "module newer than the last one before; the line below counts from the fault's start.  "
    "*Usable*: every module running and the first plain command (neither short-lived nor "
    "cancelled) accepted after the fault executed.")


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
    out += ["```", table(summary), "```", "", DEFINITIONS, ""]
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
                       f"{fault['down']:.1f} | {r['pid'] or ''} | {fmt(r['up_s'])} | "
                       f"{fmt(r['seen_s'])} | {fmt(r['usable_s'])} | {problem} |")
        out += ["", "## Recovery by victim", "", "| victim | rounds | seen median s | seen max s |",
                "|---|---|---|---|"]
        by_victim: Dict[str, List[float]] = {}
        for r in summary["rounds"]:
            if r["seen_s"] is not None:
                by_victim.setdefault(r["fault"]["victim"], []).append(r["seen_s"])
        for victim, values in sorted(by_victim.items()):
            out.append(f"| {victim} | {len(values)} | "
                       f"{fmt(figures.percentile(values, 0.5))} | {fmt(max(values))} |")
    if summary["cuts"]:
        out += ["", "## Blackouts", "", "| at | seconds | seen s |", "|---|---|---|"]
        out += [f"| {time.strftime('%H:%M:%S', time.localtime(c['at']))} | {c['seconds']:.1f} | "
                f"{fmt(c.get('seen_s'))} |" for c in summary["cuts"]]
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
        out += ["", "## Commands lost, duplicated, out of order, late or cancelled yet run", "",
                "| kind | seq | N | accepted at | rounds around it |", "|---|---|---|---|---|"]
        out += [f"| {w['kind']} | {w['seq']} | {w['n']} | {fmt(w['accepted_at'])} | "
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
