"""Write the model files in ``models/`` from the description.

``python -m walkman.model.generate`` regenerates them; a test fails when the
committed files and the description disagree, so they cannot drift apart.
"""

from __future__ import annotations

import sys
from typing import Dict

from walkman.model.description import walkman
from walkman.model.mjcf import to_mjcf
from walkman.model.urdf import to_urdf
from walkman import MODELS_DIR

MODELS = MODELS_DIR


def render() -> Dict[str, str]:
    robot = walkman()
    return {"walkman.urdf": to_urdf(robot), "walkman.xml": to_mjcf(robot, drc=False),
            "walkman_drc.xml": to_mjcf(robot, drc=True)}


def main() -> int:
    MODELS.mkdir(exist_ok=True)
    for name, text in render().items():
        (MODELS / name).write_text(text)
        print(f"wrote {MODELS / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
