"""The benchmarks still run: every script answers --help, and the quickest runs whole.

A benchmark nobody runs breaks quietly (bench_yarp_lite's child roles printed
the machine line into the JSON their parent parsed, and the script failed for
weeks).  The figures are not checked here -- speed is for the benchmarks, not
the tests -- only that each script starts and that bench_yarp_lite's smoke run
prints every table.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
SCRIPTS = sorted(path.name for path in BENCH.glob("bench_*.py"))


def test_every_benchmark_is_found():
    assert "bench_yarp_lite.py" in SCRIPTS and len(SCRIPTS) >= 8


@pytest.mark.parametrize("script", SCRIPTS)
def test_a_benchmark_starts_and_explains_itself(script):
    result = subprocess.run([sys.executable, str(BENCH / script), "--help"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "usage:" in result.stdout


@pytest.mark.requires("reference")
def test_bench_yarp_lite_smoke_run_prints_every_table():
    result = subprocess.run([sys.executable, str(BENCH / "bench_yarp_lite.py"), "--smoke"],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    for heading in ("RPC round trip", "Server side: a C++ RpcClient", "One-way throughput",
                    "Name server"):
        assert heading in result.stdout, result.stdout
    assert "(n/a)" not in result.stdout, result.stdout


def test_the_stop_bench_reads_click_to_held_from_the_bridges_own_log_lines(monkeypatch):
    """bench_stop_all's *held* comes from the lines both bridges log for each stop, with the
    wall-clock time WALKMAN_LOG_TIME puts first: made here by the real stop line's two ends
    and the real log format, not typed in."""
    import logging

    from bridge.gym.stop_line import Ack, PilotStops, RobotStops
    from nodekit.logs import LOG_TIME_ENV, line_format

    sys.path.insert(0, str(BENCH))
    try:
        import bench_stop_all
    finally:
        sys.path.remove(str(BENCH))
    monkeypatch.setenv(LOG_TIME_ENV, "1")
    lines = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            lines.append(self.format(record))

    keep = Keep()
    keep.setFormatter(logging.Formatter(line_format("bridge")))
    logger = logging.getLogger("bridge.stop")
    level = logger.level
    logger.addHandler(keep)
    logger.setLevel(logging.INFO)
    try:
        robot = RobotStops(lambda word, stop_id: Ack(stop_id, "held", True, 2.5),
                           lambda ack, again: pilot.on_ack(ack))
        pilot = PilotStops(lambda order, again: robot.on_order(order))
        ack = pilot.order("stop_all", timeout=5.0)
        unanswered = PilotStops(lambda order, again: None).order("stop_all", timeout=0.3)
    finally:
        logger.removeHandler(keep)
        logger.setLevel(level)
    assert ack is not None and unanswered is None
    held, never = bench_stop_all.held_times(lines, lines)
    assert len(held) == 1 and never == 1, lines          # the unanswered one never held
    assert 2.5 <= held[0] < 2.5 + 1000, held             # the robot's 2.5 ms, and the way there
