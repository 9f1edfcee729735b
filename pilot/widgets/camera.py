"""The camera view: the robot's head camera, with the tiles that did not arrive marked.

The bridge sends images as tiles of one datagram each and fills what was lost
with black; :func:`pilot.link.missing_blocks` finds those regions and the view
hatches them in red, with the frame's completeness and age beside it, so the
pilot never mistakes a lost tile for a dark object.
"""

from __future__ import annotations

import time

import numpy as np
from python_qt_binding.QtCore import Qt
from python_qt_binding.QtGui import QImage, QPixmap
from python_qt_binding.QtWidgets import QLabel, QVBoxLayout, QWidget

from pilot.link import BLOCK, CloudEvent, ImageEvent

MISSING_COLOUR = np.array([200, 30, 30], np.uint8)


def marked(rgb: np.ndarray, missing: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """The image with missing blocks hatched (every other row of them red)."""
    out = rgb.copy()
    if not missing.any():
        return out
    mask = np.kron(missing, np.ones((block, block), bool))
    hatch = (np.add.outer(np.arange(mask.shape[0]), np.arange(mask.shape[1])) % 6) < 2
    region = out[:mask.shape[0], :mask.shape[1]]
    region[mask & hatch] = MISSING_COLOUR
    return out


class CameraView(QWidget):
    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setObjectName("camera")
        layout = QVBoxLayout(self)
        self.picture = QLabel("camera: no image yet")
        self.picture.setAlignment(Qt.AlignCenter)
        self.picture.setMinimumSize(320, 240)
        self.caption = QLabel("")
        self.caption.setObjectName("camera_caption")
        layout.addWidget(self.picture, 1)
        layout.addWidget(self.caption)
        self.image_completeness = None
        self.cloud_completeness = None
        self.frames = 0
        self.last_frame = 0.0

    def on_image(self, event: ImageEvent) -> None:
        rgb = np.ascontiguousarray(marked(event.rgb, event.missing))
        height, width = rgb.shape[:2]
        image = QImage(rgb.data, width, height, 3 * width, QImage.Format_RGB888).copy()
        self.picture.setPixmap(QPixmap.fromImage(image).scaled(
            self.picture.size(), Qt.KeepAspectRatio, Qt.SmoothTransformation))
        self.image_completeness = event.completeness
        self.frames += 1
        self.last_frame = time.monotonic()
        self._caption()

    def on_cloud(self, event: CloudEvent) -> None:
        self.cloud_completeness = event.completeness
        self._caption()

    def _caption(self) -> None:
        parts = [f"frame {self.frames}"]
        if self.image_completeness is not None:
            parts.append(f"image {self.image_completeness:.0%} arrived")
        if self.cloud_completeness is not None:
            parts.append(f"cloud {self.cloud_completeness:.0%} of points")
        self.caption.setText(" | ".join(parts) + ("  (red: tiles that did not arrive)"
                                                  if self.image_completeness not in (None, 1.0)
                                                  else ""))
