"""The camera view: the robot's head camera, with the tiles that did not arrive marked.

The bridge sends images as tiles of one datagram each and fills what was lost
with black; the pilot bridge then says which cells of the frame did not arrive
(:mod:`pilot.arrival`).  The view hatches exactly those in red and shows the
image's and the cloud's share that arrived, so the pilot never mistakes a lost
tile for a dark object -- nor a dark sky for a lost tile.  With no report for a
frame (the lab: no bridge) the frame is whole: 100 %, nothing hatched.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np
from python_qt_binding.QtCore import Qt
from python_qt_binding.QtGui import QImage, QPixmap
from python_qt_binding.QtWidgets import QLabel, QVBoxLayout, QWidget

from pilot.arrival import ArrivalBook, fraction, missing_mask
from pilot.link import CLOUD_TOPIC, IMAGE_TOPIC, ArrivalEvent, CloudEvent, ImageEvent
from pilot.link_cut import LinkCut

MISSING_COLOUR = np.array([200, 30, 30], np.uint8)


def marked(rgb: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """The image with its ``missing`` pixels (H x W bool) hatched: diagonal red stripes,
    so what shows through between them is the black the bridge filled in."""
    out = rgb.copy()
    if not missing.any():
        return out
    hatch = (np.add.outer(np.arange(missing.shape[0]), np.arange(missing.shape[1])) % 6) < 2
    out[missing & hatch] = MISSING_COLOUR
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
        self.reports = {IMAGE_TOPIC: ArrivalBook(), CLOUD_TOPIC: ArrivalBook()}
        self.image: Optional[ImageEvent] = None
        self.cloud: Optional[CloudEvent] = None
        self.frames = 0
        self.last_frame = 0.0
        #: While the link is down the frame shown is as old as the cut, or older: said so.
        self.cut = LinkCut()

    @property
    def image_completeness(self) -> Optional[float]:
        return None if self.image is None else fraction(self.report_for(IMAGE_TOPIC))

    @property
    def cloud_completeness(self) -> Optional[float]:
        return None if self.cloud is None else fraction(self.report_for(CLOUD_TOPIC))

    def report_for(self, topic: str) -> Optional[ArrivalEvent]:
        """The bridge's report on the frame of ``topic`` shown now, if one came."""
        frame = self.image if topic == IMAGE_TOPIC else self.cloud
        return None if frame is None else self.reports[topic].find(frame.stamp_ns)

    def on_image(self, event: ImageEvent) -> None:
        self.image = event
        self.frames += 1
        self.last_frame = self.cut.clock()
        self._draw()

    def on_link(self, event) -> None:
        self.cut.on_link(event)
        self._caption()

    def tick(self) -> None:
        """Once a second (the window's timer): the age of a frame shown during a cut."""
        if self.cut.down_for is not None:
            self._caption()

    def on_cloud(self, event: CloudEvent) -> None:
        self.cloud = event
        self._caption()

    def on_arrival(self, event: ArrivalEvent) -> None:
        """A report, before its frame (kept) or after it (the frame shown again)."""
        book = self.reports.get(event.topic)
        if book is None:
            return
        book.add(event)
        if event.topic == IMAGE_TOPIC and self.image is not None and \
                self.image.stamp_ns == event.stamp_ns:
            self._draw()
        elif event.topic == CLOUD_TOPIC and self.cloud is not None and \
                self.cloud.stamp_ns == event.stamp_ns:
            self._caption()

    def _draw(self) -> None:
        height, width = self.image.rgb.shape[:2]
        missing = missing_mask(self.report_for(IMAGE_TOPIC), height, width)
        rgb = np.ascontiguousarray(marked(self.image.rgb, missing))
        image = QImage(rgb.data, width, height, 3 * width, QImage.Format_RGB888).copy()
        self.picture.setPixmap(QPixmap.fromImage(image).scaled(
            self.picture.size(), Qt.KeepAspectRatio, Qt.SmoothTransformation))
        self._caption()

    def _caption(self) -> None:
        parts = [f"frame {self.frames}"]
        image, cloud = self.image_completeness, self.cloud_completeness
        if image is not None:
            parts.append(f"image {percent(image)} arrived")
        if cloud is not None:
            parts.append(f"cloud {percent(cloud)} of points")
        report = self.report_for(IMAGE_TOPIC)
        lost = report is not None and bool(report.missing)
        cut = self.cut.banner(f"frame {self.frames}", self.last_frame if self.frames else None)
        if cut:
            parts = [cut] + parts[1:]
        self.caption.setText(" | ".join(parts) +
                             ("  (red: tiles that did not arrive)" if lost else ""))


def percent(share: float) -> str:
    """Rounded down: "100%" only when everything arrived (a float32 0.7 is still 70%)."""
    return f"{math.floor(share * 100 + 1e-4):d}%"
