"""What of a camera frame or a cloud arrived: the bridge's reports, matched to their frames.

The pilot bridge publishes, beside each tiled frame, a report of the cells
that arrived (:class:`~pilot.link.ArrivalEvent`, from ``<topic>/arrived``) with
the frame's stamp.  The report and the frame come on two topics, so either may
come first: a :class:`ArrivalBook` keeps the last few reports of a topic by
stamp, and the view asks it again when a report comes after its frame.  A frame
nobody reported on did not cross a bridge (the lab): it is whole, whatever its
black or NaN cells show.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Optional

import numpy as np

from pilot.link import ArrivalEvent

#: Reports kept per topic: a few seconds of frames at the camera's rate.
KEEP = 32


class ArrivalBook:
    """One topic's latest reports, by the stamp of the frame they describe."""

    def __init__(self, keep: int = KEEP) -> None:
        self.keep = keep
        self._reports: "OrderedDict[int, ArrivalEvent]" = OrderedDict()

    def add(self, report: ArrivalEvent) -> None:
        self._reports[report.stamp_ns] = report
        self._reports.move_to_end(report.stamp_ns)
        while len(self._reports) > self.keep:
            self._reports.popitem(last=False)

    def find(self, stamp_ns: int) -> Optional[ArrivalEvent]:
        """The report on the frame stamped ``stamp_ns``, or None (none came, or not yet)."""
        return self._reports.get(stamp_ns)


def fraction(report: Optional[ArrivalEvent]) -> float:
    """The share of a frame that arrived: all of it when no bridge reported a loss."""
    return 1.0 if report is None else report.fraction


def missing_mask(report: Optional[ArrivalEvent], height: int, width: int) -> np.ndarray:
    """``height x width`` bool, True on the cells the report says did not arrive.

    A report about a frame of another size (it cannot be this frame's) marks nothing.
    """
    mask = np.zeros((height, width), bool)
    if report is None or (report.height, report.width) != (height, width):
        return mask
    for x, y, w, h in report.missing:
        mask[y:y + h, x:x + w] = True
    return mask
