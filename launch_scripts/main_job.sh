#!/usr/bin/env bash
# Install what is missing and run the main job (see README).
set -euo pipefail
cd "$(dirname "$0")/.."
launch_scripts/bootstrap.sh
exec .venv/bin/python -m system.mainjob "$@"
