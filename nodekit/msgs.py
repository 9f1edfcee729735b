"""The ``walkman_msgs`` ROS package: generate its Python code with Debian's genpy.

``python -m nodekit.msgs`` writes ``build/ros/lib/walkman_msgs/{msg,srv}``;
``launch_scripts/walkman_env.sh`` then puts it on ``PYTHONPATH`` and the package
on ``ROS_PACKAGE_PATH``, so ``rosmsg show walkman_msgs/Status`` and
``rostopic pub /gaze_control/switch walkman_msgs/Switch ...`` work from any shell.
Skips the work when the generated files are newer than the definitions.

Every ROS program of ours calls :func:`ensure_importable` as it starts, and a launcher starts
them all at once: the generation holds a lock (``flock`` on a file beside the output), so a
program never imports a file another one is half-way through writing.  A process that had
the output folder on ``sys.path`` before it existed (``PYTHONPATH`` from
``walkman_env.sh`` on a fresh checkout) remembers that folder as empty until the import
system's caches are invalidated: the gateway's ROS thread then died with "No module named
'walkman_msgs'" and the gateway never came up.
"""

from __future__ import annotations

import fcntl
import importlib
import sys
from pathlib import Path
from typing import List

PACKAGE = "walkman_msgs"
SOURCE = Path(__file__).resolve().parents[1] / "rosnodes" / PACKAGE   # the ROS package
REPO = SOURCE.parents[1]
OUTPUT = REPO / "build" / "ros" / "lib"
SHARE = REPO / "build" / "ros" / "share"
SEARCH = {"std_msgs": Path("/usr/share/std_msgs/msg")}


def _stale(kind: str, output: Path) -> List[Path]:
    sources = sorted((SOURCE / kind).glob(f"*.{kind}"))
    target = output / PACKAGE / kind
    newest = max((p.stat().st_mtime for p in sources), default=0)
    built = [target / f"_{p.stem}.py" for p in sources]
    if all(b.exists() and b.stat().st_mtime >= newest for b in built) and \
            (target / "__init__.py").exists():
        return []
    return sources


def generate(force: bool = False, output: Path = OUTPUT) -> bool:
    """Generate what is out of date into ``output``; True when something was written.
    One process at a time: the others wait, then find it up to date."""
    try:
        output.mkdir(parents=True, exist_ok=True)
        lock = open(output / ".generating.lock", "w")
    except OSError:     # a read-only install: up to date, or _generate says what it cannot
        return _generate(force, output)
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)    # released when the file closes, or the holder dies
        return _generate(force, output)


def _generate(force: bool, output: Path) -> bool:
    import genpy.generator
    import genpy.genpy_main

    missing = [name for name, path in SEARCH.items() if not path.is_dir()]
    if missing:
        raise SystemExit(f"nodekit.msgs: message definitions of {missing} are not installed "
                         f"(apt-get install ros-std-msgs)")
    wrote = False
    includes = [f"-I{PACKAGE}:{SOURCE / 'msg'}"] + [f"-I{n}:{p}" for n, p in SEARCH.items()]
    for kind, generator in (("msg", genpy.generator.MsgGenerator()),
                            ("srv", genpy.generator.SrvGenerator())):
        sources = sorted((SOURCE / kind).glob(f"*.{kind}")) if force else _stale(kind, output)
        if not sources:
            continue
        target = output / PACKAGE / kind
        target.mkdir(parents=True, exist_ok=True)
        base = ["gen", "-p", PACKAGE, "-o", str(target), *includes]
        for argv in (base + [str(p) for p in sources], base + ["--initpy"]):
            try:
                genpy.genpy_main.genmain(argv, f"gen{kind}_py", generator)
            except SystemExit as exit_:  # genmain always exits
                if exit_.code:
                    raise SystemExit(f"nodekit.msgs: genpy failed on {kind} ({exit_.code})")
        wrote = True
    package_init = output / PACKAGE / "__init__.py"
    if not package_init.exists():
        package_init.write_text("")
    _declare_dependencies()
    return wrote


def _declare_dependencies() -> None:
    """Debian ships std_msgs' .msg files without a package.xml; rospack needs one."""
    for name, path in SEARCH.items():
        package = SHARE / name
        package.mkdir(parents=True, exist_ok=True)
        manifest = package / "package.xml"
        if not manifest.exists():
            manifest.write_text(f'<?xml version="1.0"?>\n<package format="2"><name>{name}</name>'
                                f'<version>0.0.0</version><description>{name} as installed by '
                                f'Debian ({path})</description><maintainer email="none@invalid">'
                                f'none</maintainer><license>BSD</license></package>\n')
        link = package / "msg"
        if not link.exists():
            link.symlink_to(path)


def ensure_importable(output: Path = OUTPUT) -> None:
    """Make ``import walkman_msgs`` work in this process (generating into ``output`` if
    needed)."""
    generate(output=output)
    if str(output) not in sys.path:
        sys.path.insert(0, str(output))
    importlib.invalidate_caches()   # a folder seen missing before is looked at again


if __name__ == "__main__":
    changed = generate(force="--force" in sys.argv)
    print(f"[walkman_msgs] {'generated' if changed else 'up to date'} in {OUTPUT / PACKAGE}")
