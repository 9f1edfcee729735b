"""How late a frame came, from the sender's clock stamp and the lowest offset (bridge.wire.transit)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from bridge.wire.transit import MODULUS, Lateness, stamp
from codec_helpers import FUZZ


def test_a_frame_held_on_the_way_is_late_by_the_time_it_was_held():
    lateness = Lateness()
    # The sender's clock reads 5000 s when the receiver's reads 20 s: clocks need not agree.
    assert lateness.of(stamp(5000.0), 20.05) == 0.0            # the first: the baseline
    assert lateness.of(stamp(5001.0), 21.05) == 0.0            # as quick
    assert lateness.of(stamp(5002.0), 28.05) == 6.0            # unread 6 s in a stalled socket
    assert lateness.of(stamp(5003.0), 23.06) == 0.01           # a little jitter counts too
    assert lateness.of(stamp(5004.0), 24.03) == 0.0            # quicker: the new baseline
    assert lateness.of(stamp(5005.0), 25.05) == 0.02


def test_the_stamps_wrap_without_a_jump():
    lateness = Lateness()
    last = (MODULUS - 500) / 1000.0                              # 0.5 s before the wrap
    lateness.of(stamp(last), 100.0)
    assert stamp(last + 1.0) < stamp(last)                       # wrapped
    assert lateness.of(stamp(last + 1.0), 101.0) == 0.0
    assert lateness.of(stamp(last + 2.0), 104.5) == 2.5


@FUZZ
@given(st.lists(st.tuples(st.floats(0, 1e6), st.floats(0, 30)), min_size=1, max_size=30),
       st.floats(-1e5, 1e5))
def test_lateness_is_the_delay_beyond_the_quickest_whatever_the_offset(sends, offset):
    """Frames sent at ``t`` and read at ``t + offset + delay``: each one's lateness is its
    delay less the least delay before it (to the ms), never negative."""
    lateness, quickest = Lateness(), None
    for sent, delay in sorted(sends):
        read = sent + offset + 1e6 + delay                      # the receiver's clock
        late = lateness.of(stamp(sent), read)
        quickest = delay if quickest is None else min(quickest, delay)
        assert late >= 0.0
        assert abs(late - (delay - quickest)) <= 0.0021


def test_a_frame_held_on_a_real_connection_is_journalled_as_older(tmp_path):
    """Two TCP channels through a relay that holds the pilot's bytes for a second (a TCP
    stream stalled behind a retransmission): the robot's journal counts the second."""
    import time

    from harness import free_port, wait_until
    from test_copies import Relay
    from test_tcp_channel import COMMAND, End
    from yarp_lite.bottle import Bottle

    port = free_port()
    relay = Relay(port)
    robot = End("robot", port, tmp_path / "robot", listen=True).start()
    pilot = End("pilot", relay.port, tmp_path / "pilot", listen=False).start()
    try:
        wait_until(lambda: robot.channel.connected and pilot.channel.connected, 10,
                   message="link up")
        pilot.channel.send_reliable(COMMAND, Bottle([Bottle(["first"]), 1]))
        wait_until(lambda: len(robot.reliable) == 1, 10, message="the first command")
        relay.flowing.clear()
        pilot.channel.send_reliable(COMMAND, Bottle([Bottle(["held"]), 2]))
        wait_until(lambda: relay.holding, 10, message="the relay holding the frame")
        time.sleep(1.0)          # the thing under test: the frame is held this long
        relay.flowing.set()
        wait_until(lambda: len(robot.reliable) == 2, 10, message="the held command")
        assert robot.held_for[0] < 0.5
        assert robot.held_for[1] >= 0.9, robot.held_for
    finally:
        relay.flowing.set()
        pilot.stop()
        robot.stop()
        relay.close()
