"""Walk-Man: the Generic YARP Module, the hardware abstraction layer, and the robot."""

from pathlib import Path

#: The robot's model files, the bridge and HAL configurations, the contexts and layouts:
#: data of this package, so an installed copy has them (``models/`` at the top of the source
#: tree is a link here, for users and docs).
MODELS_DIR = Path(__file__).resolve().parent / "models"
