"""The bridge tests' helpers (bridge_harness, pilot_side, pilot_sender) import by name."""

import sys
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parent))
