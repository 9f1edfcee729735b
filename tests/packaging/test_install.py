"""The packages install as a user installs them, and run from there.

* ``pip install ./yarp_lite`` into a bare virtual environment (no system site
  packages): the distribution needs nothing outside the standard library, the
  installed ``yarp-lite`` runs a network on its own, and yarp_lite's own tests
  (every ``tests/unit`` file that needs nothing else) pass against it.
* ``pip install .[sim,bridge]`` into a clean one that sees Debian's packages
  (rospy): every console script answers ``--help``, the models ship as package
  data, and an installed GYM module (the chaos witness) runs against the
  installed name server.

Both build from a copy of the source (pip builds in the tree it is given, and
the tree under test stays clean) and run from a folder outside it, with no
``PYTHONPATH``, so nothing can come from the source tree by accident.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Dict, List

import pytest

from harness import Implementation, YarpWorld

REPO = Path(__file__).resolve().parents[2]
#: The interpreter a user makes virtual environments from (Debian's, as the README says).
BASE_PYTHON = Path(sys.base_prefix) / "bin" / "python3"
NOT_SOURCE = shutil.ignore_patterns(".venv", ".git", "build", "dist", "out", "__pycache__",
                                    "*.egg-info", ".hypothesis", ".pytest_cache", "tests")


def run(argv: List, cwd: Path, env: Dict[str, str], timeout: float = 600) -> str:
    done = subprocess.run([str(a) for a in argv], cwd=str(cwd), env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0, (f"{' '.join(map(str, argv))} failed ({done.returncode}):\n"
                                  f"{done.stdout[-3000:]}\n{done.stderr[-3000:]}")
    return done.stdout


def outside_env() -> Dict[str, str]:
    """The caller's environment without anything that points into the source tree."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if not p.startswith(str(REPO)))
    return env


def install(tmp: Path, source: Path, requirement: str, system_site: bool) -> Path:
    """A new virtual environment under ``tmp`` with ``requirement`` installed from a copy
    of ``source``; returns its ``bin`` folder."""
    copy = tmp / "src"
    shutil.copytree(source, copy, ignore=NOT_SOURCE, symlinks=True)
    venv = tmp / "venv"
    env = outside_env()
    run([BASE_PYTHON, "-m", "venv", *(["--system-site-packages"] if system_site else []), venv],
        tmp, env)
    run([venv / "bin" / "pip", "install", "-q", "--disable-pip-version-check",
         requirement.replace("SRC", str(copy))], tmp, env)
    return venv / "bin"


@pytest.fixture(scope="module")
def lite_bin(tmp_path_factory) -> Path:
    return install(tmp_path_factory.mktemp("yarp-lite"), REPO / "yarp_lite", "SRC",
                   system_site=False)


@pytest.fixture(scope="module")
def lite_test_bin(tmp_path_factory) -> Path:
    """Another bare environment with the lone yarp-lite, and pytest and hypothesis to test it
    (kept apart from ``lite_bin``, whose package list is checked)."""
    bin_dir = install(tmp_path_factory.mktemp("yarp-lite-tested"), REPO / "yarp_lite", "SRC",
                      system_site=False)
    run([bin_dir / "pip", "install", "-q", "--disable-pip-version-check", "pytest",
         "hypothesis"], bin_dir, outside_env())
    return bin_dir


@pytest.fixture(scope="module")
def system_bin(tmp_path_factory) -> Path:
    return install(tmp_path_factory.mktemp("walkman"), REPO, "SRC[sim,bridge]",
                   system_site=True)


def installed_scripts(bin_dir: Path, distribution: str) -> List[str]:
    code = ("import importlib.metadata as m, json, sys; "
            "print(json.dumps([e.name for e in m.distribution(sys.argv[1]).entry_points "
            "if e.group == 'console_scripts']))")
    return json.loads(run([bin_dir / "python", "-c", code, distribution], bin_dir,
                          outside_env()))


def test_yarp_lite_installs_alone_with_nothing_outside_the_standard_library(lite_bin):
    installed = json.loads(run([lite_bin / "pip", "list", "--format", "json",
                                "--disable-pip-version-check"], lite_bin, outside_env()))
    assert {p["name"] for p in installed} - {"pip", "setuptools"} == {"yarp-lite"}
    # Everything the whole package imports is yarp_lite or the standard library.
    # (What the interpreter loaded before -- sitecustomize, setuptools' hook -- is not ours.)
    code = ("import sys; before = set(sys.modules); import pkgutil, importlib, yarp_lite; "
            "[importlib.import_module(m.name) for m in pkgutil.walk_packages("
            "yarp_lite.__path__, 'yarp_lite.') if m.name != 'yarp_lite.__main__']; "
            "print(sorted({n.split('.')[0] for n in set(sys.modules) - before}"
            " - set(sys.stdlib_module_names) - {'yarp_lite'}))")
    assert run([lite_bin / "python", "-c", code], lite_bin, outside_env()).strip() == "[]"
    assert installed_scripts(lite_bin, "yarp-lite") == ["yarp-lite"]


