"""``pip install .`` into a fresh venv: the installed tools need nothing from the source tree.

Issue 30: ``walkman-chaos`` started ``tests.bridge.counting_module``, which no
distribution contains.  Here the tree is copied (a build must not write into the
shared source tree), installed without dependencies into a new venv, and used
from an empty folder with no ``PYTHONPATH``: ``walkman-chaos --help`` works, the
witness it starts is the installed package's, and it writes its log line.

The new venv finds its dependencies (numpy, lxml, rospy...) in the development
venv's site-packages through one path line.  Lines of a ``.pth`` file are put on
``sys.path`` as they are: the ``.pth`` files *inside* that folder -- among them
the editable install that points at the source tree -- are not read, which the
test checks before trusting anything else.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from system.topology import REPO

#: Not part of a source tree's ``pip install .``: VCS, environments, build and run outputs.
NOT_SOURCE = shutil.ignore_patterns(".git", ".venv", "build", "out", "*.egg-info", "__pycache__",
                                    ".pytest_cache", ".hypothesis", "*.pyc")

PROBE = r"""
import importlib.metadata, json, os, sys
from system import chaos_run
from walkman.gym.interfaces import RecordingInterfaces
from walkman.gym.runner import load_module_class
from walkman.hal import virtual_board
from walkman.modules import witness

spec = chaos_run.WITNESS.argv[chaos_run.WITNESS.argv.index("walkman.gym.supervisor") + 1]
module_class = load_module_class(spec)
os.environ[witness.LOG_VARIABLE] = "executed.log"
interfaces = RecordingInterfaces("/counter", module_class)
module = module_class("witness", {}, interfaces)
module.custom_init()
interfaces.commands.feed(["count", 5])
module.run()
module.custom_release()
files = [str(f) for f in importlib.metadata.files("walkman-architecture")]
print(json.dumps({"spec": spec, "class_file": sys.modules[module_class.__module__].__file__,
                  "board_file": virtual_board.__file__, "files": files,
                  "ran": [e.seq for e in witness.read_log("executed.log")]}))
"""


def run(argv, cwd: Path, env: dict, timeout: float = 300) -> subprocess.CompletedProcess:
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert done.returncode == 0, f"{argv}: {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done


def test_an_installed_walkman_chaos_runs_its_witness_from_the_package(tmp_path):
    source, venv, elsewhere = tmp_path / "source", tmp_path / "venv", tmp_path / "elsewhere"
    shutil.copytree(REPO, source, ignore=NOT_SOURCE)
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], tmp_path, env)
    python = venv / "bin" / "python"
    site = Path(run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()"
                                        "['purelib'])"], elsewhere, env).stdout.strip())
    (site / "dev_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    found = run([str(python), "-c", "import importlib.util as u; print(u.find_spec('walkman'))"],
                elsewhere, env).stdout
    assert found.strip() == "None", f"the new venv sees the source tree already: {found}"

    run([str(python), "-m", "pip", "install", "--no-deps", "--no-build-isolation",
         "--no-index", "--quiet", str(source)], elsewhere, env)
    shutil.rmtree(source)     # nothing may come from it now

    helped = run([str(venv / "bin" / "walkman-chaos"), "--help"], elsewhere, env).stdout
    assert "usage: walkman-chaos" in helped and "--cancel-every" in helped
    probe = json.loads(run([str(python), "-c", PROBE], elsewhere, env).stdout)
    assert probe["spec"] == "witness"
    assert Path(probe["class_file"]).is_relative_to(site), probe["class_file"]
    assert Path(probe["board_file"]).is_relative_to(site), probe["board_file"]
    assert probe["ran"] == [5]
    packaged = probe["files"]
    assert "walkman/modules/witness.py" in packaged and "walkman/hal/virtual_board.py" in packaged
    assert not [f for f in packaged if f.split("/")[0] in ("tests", "fuzz")]
