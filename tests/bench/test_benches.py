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
