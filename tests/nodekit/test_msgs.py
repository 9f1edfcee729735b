"""nodekit.msgs: the generated walkman_msgs import in every program, however they start."""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from nodekit.msgs import REPO

# A program of ours as it starts on a fresh checkout: the output folder is on PYTHONPATH
# (walkman_env.sh) before anything generated it, and imports ran before main() called
# ensure_importable (every import looks in that folder, and remembers it missing).
PROGRAM = """
import sys
from pathlib import Path
import json, email.mime.text    # looked up the missing folder
from nodekit.msgs import ensure_importable, generate
print("generated", generate(output=Path(sys.argv[1])))
ensure_importable(Path(sys.argv[1]))
from walkman_msgs.msg import Status, Switch, Command, Scene
from walkman_msgs.srv import StopAll, SendCommand
print("imported", Status._type, StopAll._type)
"""


def start(output: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", PROGRAM, str(output)], cwd=REPO,
                            env={"PATH": "/usr/bin:/bin",
                                 "PYTHONPATH": f"{output}:{REPO}"},
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_a_program_started_before_the_messages_existed_imports_them(tmp_path):
    output = tmp_path / "lib"
    program = start(output)
    out, _ = program.communicate(timeout=120)
    assert program.returncode == 0, out
    assert "imported walkman_msgs/Status walkman_msgs/StopAll" in out


def test_programs_started_at_once_on_a_fresh_checkout_all_import_them(tmp_path):
    """A launcher starts every program at once: one generates, the others wait for it (then
    find it up to date) and never import a half-written file."""
    output = tmp_path / "lib"
    programs = [start(output) for _ in range(4)]
    outs = [program.communicate(timeout=120)[0] for program in programs]
    for program, out in zip(programs, outs):
        assert program.returncode == 0, out
        assert "imported walkman_msgs/Status" in out
    assert sum("generated True" in out for out in outs) == 1, outs


READ_ONLY_PROGRAM = """
import os, shutil, sys
from pathlib import Path
import nodekit.msgs
from nodekit.msgs import generate
output = Path(sys.argv[1])
# The other user reads the message definitions and the dependencies' manifests too: copies
# beside the install, readable wherever the checkout lives (a clone under /root, mode 700,
# is not).
nodekit.msgs.SOURCE = Path(shutil.copytree(nodekit.msgs.SOURCE, output.parent / "definitions"))
nodekit.msgs.SHARE = output.parent / "share"
generate(output=output)
os.remove(output / ".generating.lock")
os.chmod(output, 0o555)
os.setuid(65534)                      # nobody: the folder is not ours to write
print("up to date:", generate(output=output), flush=True)
"""


@pytest.mark.requires("root")
def test_messages_installed_read_only_still_import_for_another_user():
    """An install its users cannot write (no lock file can be made there) is used as it
    is when it is up to date -- from a checkout anywhere, one its users cannot enter too."""
    with tempfile.TemporaryDirectory() as folder:      # pytest's tmp_path is root's alone
        os.chmod(folder, 0o755)
        result = subprocess.run([sys.executable, "-c", READ_ONLY_PROGRAM, f"{folder}/lib"],
                                cwd=REPO, capture_output=True, text=True, timeout=120)
        os.chmod(f"{folder}/lib", 0o755)               # for the clean-up
    assert result.returncode == 0, result.stdout + result.stderr
    assert "up to date: False" in result.stdout
