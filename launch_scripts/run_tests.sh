#!/usr/bin/env bash
# Install what is missing, build the reference YARP 3.5 (cached), run the test suite.
# Extra arguments go to pytest (e.g. -k interop, -x).
set -euo pipefail
cd "$(dirname "$0")/.."
launch_scripts/bootstrap.sh
launch_scripts/build_reference_yarp.sh
# What CI has must be used, not skipped (tests/requirements.py): the interop suite runs
# against the reference YARP (and its devices), the emulated-network tests as root (namespaces, tc, nftables),
# the Pilot Interface's GUI tests under Xvfb, the ROS nodes' tests with ROS.
export WALKMAN_REQUIRE_REFERENCE=1
export WALKMAN_REQUIRE_REFERENCE_DEVICES=1
export WALKMAN_REQUIRE_ROOT=1
export WALKMAN_REQUIRE_XVFB=1
export WALKMAN_REQUIRE_ROS=1
# Hypothesis derandomised (tests/conftest.py's "ci" profile: the same examples every run, so a
# red run is reproducible and a green one is not luck), whether or not the CI system sets CI.
export WALKMAN_HYPOTHESIS_PROFILE=ci
# One pytest worker per core (WALKMAN_TEST_WORKERS=N to choose; 1: one test at a time).
# On a fast machine a third worker on 2 cores filled the CPU the robot's real-time waits left
# idle (the suite 13:21 -> 11:20; a fourth: 10:52 against 10:30).  On one 2.5 times slower
# (2026-11-28: a module's control tick 0.4-0.7 ms median against 0.15-0.25) three workers ran
# three topologies at once: the load average reached 73-82, a walking module's loop stalled
# 120 ms and its heartbeat 5 s, roscore gave up on its master after 10 s, and 5-8 tests
# failed in each of three runs (23-30 min); two workers there: 1 and 4 failures (PI click
# tests, the drive's throttle timing), 22:27 and 23:46, the load at most 25 and 52 -- better,
# not enough.  Then the HAL sent each reader only the rate it asked for (+period), an idle
# module's readers ran below every loop, and the PI's free-standing terrain course got the
# machine to itself (mark alone): fc61 passed whole there, 22:26, the load at most 12.
# The suite is CPU-bound: what shortens it is less CPU, and what keeps it honest is not
# starving the simulated robot's loops.  Every test takes its ports from the machine-wide
# registry (yarp_lite/freeport.py) and names its network namespaces after its process, so
# tests run side by side; each waits for what it needs, never for a time.  Work stealing over
# the folders heaviest first (tests/conftest.py) pairs one stream of topologies with lighter
# tests; starting the longest tests first on every worker (tried in e42e00d) ran four
# topologies at once, the load average reached 38 and the suite took 15 min.
# The tests that run no real-time thread (codecs, yarp_lite and real YARP processes, the PI's
# widgets, ROS nodes, the robot offline on simulated time) hold nothing and run beside the
# tests that have the machine to themselves, as CPU burners would: one worker begins with
# those tests, the other with the tests alone (tests/robot_slots.py).
workers=${WALKMAN_TEST_WORKERS:-$(nproc)}
parallel=()
if [[ $workers -gt 1 ]]; then parallel=(-n "$workers" --dist worksteal); fi
set +e
.venv/bin/python -m pytest tests -ra --durations=25 "${parallel[@]}" "$@"   # the 25 slowest: where the time goes
status=$?
set -e
if [[ $status -eq 5 ]]; then
  echo "[run_tests] pytest collected no tests: that is a failure" >&2
  exit 1
fi
exit $status
