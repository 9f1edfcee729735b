"""The README's main job, run as a user runs it, judged by what it tells the user: the verdict it
prints, and every latency figure of its report, each backed by a receipt and within reason.

Both link profiles a pilot meets: ``drc`` (1 Mbit/s, 5 % loss) and ``degraded`` (9600 bit/s).
Each runs the scripted session in the lab topology and then in the DRC one, as root over the
emulated hosts; one after the other, since both build the same emulated network.
"""

from __future__ import annotations

import re
import statistics
import sys

import pytest

from harness import dump_outputs_if_failed
from system.processes import Proc

PYTHON = sys.executable
#: The most a command may take to be answered, per profile (ms): the lab answers in tens of
#: ms; the DRC link adds its delay and retransmissions, the degraded radio its 9600 bit/s.
SANE_MS = {"lab": 2_000, "drc": 5_000, "degraded": 20_000}
ROW = re.compile(r"^\| (?P<name>[^|]+?) \| (?P<lab>[^|]+?) \| (?P<drc>[^|]+?) \|$")


def latency_rows(report: str) -> list:
    """The rows of the report's command latency table, as the user reads them."""
    section = report.split("## Command latency", 1)[1].split("\n## ", 1)[0]
    return [match.groupdict() for line in section.splitlines()
            if (match := ROW.match(line)) and not line.startswith(("| command", "|---"))]


@pytest.mark.requires("root")
@pytest.mark.two_pcs
def test_the_main_job_tells_the_truth_on_both_links(tmp_path, request):
    runs = []
    try:
        for profile in ("drc", "degraded"):
            out = tmp_path / profile
            job = Proc([PYTHON, "-m", "system.mainjob", "--profile", profile, "--out", str(out)],
                       None, f"main job ({profile})")
            runs.append(job)
            code = job.wait(timeout=1200)
            said = job.output()
            assert "verdict: no observable difference" in said, said[-3000:]
            assert code == 0, said[-3000:]
            check_latencies((out / "report.md").read_text(), said, profile)
    finally:
        dump_outputs_if_failed(request, runs)


def check_latencies(report: str, said: str, profile: str) -> None:
    rows = latency_rows(report)
    assert len(rows) >= 5, f"the report's latency table has {len(rows)} rows:\n{report}"
    figures = {"lab": [], "drc": []}
    for row in rows:
        for side in ("lab", "drc"):
            value = row[side]
            assert value.isdigit(), f"{row['name']} ({side}): {value!r}, not a figure backed " \
                                    f"by its receipt"
            ms = int(value)
            limit = SANE_MS["lab" if side == "lab" else profile]
            assert 0 <= ms <= limit, f"{row['name']} ({side}, {profile}): {ms} ms"
            figures[side].append(ms)
    medians = re.search(r"command -> receipt latency, median: lab (\d+) ms, drc (\d+) ms", said)
    assert medians, said[-2000:]
    for side, shown in zip(("lab", "drc"), medians.groups()):
        assert abs(int(shown) - statistics.median(figures[side])) <= 1, \
            f"the summary's {side} median {shown} ms is not the table's"
