#!/usr/bin/env bash
# The pilot PC: its name servers (yarp-lite server + roscore), then its programs in any order.
#   launch_scripts/pilot_pc.sh --peer <the other PC's address> [options: --help]
# Run launch_scripts/bootstrap.sh once first.  Ctrl-C stops everything.
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python -m system.pc pilot "$@"
