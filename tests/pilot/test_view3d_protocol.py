"""The 3-D view's protocol (pilot/view3d_protocol.py): JSON lines between the PI and librviz.

Every message both ways, whole and one byte at a time; a message travelling the
wrong way, a bad field (named), a NaN, a long line, the end mid-line; and a
fuzz target: any bytes give messages or RemoteProtocolError, and what was
decoded encodes back to the same line.
"""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from codec_helpers import FUZZ, feed_one_byte_at_a_time
from pilot.view3d_protocol import (MAX_LINE, AddMarker, Decoder, Direction, EnableDisplay, Go,
                                   LocalProtocolError, MarkerMoved, Ping, Pong,
                                   RemoteProtocolError, RemoveMarker, RosNodes, UpdateMarker,
                                   WindowReady, decode_line, encode)

POSE = (0.66, 0.25, 0.08, 0.0, -1.0472, math.pi)
TO_CHILD = [Go(("/pi_view3d_41", "/rviz_17")), Go(), AddMarker("drc_valve", POSE),
            AddMarker("drc_wall", POSE, "drill"), UpdateMarker("drc_valve", POSE),
            RemoveMarker("drc_door"), EnableDisplay("Cloud", False), Ping(7)]
TO_PI = [WindowReady(0x400006, 4321), RosNodes("/pi_view3d_4321", {"/rviz_17": "http://h:1/"}),
         RosNodes("/pi_view3d_1"), MarkerMoved("drc_valve", POSE), Pong(7)]


def pull(decoder: Decoder):
    return decoder.next_message()


@pytest.mark.parametrize("direction, messages", [(Direction.TO_CHILD, TO_CHILD),
                                                 (Direction.TO_PI, TO_PI)])
def test_every_message_round_trips_whole_and_one_byte_at_a_time(direction, messages):
    stream = b"".join(encode(m) for m in messages)
    whole = Decoder(direction)
    whole.feed(stream)
    assert whole.messages() == messages
    assert feed_one_byte_at_a_time(Decoder(direction), stream, pull) == messages


def test_the_wire_is_one_json_object_a_line():
    assert encode(AddMarker("drc_valve", (1, 2, 3, 0, 0, 0.5))) == \
        b'{"type":"add","name":"drc_valve","pose":[1.0,2.0,3.0,0.0,0.0,0.5],"kind":"disc"}\n'
    assert json.loads(encode(WindowReady(5, 6))) == {"type": "window", "window": 5, "pid": 6}


def test_a_half_arrived_line_waits_and_is_never_half_consumed():
    line = encode(MarkerMoved("drc_door", POSE))
    decoder = Decoder(Direction.TO_PI)
    decoder.feed(line[:-1])
    assert decoder.next_message() is None and decoder.next_message() is None
    decoder.feed(line[-1:])
    assert decoder.next_message() == MarkerMoved("drc_door", POSE)


def test_messages_then_trailing_garbage_gives_the_messages_then_the_error():
    decoder = Decoder(Direction.TO_CHILD)
    decoder.feed(encode(Ping(1)) + encode(Ping(2)) + b"\xff\xfegarbage\n")
    assert decoder.next_message() == Ping(1)
    assert decoder.next_message() == Ping(2)
    with pytest.raises(RemoteProtocolError, match="not a JSON line"):
        decoder.next_message()
    with pytest.raises(RemoteProtocolError):     # the stream is dead from then on
        decoder.next_message()


def test_a_message_travelling_the_wrong_way_is_the_peers_error():
    decoder = Decoder(Direction.TO_CHILD)
    decoder.feed(encode(WindowReady(1, 2)))
    with pytest.raises(RemoteProtocolError, match="'window' travels child -> PI only"):
        decoder.next_message()


