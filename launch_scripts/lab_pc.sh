#!/usr/bin/env bash
# The lab PC (the paper's lab setting, one PC for robot and pilot): its name servers (yarp-lite server + roscore), then its programs in any order.
#   launch_scripts/lab_pc.sh [options: --help]
# Run launch_scripts/bootstrap.sh once first.  Ctrl-C stops everything.
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python -m system.pc lab "$@"