def test_the_installed_yarp_lite_runs_a_network(lite_bin, tmp_path):
    tool = [str(lite_bin / "yarp-lite")]
    installed = Implementation("installed yarp-lite", [*tool, "server"], tool)
    world = YarpWorld(tmp_path, installed)
    env = {**outside_env(), **{k: v for k, v in world.env.items() if k.startswith("YARP")}}
    try:
        help_text = run([*tool, "--help"], tmp_path, env)
        assert "Usage:" in help_text and "server" in help_text
        world.start_server()
        reader = world.start([*tool, "read", "/installed/read"], "yarp-lite read", env=env)
        run([*tool, "wait", "/installed/read"], tmp_path, env, timeout=30)
        writer = subprocess.run([*tool, "write", "/installed/write", "/installed/read"],
                                input="hello (1 2) 3.5\n", env=env, cwd=tmp_path,
                                capture_output=True, text=True, timeout=30)
        assert writer.returncode == 0, writer.stderr
        reader.wait_for(r"hello \(1 2\) 3\.5", timeout=20)
    finally:
        world.close()


#: The standalone suite's conftest: the project's hypothesis settings without the rest.
STANDALONE_CONFTEST = """
from hypothesis import settings
settings.register_profile("standalone", deadline=None, derandomize=True, database=None)
settings.load_profile("standalone")
"""
STANDALONE_IMPORTS = {"__future__", "yarp_lite", "pytest", "hypothesis"}


def standalone_tests() -> List[Path]:
    """The ``tests/unit`` files of yarp_lite that import nothing but yarp_lite, the
    standard library, pytest and hypothesis: its tests, runnable without the system."""
    found = []
    for path in sorted((REPO / "tests" / "unit").glob("test_*.py")):
        tops = {(node.module or "").split(".")[0] if isinstance(node, ast.ImportFrom)
                else alias.name.split(".")[0]
                for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, (ast.Import, ast.ImportFrom))
                for alias in (node.names if isinstance(node, ast.Import) else [None])}
        if "yarp_lite" in tops and tops <= STANDALONE_IMPORTS | set(sys.stdlib_module_names):
            found.append(path)
    return found


def test_yarp_lites_own_tests_pass_against_the_lone_installed_package(lite_test_bin, tmp_path):
    tests = standalone_tests()
    assert len(tests) >= 10, [t.name for t in tests]
    suite = tmp_path / "suite"
    suite.mkdir()
    for path in tests:
        shutil.copy(path, suite / path.name)
    (suite / "conftest.py").write_text(STANDALONE_CONFTEST)
    summary = run([lite_test_bin / "python", "-m", "pytest", "-q", "-p", "no:cacheprovider",
                   suite], tmp_path, outside_env(), timeout=900).strip().splitlines()[-1]
    assert "passed" in summary and "failed" not in summary and "error" not in summary, summary


def test_every_installed_console_script_answers_help(system_bin, tmp_path):
    scripts = installed_scripts(system_bin, "walkman-architecture")
    assert "walkman-chaos" in scripts and "yarp-lite" in scripts and len(scripts) >= 13
    for script in scripts:
        text = run([system_bin / script, "--help"], tmp_path, outside_env(), timeout=60)
        assert "usage" in text.lower(), f"{script} --help printed no usage:\n{text}"


def test_the_models_ship_with_the_installed_package(system_bin, tmp_path):
    where = run([system_bin / "python", "-c", "import walkman; print(walkman.MODELS_DIR)"],
                tmp_path, outside_env()).strip()
    models = Path(where)
    assert models.is_relative_to(system_bin.parent), f"models found in the source tree: {where}"
    for name in ("bridge_drc.xml", "bridge_paper.xml", "hal_chains.ini", "walkman.urdf",
                 "walkman_drc.xml", "pilot_layouts.ini", "contexts/gaze_control/gaze_control.ini"):
        assert (models / name).is_file(), f"{name} is not in the installed package"
    table = run([system_bin / "walkman-bridge", "--check", models / "bridge_drc.xml"], tmp_path,
                outside_env())
    assert "gaze_control" in table


def test_an_installed_module_runs_against_the_installed_name_server(system_bin, tmp_path):
    """The chaos witness comes from the package (an installed walkman-chaos could not run
    when it lived in tests/)."""
    tool = [str(system_bin / "yarp-lite")]
    world = YarpWorld(tmp_path, Implementation("installed", [*tool, "server"], tool))
    env = {**outside_env(), **{k: v for k, v in world.env.items() if k.startswith("YARP")},
           "COUNTER_LOG": str(tmp_path / "executed.log"), "PYTHONUNBUFFERED": "1"}
    try:
        world.start_server()
        module = world.start([str(system_bin / "walkman-module"), "witness", "--name", "/counter"],
                             "walkman-module witness", env=env)
        module.wait_for("ready for the pilot", timeout=60)
        run([*tool, "exists", "/counter/switch:i"], tmp_path, env, timeout=30)
    finally:
        world.close()


#: Issue 30: walkman-chaos started tests.bridge.counting_module, which no distribution
#: contains.  Its witness and the virtual control board now ship in the package.
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


def test_the_installed_chaos_runs_its_witness_and_board_from_the_package(system_bin, tmp_path):
    helped = run([system_bin / "walkman-chaos", "--help"], tmp_path, outside_env())
    assert "usage: walkman-chaos" in helped and "--cancel-every" in helped
    probe = json.loads(run([system_bin / "python", "-c", PROBE], tmp_path, outside_env()))
    site = system_bin.parent
    assert probe["spec"] == "witness"
    assert Path(probe["class_file"]).is_relative_to(site), probe["class_file"]
    assert Path(probe["board_file"]).is_relative_to(site), probe["board_file"]
    assert probe["ran"] == [5]
    packaged = probe["files"]
    assert "walkman/modules/witness.py" in packaged and "walkman/hal/virtual_board.py" in packaged
    assert not [f for f in packaged if f.split("/")[0] in ("tests", "fuzz")]
