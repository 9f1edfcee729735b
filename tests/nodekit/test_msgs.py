"""nodekit.msgs: the generated walkman_msgs import in every program, however they start."""

import subprocess
import sys
from pathlib import Path

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