@pytest.mark.parametrize("line, names", [
    (b'{"type":"add","name":"v","pose":[1,2,3]}', "add: field 'pose' must be 6 finite"),
    (b'{"type":"add","name":"v","pose":[1,2,3,4,5,true]}', "field 'pose'"),
    (b'{"type":"add","name":"v","pose":[1,2,3,4,5,NaN]}', "not a JSON line"),
    (b'{"type":"add","name":"v","pose":[1,2,3,4,5,1e999]}', "field 'pose'"),
    (b'{"type":"add","name":"","pose":[1,2,3,4,5,6]}', "add: field 'name'"),
    (b'{"type":"add","pose":[1,2,3,4,5,6]}', "add: field 'name' missing"),
    (b'{"type":"remove","name":"v","colour":"red"}', "remove: unknown field(s) ['colour']"),
    (b'{"type":"display","name":"Cloud","enabled":1}', "display: field 'enabled' must be"),
    (b'{"type":"ping","seq":-1}', "ping: field 'seq'"),
    (b'{"type":"go","forget":"/rviz_1"}', "go: field 'forget' must be a list"),
    (b'{"type":"go","forget":[""]}', "go: field 'forget' must be a non-empty string"),
    (b'{"type":"teleport"}', "unknown message type 'teleport'"),
    (b'{"name":"v"}', "unknown message type None"),
    (b'[1,2]', "must be a JSON object"),
])
def test_a_bad_line_is_refused_naming_what_is_wrong(line, names):
    with pytest.raises(RemoteProtocolError) as error:
        decode_line(line, Direction.TO_CHILD)
    assert names in str(error.value)


def test_the_end_of_the_stream_mid_line_is_an_error_and_a_clean_end_is_not():
    decoder = Decoder(Direction.TO_PI)
    decoder.feed(encode(Pong(3)))
    decoder.feed(b"")
    assert decoder.next_message() == Pong(3) and decoder.next_message() is None
    assert decoder.ended
    cut = Decoder(Direction.TO_PI)
    cut.feed(encode(Pong(3))[:5])
    cut.feed(b"")
    with pytest.raises(RemoteProtocolError, match="ended in the middle of a line"):
        cut.next_message()
    with pytest.raises(LocalProtocolError):
        cut.feed(b"more")


def test_a_line_over_the_limit_is_refused_before_its_end_arrives():
    decoder = Decoder(Direction.TO_PI)
    decoder.feed(b"x" * (MAX_LINE + 1))
    with pytest.raises(RemoteProtocolError, match="over"):
        decoder.next_message()


@pytest.mark.parametrize("message, names", [
    (AddMarker("v", (1, 2, 3, 4, 5, float("nan"))), "add: field 'pose'"),
    (AddMarker("v", (1, 2, 3, 4, 5, 6), "teapot"), "add: field 'kind' must be one of disc"),
    (UpdateMarker("v", (1, 2, 3)), "update: field 'pose'"),
    (RemoveMarker(""), "remove: field 'name'"),
    (Ping(-1), "ping: field 'seq'"),
    (RosNodes("/n", {"/rviz": 5}), "nodes: field 'librviz'"),
    ("ping", "not a message"),
])
def test_what_the_protocol_cannot_say_is_our_error(message, names):
    with pytest.raises(LocalProtocolError, match=names.replace("(", r"\(")):
        encode(message)


@FUZZ
@given(st.binary(max_size=300) | st.lists(st.sampled_from([encode(m) for m in TO_CHILD + TO_PI]
                                                          + [b"{", b"}", b"\n", b'"type"'])
                                           ).map(b"".join),
       st.sampled_from(list(Direction)))
def test_fuzz_any_bytes_give_messages_or_the_peers_error(data, direction):
    decoder = Decoder(direction)
    decoder.feed(data)
    try:
        for message in decoder.messages():
            again = Decoder(direction)
            again.feed(encode(message))
            assert again.messages() == [message]
    except RemoteProtocolError:
        pass


def test_every_kind_the_wire_takes_is_drawn_as_itself():
    """The render process draws an unknown kind as the plain disc: a kind of object added
    to the shared scene (and so to the wire) without a shape would pass unnoticed."""
    from pilot.view3d_child import OBJECT_SHAPES
    from pilot.view3d_protocol import MARKER_KINDS

    assert set(OBJECT_SHAPES) == set(MARKER_KINDS)
