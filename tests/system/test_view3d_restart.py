"""The 3-D view cannot take the PI down (issue 31): its render process SIGKILLed under Xvfb.

A real PI (tests/system/view3d_driver.py) on a lab PC's name servers: librviz's
window is embedded and draws; killed with SIGKILL, the PI lives on, says "3-D view
restarting -- it was killed: signal 9" in the view's place and in its log, and the
view comes back from a new process, embedded and drawing, with the valve's marker
where the pilot had dragged it.  Screenshots go to ``out/pilot-gui``.
"""

from __future__ import annotations

import re
import shutil
import sys

import pytest

from system.display import display_env, private_display
from system.processes import REPO

pytestmark = pytest.mark.requires("xvfb")


def test_a_killed_3d_view_comes_back_and_the_pi_lives_on(make_pc, tmp_path):
    pc = make_pc("lab")
    out = tmp_path / "screens"
    out.mkdir()
    try:
        with private_display() as display:
            pc.start_name_servers()
            pc.extra_env.update(display_env(display), PI_NAME="pi_view3d_test",
                                PYTHONFAULTHANDLER="1")
            pi = pc.start("pi", [sys.executable, str(REPO / "tests" / "system" /
                                                     "view3d_driver.py"), str(out)])
            pi.wait_for(r"DONE|FAIL", 400)
            assert "FAIL" not in pi.output(), pi.output()
    finally:
        shutil.copytree(out, REPO / "out" / "pilot-gui", dirs_exist_ok=True)
    text = pi.output()
    print("\n".join(line for line in text.splitlines() if line.startswith("STEP")))
    first, second = map(int, re.search(r"STEP view back: render process (\d+) \(was (\d+)\)",
                                       text).groups()[::-1])
    assert first != second
    assert "STEP the PI says: 3-D view restarting" in text
    assert "STEP marker dragged: valve x 0.720" in text
    assert "STEP ghost drawn:" in text        # the preview's translucent robot, then gone
