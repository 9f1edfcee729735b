#!/usr/bin/env bash
# Build the reference YARP 3.5 (C++) from the PyPI sdist, the peer yarp_lite must
# interoperate with byte for byte. Idempotent: an existing build is reused.
#
# Usage: launch_scripts/build_reference_yarp.sh [--print-prefix]
# Result: $WALKMAN_YARP_PREFIX (default ~/.cache/walkman/yarp-3.5.0) holds bin/yarp,
# bin/yarpserver, bin/yarpdev, the libraries and the device plugins the HAL is compared
# with (controlboardwrapper2 + fakeMotionControl, remote_controlboard, analogServer,
# inertial + fakeIMU); tests find it there (see tests/requirements.py).
set -euo pipefail

VERSION=3.5.0
SHA256=7a8f78e1b6d3477fcd5e73fd5839ebf6971c3c0f5d3208d3ec0ee2b0c44507b9
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/walkman"
PREFIX="${WALKMAN_YARP_PREFIX:-$CACHE/yarp-$VERSION}"

if [[ "${1:-}" == "--print-prefix" ]]; then echo "$PREFIX"; exit 0; fi

# What the build holds; a cached build made with another list is rebuilt (incrementally).
FEATURES="core devices:controlboardwrapper2,fakeMotionControl,remote_controlboard,analogServer,fakeAnalogSensor,inertial,fakeIMU"
if [[ -x "$PREFIX/bin/yarpserver" && -x "$PREFIX/bin/yarpdev" && "$(cat "$PREFIX/.complete" 2>/dev/null)" == "$FEATURES" ]]; then
  echo "reference YARP $VERSION already built in $PREFIX"
  exit 0
fi

say() { echo "[build_reference_yarp] $*"; }
need=()
for pkg in cmake g++ make ycm-cmake-modules libeigen3-dev; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if ((${#need[@]})); then
  say "installing build tools: ${need[*]}"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
fi

mkdir -p "$CACHE"
tarball="$CACHE/yarp_middleware-$VERSION.tar.gz"
if ! echo "$SHA256  $tarball" | sha256sum -c --status 2>/dev/null; then
  # The project's venv (made by bootstrap.sh) has pip; Debian's python3 may not.
  PIP_PYTHON="$(cd "$(dirname "$0")/.." && pwd)/.venv/bin/python"
  [[ -x $PIP_PYTHON ]] || PIP_PYTHON=python3
  say "downloading the yarp-middleware $VERSION sdist with pip"
  part="$CACHE/download.part"
  rm -rf "$part" && mkdir -p "$part"
  # The sdist is the whole YARP source; pip downloads it (its build tools come as wheels, only to read its metadata).
  "$PIP_PYTHON" -m pip download -q --disable-pip-version-check --no-deps --no-binary yarp-middleware \
    -d "$part" "yarp-middleware==$VERSION" 2>&1 | tail -5 || true
  got="$part/yarp_middleware-$VERSION.tar.gz"
  [[ -f $got ]] || { say "pip could not download yarp-middleware==$VERSION"; exit 1; }
  echo "$SHA256  $got" | sha256sum -c --status || { say "checksum mismatch for the yarp-middleware sdist"; exit 1; }
  mv "$got" "$tarball" && rm -rf "$part"
fi

src="$CACHE/src/yarp_middleware-$VERSION"
if [[ ! -f "$src/CMakeLists.txt" ]]; then
  mkdir -p "$CACHE/src"
  tar -xzf "$tarball" -C "$CACHE/src"
fi

# YARP 3.5 misses standard includes that GCC 12 no longer pulls in transitively.
includes="-include utility -include cstdint -include limits -include iterator -include algorithm"
includes+=" -include string -include functional -include memory -include stdexcept -include cstring -include array"
build="$CACHE/build/yarp-$VERSION"
mkdir -p "$build"
say "configuring (log: $build/configure.log)"
cmake -S "$src" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$PREFIX" \
  -DSKIP_ACE=ON -DYARP_COMPILE_BINDINGS=OFF -DYARP_COMPILE_GUIS=OFF -DYARP_COMPILE_TESTS=OFF \
  -DYARP_COMPILE_EXAMPLES=OFF -DYARP_COMPILE_UNMAINTAINED=OFF -DYARP_COMPILE_DEVICE_PLUGINS=ON \
  -DYARP_COMPILE_libYARP_math=ON -DENABLE_yarpmod_fakeMotionControl=ON -DENABLE_yarpmod_fakeIMU=ON \
  -DENABLE_yarpmod_fakeAnalogSensor=ON -DYARP_COMPILE_CARRIER_PLUGINS=OFF \
  -DCMAKE_CXX_FLAGS="$includes" >"$build/configure.log" 2>&1 || { tail -30 "$build/configure.log"; exit 1; }
say "compiling with $(nproc) jobs, about 15 minutes on 2 cores (log: $build/build.log)"
start=$SECONDS
cmake --build "$build" -j"$(nproc)" >"$build/build.log" 2>&1 &
pid=$!
while kill -0 "$pid" 2>/dev/null; do
  sleep 30
  pct=$(grep -o '^\[ *[0-9]*%\]' "$build/build.log" | tail -1 | tr -d '[]% ' || true)
  say "  ${pct:-0}% after $((SECONDS - start)) s"
done
wait "$pid" || { tail -40 "$build/build.log"; exit 1; }
cmake --install "$build" >"$build/install.log" 2>&1 || { tail -20 "$build/install.log"; exit 1; }
echo "$FEATURES" > "$PREFIX/.complete"
say "done in $((SECONDS - start)) s: $PREFIX/bin/yarpserver"
