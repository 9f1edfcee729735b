#!/usr/bin/env bash
# Install what is missing on a Debian bookworm machine and prepare .venv/.
# Idempotent: packages already present are skipped, an up-to-date venv is reused.
#
# Usage (as root): launch_scripts/bootstrap.sh
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
say() { echo "[bootstrap] $*"; }

DEBIAN_PACKAGES=(
  ros-core python3-rospy python3-std-msgs python3-sensor-msgs python3-geometry-msgs
  python3-genpy python3-genmsg python3-rosbag python3-rosmsg python3-rostopic
  python3-rosservice python3-roslaunch
  ros-std-msgs ros-sensor-msgs ros-geometry-msgs python3-tf2-msgs
  libosmesa6 nftables iproute2 python3-venv python3-dev g++ cmake make curl
  ycm-cmake-modules libsqlite3-dev libeigen3-dev
  python3-pyqt5 python3-python-qt-binding rviz python3-rviz python3-interactive-markers
  python3-visualization-msgs ros-visualization-msgs xvfb xauth
)

missing=()
for pkg in "${DEBIAN_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  if [[ $EUID -ne 0 ]]; then
    echo "[bootstrap] missing Debian packages: ${missing[*]}; run as root to install them" >&2
    exit 1
  fi
  say "installing Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  say "Debian packages already installed"
fi

VENV=$ROOT/.venv
if [[ ! -x $VENV/bin/python ]]; then
  say "creating $VENV (system site packages visible, for rospy)"
  /usr/bin/python3 -m venv --system-site-packages "$VENV"
fi

PY_PACKAGES=(numpy mujoco pin lxml opencv-python-headless pytest pytest-xdist hypothesis matplotlib atheris)
stamp=$VENV/.walkman-installed
want="$(sha256sum setup.py | cut -d' ' -f1) ${PY_PACKAGES[*]}"
if [[ ! -f $stamp || "$(cat "$stamp")" != "$want" ]]; then
  say "installing Python packages into .venv: ${PY_PACKAGES[*]} and this project"
  "$VENV/bin/pip" install -q --disable-pip-version-check "${PY_PACKAGES[@]}" 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/pip" install -q --disable-pip-version-check -e "$ROOT" 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/python" -c "import numpy, mujoco, pinocchio, lxml, cv2, pytest, xdist, hypothesis, rospy, yarp_lite, PyQt5.QtTest, rviz" \
    || { echo "[bootstrap] the virtual environment is incomplete" >&2; exit 1; }
  echo "$want" > "$stamp"
else
  say "Python packages already installed in .venv"
fi
say "generating the walkman_msgs ROS messages (skipped when up to date)"
"$VENV/bin/python" -m nodekit.msgs
# Every module, node, bridge and test helper runs as its own Python process.  Where the
# environment sets PYTHONDONTWRITEBYTECODE (as some sandboxes and CI images do), none of them
# writes its bytecode, so each compiled the project's sources again on every start: 0.1-0.45 s
# of CPU per start (measured on 2 slow cores, 2026-11-28).  Compiled here once (compileall
# writes regardless), they are read, not compiled.
say "byte-compiling the project (each of its processes then starts without compiling it)"
"$VENV/bin/python" -m compileall -q -j 0 walkman yarp_lite bridge rosnodes pilot nodekit system \
  tests bench fuzz build/ros > /dev/null
say "ready: source launch_scripts/walkman_env.sh (ROS tools, messages and .venv/bin on PATH)"
