"""The reference YARP 3.5 build: where it is, and compiling C++ helpers against it.

The interop tests and the benchmarks compare yarp_lite with the real YARP
built by ``launch_scripts/build_reference_yarp.sh`` (in
``~/.cache/walkman/yarp-3.5.0`` unless ``WALKMAN_YARP_PREFIX`` says otherwise).
Small C++ programs (a Bottle oracle, a benchmark peer) are compiled against it
once and cached by source hash.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
from pathlib import Path
from typing import Optional

CACHE = Path(os.environ.get("XDG_CACHE_HOME", str(Path.home() / ".cache"))) / "walkman"

MISSING = ("reference YARP 3.5 not built: run launch_scripts/build_reference_yarp.sh "
           "(the README's test command does it)")

# YARP 3.5 headers rely on includes GCC 12 no longer provides transitively.
_FORCED_INCLUDES = ("utility", "cstdint", "limits", "string", "functional", "memory",
                    "vector", "algorithm", "stdexcept", "cstring", "array")


DEVICES_MISSING = ("reference YARP 3.5 built without its devices (controlboardwrapper2, "
                   "fakeMotionControl, remote_controlboard): run "
                   "launch_scripts/build_reference_yarp.sh (the README's test command does it)")


def devices() -> Optional[Path]:
    """The plugin data dir (for YARP_DATA_DIRS) when the devices are built, else None."""
    root = prefix()
    if root is None or not (root / "lib" / "yarp" / "yarp_controlboardwrapper2.so").is_file() \
            or not (root / "lib" / "yarp" / "yarp_fakeMotionControl.so").is_file() \
            or not (root / "bin" / "yarpdev").is_file():
        return None
    return root / "share" / "yarp"


def prefix() -> Optional[Path]:
    """Install prefix of the reference build, or None when it is not built."""
    root = Path(os.environ.get("WALKMAN_YARP_PREFIX", str(CACHE / "yarp-3.5.0")))
    if (root / "bin" / "yarpserver").is_file() and (root / "bin" / "yarp").is_file():
        return root
    return None


def compile_cpp(source: Path, name: str, libraries: tuple = ("YARP_os", "YARP_init")) -> Path:
    """Compile ``source`` against the reference YARP; reuse a cached binary."""
    root = prefix()
    if root is None:
        raise RuntimeError(MISSING)
    digest = hashlib.sha256(source.read_bytes() + " ".join(libraries).encode()).hexdigest()[:16]
    target = CACHE / "helpers" / f"{name}-{digest}"
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    includes = [flag for header in _FORCED_INCLUDES for flag in ("-include", header)]
    command = ["g++", "-O2", "-std=c++17", *includes, str(source), f"-I{root / 'include'}",
               f"-L{root / 'lib'}", *(f"-l{library}" for library in libraries),
               f"-Wl,-rpath,{root / 'lib'}",
               "-lpthread", "-o", f"{target}.{os.getpid()}.tmp"]   # two test workers may race
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"compiling {source} failed:\n{result.stderr[-2000:]}")
    os.replace(f"{target}.{os.getpid()}.tmp", target)
    return target
