"""The bridge's arrival reports matched to the frames they describe (no Qt, no ROS)."""

from __future__ import annotations

import numpy as np

from pilot.arrival import KEEP, ArrivalBook, fraction, missing_mask
from pilot.link import IMAGE_TOPIC, ArrivalEvent


def report(stamp_ns: int, share: float = 0.75, missing=((0, 0, 8, 4),), size=(8, 16)):
    return ArrivalEvent(IMAGE_TOPIC, stamp_ns, size[0], size[1], share, tuple(missing))


def test_a_report_is_found_by_its_frames_stamp_whichever_came_first():
    book = ArrivalBook()
    assert book.find(100) is None                    # the frame first: nothing yet
    book.add(report(100))
    book.add(report(200, 1.0, ()))
    assert book.find(100).fraction == 0.75 and book.find(200).missing == ()
    assert book.find(150) is None                    # no report for that frame
    book.add(report(100, 0.5))                       # said again: the last word counts
    assert book.find(100).fraction == 0.5


def test_the_book_keeps_the_last_reports_only():
    book = ArrivalBook()
    for stamp in range(KEEP + 5):
        book.add(report(stamp))
    assert book.find(4) is None and book.find(5) is not None
    assert book.find(KEEP + 4) is not None


def test_no_report_means_the_whole_frame_arrived():
    """The lab: no bridge, no report; black or NaN cells are content."""
    assert fraction(None) == 1.0
    assert not missing_mask(None, 8, 16).any()


def test_the_mask_is_exactly_the_reported_rectangles():
    mask = missing_mask(report(1, missing=((0, 0, 8, 4), (12, 6, 4, 2))), 8, 16)
    expected = np.zeros((8, 16), bool)
    expected[0:4, 0:8] = expected[6:8, 12:16] = True
    assert np.array_equal(mask, expected) and fraction(report(1)) == 0.75


def test_a_report_about_a_frame_of_another_size_marks_nothing():
    assert not missing_mask(report(1), 16, 16).any()
