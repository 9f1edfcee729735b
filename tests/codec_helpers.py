"""Helpers shared by the codec tests: byte-by-byte feeding and fuzz settings."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

FUZZ = settings(max_examples=300, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def feed_one_byte_at_a_time(decoder, data: bytes, pull):
    """Feed ``data`` one byte at a time, collecting whatever ``pull`` yields."""
    events = []
    for index in range(len(data)):
        decoder.feed(data[index:index + 1])
        while True:
            event = pull(decoder)
            if event is None:
                break
            events.append(event)
    return events
