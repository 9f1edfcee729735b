"""One fuzz target per decoder, each seeded with valid encodings the codecs produce.

A target feeds its input through the decoder the way the running code does (a
stream in pieces, datagrams in order, one decoder across frames...), then
checks what the decoder returned keeps its promises: a decoded Bottle
re-encodes, a stream decoder gives the same messages whatever the pieces, a
refused robot-state frame leaves the decoder as it was.  Inputs that need a
checksum to get past the first check (bridge frames and datagrams, udp
datagrams) are also tried with the checksum fixed, so the fuzzer reaches the
parser behind it.
"""

from __future__ import annotations

import struct
import zlib
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from bridge import config, status
from bridge.config import ConfigError
from bridge.errors import BridgeProtocolError
from bridge.wire import compact, datagrams, fec, frames, link, state_codec, tiles
from fuzz.harness import Target, attempt, join_records, split_records
from walkman.hal import controlboard
from walkman.hal.controlboard import ControlBoardError
from walkman.hal.virtual_board import VirtualBoard
from yarp_lite import admin as port_admin
from yarp_lite import bottle, bottle_text, framing
from yarp_lite.bottle import Bottle, Dict as DictValue, Float32, Int8, Int16, Int64, Vocab
from yarp_lite.carriers import carrier_for_header
from yarp_lite.carriers.datagram import CRC_SIZE, DatagramAssembler, pack_message
from yarp_lite.contact import Contact, is_valid_port_name
from yarp_lite.errors import RemoteProtocolError
from yarp_lite.lines import split_line
from yarp_lite.nameserver.registry import Registry
from yarp_lite.nameserver.service import NameService, OldReply
from yarp_lite.nameserver.subscriptions import Subscriptions
from walkman import MODELS_DIR

YARP = (RemoteProtocolError,)
BRIDGE = (BridgeProtocolError,)
MODELS = MODELS_DIR

#: Bottles that cover every wire type, nesting, typed lists and dicts.
SAMPLE_BOTTLES = [
    Bottle([]),
    Bottle([1, 2, 3]),
    Bottle(["start", 7]),
    Bottle([Vocab("add"), "/port", "tcp"]),
    Bottle([12, "a", 0.25, Float32(1.5), Int8(-3), Int16(300), Int64(1 << 40)]),
    Bottle([b"\x00\xffblob", "text with \"quotes\" and \\", -0.0, float("inf")]),
    Bottle([Bottle([1, Bottle(["deep", Bottle([2.5, 3.5, 4.5])])]), [Vocab("ok")] * 3]),
    Bottle([DictValue.from_mapping({"a": 1, "b": "two", "c": [3, 4]})]),
    Bottle([(0.5 * i) for i in range(40)]),
    Bottle([["name", "/x"], ["ip", "10.0.0.1"], ["port_number", 10002]]),
]


def _reencodes(value: Bottle) -> None:
    """A decoded Bottle must encode again, stably, and print as text."""
    once = bottle.encode(value)
    if bottle.encode(bottle.decode(once)) != once:
        raise AssertionError("re-encoding a decoded Bottle is not stable")
    bottle_text.format_bottle(value)


# -- yarp_lite ---------------------------------------------------------------------------


def bottle_binary(data: bytes) -> None:
    _reencodes(bottle.decode(data))
    attempt(YARP, bottle.decode_prefix, data)


def bottle_text_target(data: bytes) -> None:
    text = data.decode("utf-8", "surrogateescape")
    bottle_text.is_complete(text)
    value = bottle_text.parse(text)
    _reencodes(value)
    bottle_text.parse(bottle_text.format_bottle(value))


def connection_header(data: bytes) -> None:
    """The first bytes a port reads from a new connection (``port.py``'s accept path)."""
    framing.parse_yarp_number(data[:8])  # a header reply or an acknowledgement
    carrier = carrier_for_header(data[:8])
    if carrier is None:
        return  # the port answers PROTOCOL_NOT_FOUND
    rest = data[8:]
    if carrier.name == "name_ser":
        sender = "anon"
    elif carrier.text_mode:
        found = split_line(rest)
        if found is None:
            return
        sender = found[0]
    else:
        length = framing.sender_name_length(rest[:4])
        if len(rest) < 4 + length:
            return
        sender = framing.decode_sender_name(rest[4:4 + length])
    contact = Contact.parse(sender)
    is_valid_port_name(contact.name)
    str(contact), contact.uri()


def _drain(data: bytes, piece: int, window: bool) -> Tuple[List[Tuple[str, str, bytes]], bool]:
    """Messages a :class:`MessageDecoder` gives for ``data`` fed ``piece`` bytes at a time."""
    decoder = framing.MessageDecoder("fuzz", max_message=1 << 16)
    out: List[Tuple[str, str, bytes]] = []
    pos = 0
    try:
        while True:
            message = decoder.next_message()
            if message is not None:
                out.append((message.command, message.text, bytes(message.payload)))
                continue
            if pos >= len(data):
                return out, False
            room = decoder.payload_window() if window else None
            if room is not None:
                count = min(len(room), len(data) - pos)
                room[:count] = data[pos:pos + count]
                room.release()
                decoder.commit(count)
                pos += count
            else:
                decoder.feed(data[pos:pos + piece])
                pos += piece
    except RemoteProtocolError:
        return out, True


def message_stream(data: bytes) -> None:
    """Index + port command + payload: the same messages however the bytes arrive."""
    whole = _drain(data, max(len(data), 1), window=False)
    pieces = _drain(data, 1 + (data[0] % 7 if data else 0), window=False)
    direct = _drain(data, 3, window=True)
    if not whole == pieces == direct:
        raise AssertionError(f"the decoder depends on how bytes arrive: {whole} / {pieces} / "
                             f"{direct}")
    for command, _, payload in whole[0]:
        if command in ("d", "D", "a"):
            value = attempt(YARP, bottle.decode, payload)
            if value is not None:
                _reencodes(value)
    framing.parse_payload(data)


def _fix_crc32(datagram: bytes) -> bytes:
    if len(datagram) < CRC_SIZE:
        return datagram
    value = zlib.crc32(datagram[CRC_SIZE:])
    return struct.pack("<i", value - (1 << 32) if value >= 1 << 31 else value) + \
        datagram[4:]


def udp_datagrams(data: bytes) -> None:
    """Datagrams in order into a :class:`DatagramAssembler` and a message decoder, as
    ``carriers/udp.py``'s message source does; bit 0 of the first byte fixes CRCs."""
    if not data:
        return
    fix = data[0] & 1
    assembler = DatagramAssembler()
    decoder = framing.MessageDecoder("fuzz udp", max_message=1 << 16)
    for datagram in split_records(data[1:]):
        body, restart = assembler.accept(_fix_crc32(datagram) if fix else datagram)
        if restart:
            decoder.reset()
        if body is None:
            continue
        decoder.feed(body)
        try:
            message = decoder.next_message()
        except RemoteProtocolError:
            decoder.reset()
            assembler.message_done()
            continue
        if message is not None:
            assembler.message_done()
            decoder.reset()
            attempt(YARP, bottle.decode, message.payload)


def text_lines(data: bytes) -> None:
    """Lines as a text connection reads them, each a contact, a port name and a Bottle."""
    pos = 0
    while True:
        found = split_line(data, pos)
        if found is None:
            return
        line, end = found
        if not pos < end <= len(data):
            raise AssertionError(f"split_line at {pos} ended at {end} of {len(data)}")
        Contact.parse(line)
        is_valid_port_name(line)
        bottle_text.is_complete(line)
        pos = end


def _commands(data: bytes) -> List[Bottle]:
    """Bit 0 of the first byte: binary Bottles as records, else text lines."""
    if not data:
        return []
    if data[0] & 1:
        return [value for value in (attempt(YARP, bottle.decode, record)
                                    for record in split_records(data[1:])) if value is not None]
    lines = data[1:].decode("utf-8", "surrogateescape").split("\n")
    return [value for value in (attempt(YARP, bottle_text.parse, line) for line in lines)
            if value is not None]


def _render(reply: Any) -> None:
    if isinstance(reply, OldReply):
        reply.text()
        reply.binary()
    else:
        _reencodes(reply)


def nameserver(data: bytes) -> None:
    service = NameService(Registry(":memory:", 10000), Subscriptions(":memory:"),
                          "10.0.0.1", 10000, silent=True)
    for command in _commands(data):
        outcome = service.apply(command, "10.0.0.7")
        _render(outcome.reply)
        for event in outcome.events:
            _reencodes(event)


class FakePort:
    """An in-memory port for the admin protocol (the effects are the port's own)."""

    name = "/fuzz"

    def __init__(self) -> None:
        self.outputs: Dict[str, port_admin.Route] = {"/out": port_admin.Route("/fuzz", "/out",
                                                                              "tcp")}
        self.inputs = [port_admin.Route("/in", "/fuzz", "udp", connectionless=True)]
        self.props: Dict[str, object] = {}

    def address(self) -> Contact:
        return Contact("/fuzz", "tcp", "127.0.0.1", 10002)

    def input_routes(self) -> List[port_admin.Route]:
        return list(self.inputs)

    def output_routes(self) -> List[port_admin.Route]:
        return list(self.outputs.values())

    def add_output(self, target: str) -> Tuple[bool, str]:
        contact = Contact.parse(target)
        self.outputs[contact.name] = port_admin.Route("/fuzz", contact.name,
                                                      contact.carrier or "tcp")
        return True, f"Added connection from /fuzz to {target}"

    def remove_output(self, target: str) -> bool:
        return self.outputs.pop(target, None) is not None

    def remove_input(self, source: str) -> bool:
        before = len(self.inputs)
        self.inputs = [route for route in self.inputs if route.source != source]
        return len(self.inputs) != before

    def properties(self) -> Dict[str, object]:
        return self.props

    def admin_fallback(self, command: Bottle) -> Optional[Bottle]:
        return None


def admin_target(data: bytes) -> None:
    port = FakePort()
    for command in _commands(data):
        _reencodes(port_admin.admin(port, command))
        if command and isinstance(command[0], str):
            port_admin.port_command(port, str(command[0]))


# -- bridge ------------------------------------------------------------------------------


#: The link's trailer: none on handshake frames, an 8-byte tag on sealed ones.
TRAILERS = (0, 8)


def bridge_frames(data: bytes) -> None:
    """The TCP link's stream split into records in pieces, each body parsed; then the
    whole input as one body (the link checks tags, not this module: a body is reached
    by anything that gets past the splitter)."""
    splitter = frames.FrameSplitter(max_frame=1 << 16)
    piece = 1 + (data[0] % 13 if data else 0)
    trailer = TRAILERS[data[0] & 1] if data else 0
    try:
        for pos in range(0, len(data), piece):
            splitter.feed(data[pos:pos + piece])
            while True:
                record = splitter.next_record(trailer)
                if record is None:
                    break
                attempt(BRIDGE, frames.parse_body, record[0])
    except BridgeProtocolError:
        pass     # the splitter refused the stream by name: what the target expects of garbage
    frames.parse_body(data)


def bridge_datagrams(data: bytes) -> None:
    """What the UDP channel's receiver does with an opened datagram: a loss report or a part."""
    if datagrams.is_report(data):
        datagrams.decode_report(data)
    else:
        datagrams.decode(data)


_LINK_KEY = link.LinkKey(bytes(range(32)))


def _peer_hello() -> bytes:
    """A genuine pilot HELLO for the robot under test (same key, same configuration)."""
    return link.LinkConnection("pilot", _LINK_KEY, b"fuzzcfg!", 2, nonce=bytes(16)).start()


def bridge_link(data: bytes) -> None:
    """bridge.wire.link.LinkConnection (robot side) fed a stream in pieces, handshake included;
    half the inputs start after a genuine peer HELLO so the fuzzer reaches AUTH and beyond."""
    robot = link.LinkConnection("robot", _LINK_KEY, b"fuzzcfg!", 1, nonce=bytes(16))
    robot.start()
    stream = (_peer_hello() if data and data[0] & 1 else b"") + data[1:]
    piece = 1 + (data[0] >> 1) % 17 if data else 1
    for pos in range(0, len(stream), piece):
        for event in robot.receive_data(stream[pos:pos + piece]):
            if isinstance(event, link.PeerHello):
                robot.send_auth()
            elif isinstance(event, link.PeerAuthenticated):
                robot.send_resume(0)


def bridge_sealed_datagrams(data: bytes) -> None:
    """bridge.wire.link.DatagramOpener over a run of datagrams, some sealed with the right key."""
    opener = link.DatagramOpener()
    opener.install(b"k" * 32)
    sealer = link.DatagramSealer(b"k" * 32)
    for index, raw in enumerate(split_records(data)):
        sealed = sealer.seal(raw) if index % 2 else raw
        inner = attempt(BRIDGE, opener.open, sealed)
        if inner is not None:
            attempt(BRIDGE, bridge_datagrams, inner)


#: Canvas ceiling for the tile target: the checks are the same, the fuzzer stays fast.
TILE_MAX_BYTES = 1 << 20


def tiles_target(data: bytes) -> None:
    tile, codec = tiles.decode_tile(data, TILE_MAX_BYTES)
    canvas = tiles.Canvas(tile.header, tile.meta)
    canvas.paste(tile, codec)
    if not 0 < canvas.completeness <= 1:
        raise AssertionError(f"a pasted tile left completeness {canvas.completeness}")


def _context(decoder: state_codec.StateDecoder) -> List[Any]:
    return [value.tolist() if isinstance(value, np.ndarray) else value
            for value in vars(decoder).values()]


def state_target(data: bytes) -> None:
    """Frames in order into one decoder; a refused frame must leave it as it was."""
    decoder = state_codec.StateDecoder()
    for frame in split_records(data):
        before = _context(decoder)
        try:
            state = decoder.decode(frame)
        except BridgeProtocolError:
            if _context(decoder) != before:
                raise AssertionError("a refused robot-state frame changed the decoder") from None
            continue
        if len(state.q) != state.layout.joints:
            raise AssertionError("decoded vectors do not match the layout")


def status_target(data: bytes) -> None:
    for command in _commands(data):
        attempt(BRIDGE, status.from_bottle, command)


def compact_target(data: bytes) -> None:
    """A full message, then deltas against it, as a TCP channel applies them."""
    records = split_records(data)
    if not records:
        return
    previous = compact.decode(records[0])
    _reencodes(previous)
    again = compact.decode(compact.encode(previous))
    if bottle.encode(again) != bottle.encode(previous):
        raise AssertionError("compact encode/decode changed a decoded Bottle")
    for record in records[1:]:
        previous = compact.decode_delta(record, previous)
        _reencodes(previous)


def fec_target(data: bytes) -> None:
    """``k`` then records: first byte bit 7 = repair, bits 0-6 = index or row."""
    if not data:
        return
    k = data[0]
    have: Dict[int, bytes] = {}
    repairs: Dict[int, bytes] = {}
    for record in split_records(data[1:]):
        if record:
            (repairs if record[0] & 0x80 else have)[record[0] & 0x7F] = record[1:]
    recovered = fec.recover(k, have, repairs)
    if set(recovered) != {index for index in range(k) if index not in have}:
        raise AssertionError(f"recover returned {sorted(recovered)} for k={k}, "
                             f"data {sorted(have)}")


def config_target(data: bytes) -> None:
    config.parse(data, "fuzz.xml")


# -- seeds -------------------------------------------------------------------------------


def _bottle_seeds() -> List[bytes]:
    return [bottle.encode(value) for value in SAMPLE_BOTTLES]


def _text_seeds() -> List[bytes]:
    return [bottle_text.format_bottle(value).encode("utf-8", "surrogateescape")
            for value in SAMPLE_BOTTLES] + [b"(1 (2 (3)) {1 2 255}) [ok] 0x1f 010 1e3 -inf"]


def _header_seeds() -> List[bytes]:
    return [b"YA\xe4\x1e\x00\x00RP" + framing.encode_sender_name("/writer"),
            b"YA\x64\x1e\x00\x00RP" + framing.encode_sender_name("tcp://h:10002/x"),
            b"YA\x61\x1e\x00\x00RP" + framing.encode_sender_name("/udp"),
            b"CONNECT /text\r\n", b"CONNACK /ack\n", b"NAME_SERVER query /x\n",
            framing.yarp_number(10002)]


def _stream_seeds() -> List[bytes]:
    def message(command: str, value: Optional[Bottle] = None) -> bytes:
        chunks = [bottle.encode(value)] if value is not None else []
        return b"".join(framing.encode_message(command, chunks))

    return [message("d", SAMPLE_BOTTLES[2]) + message("D", SAMPLE_BOTTLES[4]),
            message("a", Bottle([Vocab("list"), Vocab("out")])) + message("q"),
            message("/reader") + message("!/reader") + message("*"),
            message("d", SAMPLE_BOTTLES[8]) + framing.ACK]


def _udp_seeds() -> List[bytes]:
    seeds = []
    for value in SAMPLE_BOTTLES[2:6]:
        stream = framing.encode_message("D", [bottle.encode(value)])
        seeds.append(b"\x00" + join_records(pack_message(stream, max_datagram=48)))
    return seeds


def _line_seeds() -> List[bytes]:
    return [b"CONNECT /x\r\nd\r\n1 2 (3 4)\r\n", b"tcp://10.0.0.1:10002/\n/a/b\\\ncontinued\n",
            b"udp:/x\n\x00\r\n..."]


def _command_seeds(texts: List[str], bottles: List[Bottle]) -> List[bytes]:
    return [b"\x00" + "\n".join(texts).encode(),
            b"\x01" + join_records([bottle.encode(value) for value in bottles])]


def _nameserver_seeds() -> List[bytes]:
    texts = ["register /a", "register /b udp 1.2.3.4 5555", "query /a", "bot query /a",
             "list", "set /a ips 10.0.0.1 192.168.1.1", "get /a ips", "check /a ips 10.0.0.1",
             "subscribe /a /b", "announce /a 1", "topic /t", "type /t std_msgs String",
             "unregister /a", "route /a /b", "help", "NAME_SERVER bot list", "runners", "gc"]
    return _command_seeds(texts, [Bottle(text.split()) for text in texts])


def _admin_seeds() -> List[bytes]:
    bottles = [Bottle([Vocab(word), *rest]) for word, *rest in (
        ("help",), ("ver",), ("pray",), ("add", "/x", "udp"), ("del", "/out"), ("del", "/in"),
        ("list", Vocab("in")), ("list", Vocab("out"), "/out"), ("prop", Vocab("set"), "k", 5),
        ("prop", Vocab("get"), "k"), ("prop", Vocab("get"), "/fuzz"), ("get", Vocab("in"), "/in"),
        ("set", Vocab("out"), "/out"), ("atch", Vocab("out")))]
    return _command_seeds(["/x", "!/x", "~/in", "*", "?", "q", "[list] [out]"], bottles)


def controlboard_target(data: bytes) -> None:
    """A HAL chain's rpc:i and command:i: any Bottle is answered or refused, never a crash."""
    request = bottle.decode(data)
    reply = controlboard.respond(VirtualBoard(), request, controlboard.Stamp(), 1.0)
    if not reply or str(reply[-1]) not in ("ok", "fail", "nak"):
        raise AssertionError(f"the wrapper's answer must end in ok/fail/nak: {reply}")
    attempt((ControlBoardError,), controlboard.decode_stream, request, 2)
    attempt((ControlBoardError,), controlboard.decode_joint_data, request)


class _StubBackend:
    """Two joints, enough of :class:`walkman.hal.backend.Backend` for a ChainBoard."""

    dt = 0.001

    class _Model:
        class _Joint:
            effort = 100.0

        def joint(self, name: str) -> "_StubBackend._Model._Joint":
            return self._Joint()

    def __init__(self) -> None:
        self.model = self._Model()
        self.index = {"a": 0, "b": 1}
        self.lower, self.upper = np.array([-1.0, -2.0]), np.array([1.0, 2.0])
        self.reference = np.zeros(2)
        self.time = 0.0

    def positions(self) -> np.ndarray:
        return self.reference.copy()

    velocities = torques = temperatures = positions

    def set_references(self, indices, values) -> None:
        self.reference[np.asarray(indices, dtype=int)] = np.clip(
            values, self.lower[indices], self.upper[indices])

    def set_idle(self, indices) -> None:
        pass


def chain_board_target(data: bytes) -> None:
    """A HAL chain (ChainBoard) fed any Bottle on rpc:i or command:i, then stepped: its
    references stay finite and within the joint limits."""
    from walkman.hal.chain import ChainBoard

    backend = _StubBackend()
    board = ChainBoard("chain", ["a", "b"], backend, boot_mode="pos")
    for record in split_records(data):  # a session: mode changes, then moves...
        request = attempt(YARP, bottle.decode, record)
        if request is None:
            continue
        reply = controlboard.respond(board, request, controlboard.Stamp(), 1.0, "/fuzz")
        if not reply or str(reply[-1]) not in ("ok", "fail", "nak"):
            raise AssertionError(f"the wrapper's answer must end in ok/fail/nak: {reply}")
        command = attempt((ControlBoardError,), controlboard.decode_stream, request, 2)
        if command is not None:
            attempt((ControlBoardError,), board.command, command.what, command.joints,
                    command.values, "/fuzz", command.seq)
        for _ in range(3):
            board.step(backend.dt)
            backend.time += backend.dt
        degrees = np.degrees(backend.reference)
        if not np.all(np.isfinite(degrees)) or \
                np.any(degrees < np.degrees(backend.lower) - 1e-6) or \
                np.any(degrees > np.degrees(backend.upper) + 1e-6):
            raise AssertionError(f"references left the limits: {degrees}")


def _chain_board_seeds() -> List[bytes]:
    from yarp_lite.bottle_text import parse

    sessions = [["[set] [icmd] [cmds] ([vel] [posd])", "([vmos]) (50.0 0.0)",
                 "([dpog] 1 (1) (seq 3)) (500.0)"],
                ["[set] [vels] (10.0 20.0)", "[set] [posg] 2 (0 1) (30.0 -90.0)",
                 "[set] [rel] 0 5.0", "[set] [stos]"],
                ["[set] [icmd] [cmod] 0 [idl]", "[set] [icmd] [cmod] 0 [posd]",
                 "([dpos]) (1.0 -1.0)"]]
    return [join_records([bottle.encode(parse(text)) for text in session])
            for session in sessions]


def _controlboard_seeds() -> List[bytes]:
    from yarp_lite.bottle_text import parse

    requests = ["[get] [axes]", "get encs", "get enc 1", "[set] [posg] 1 (1) (2.0)",
                "[get] [icmd] [cmog] 2 (0 1)", "[set] [icmd] [cmds] ([posd] [pos])",
                "[get] [intm] [mods]", "[get] [pid] [pid] [pos] 0", "[get] [torq] [rngs]",
                "([dpog] 1 (1) (seq 3)) (5.0)", "([dpos]) (1.0 2.0)"]
    seeds = [bottle.encode(parse(text)) for text in requests]
    data = controlboard.JointData((1.0, 2.0), (0.0, 0.0), None, (0.5, 0.5), ("pos", "posd"))
    seeds.append(bottle.encode(controlboard.encode_joint_data(data, 2)))
    return seeds


def _frame_seeds() -> List[bytes]:
    entries = (frames.Entry(7, 2, b"\x01\x00"), frames.Entry(9, 1, bytes(40), delta=True))
    tag = bytes(8)
    return [frames.hello_body(frames.Hello("robot", b"\x01" * 8, 1 << 40, bytes(range(16)))),
            frames.auth_body(frames.Auth(bytes(16))),
            frames.resume_body(frames.Resume(300)),
            frames.data_body(entries, ack=5, seq=9),
            b"\x01" + frames.wrap(frames.data_body(entries[:1]), tag) +
            frames.wrap(frames.data_body((), ack=1), tag)]


def _datagram_seeds() -> List[bytes]:
    return [datagrams.encode(datagrams.Datagram(3, 1, 70000, 4, 2, 3, b"body")),
            datagrams.encode(datagrams.Datagram(3, 0, 1, 4, 2, 1, bytes(30), repair_row=0)),
            datagrams.encode_report(datagrams.Report(received=900, expected=1000))]


def _link_seeds() -> List[bytes]:
    """What the genuine pilot sends after its HELLO: AUTH, RESUME and a data frame."""
    robot = link.LinkConnection("robot", _LINK_KEY, b"fuzzcfg!", 1, nonce=bytes(16))
    pilot = link.LinkConnection("pilot", _LINK_KEY, b"fuzzcfg!", 2, nonce=bytes(16))
    robot_hello, pilot_hello = robot.start(), pilot.start()
    pilot.receive_data(robot_hello)
    auth = pilot.send_auth()
    robot.receive_data(pilot_hello + auth)
    pilot.receive_data(robot.send_auth() + robot.send_resume(0))
    resume = pilot.send_resume(4)
    data = pilot.send_data(frames.data_body((frames.Entry(7, 0, b"\x01\x04stop"),), seq=1))
    return [b"\x01" + auth + resume + data, b"\x03" + auth, b"\x00" + pilot_hello]


def _sealed_seeds() -> List[bytes]:
    return [join_records(_datagram_seeds() * 2)]


def _tile_seeds() -> List[bytes]:
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    depth = rng.random((12, 16), dtype=np.float32)
    cells = rng.integers(0, 256, (6, 8, 16), dtype=np.uint8)
    seeds = []
    for pixels, codec, offsets in ((image, tiles.JPEG, ()), (image, tiles.PNG, ()),
                                   (depth, tiles.ZLIB, ()), (cells, tiles.ZLIB, (0, 4, 8)),
                                   (image[..., 0].astype(np.uint16) * 200, tiles.PNG, ())):
        header = tiles.header_for(pixels, codec, 80, offsets)
        seeds.extend(tiles.split(pixels, header, compact.encode(Bottle([1, 2, "frame"])),
                                 budget=600)[:2])
    return seeds


def _state_seeds() -> List[bytes]:
    layout = state_codec.Layout((("torso", ("WaistLat", "WaistSag")),
                                 ("head", ("NeckYawj", "NeckPitchj", "x"))))
    encoder = state_codec.StateEncoder(period=0.5)
    frames_out = []
    for step in range(4):
        t = 0.5 * step
        joints = np.arange(5, dtype=float)
        frames_out.append(encoder.encode(state_codec.RobotState(
            layout, t, np.sin(t + joints), 30 * np.cos(t + joints), 40 + joints + t)))
    return [join_records(frames_out), join_records(frames_out[:1] * 2)]


def _status_seeds() -> List[bytes]:
    value = status.to_bottle({"time": 1.5, "tcp": {"bytes_out": 10, "bytes_by_id": {7: 3}},
                              "udp": {"flows": {"/points": {"mean_completeness": 0.9}}}})
    return _command_seeds([bottle_text.format_bottle(value)], [value])


def _compact_seeds() -> List[bytes]:
    seeds = []
    for old, new in ((SAMPLE_BOTTLES[4], Bottle([13, "a", 0.5, Float32(2.5), Int8(-2),
                                                 Int16(301), Int64((1 << 40) + 1)])),
                     (SAMPLE_BOTTLES[8], Bottle([(0.25 * i) for i in range(40)]))):
        seeds.append(join_records([compact.encode(old), compact.encode_delta(new, old)]))
    seeds.extend(join_records([compact.encode(value)]) for value in SAMPLE_BOTTLES)
    return seeds


def _fec_seeds() -> List[bytes]:
    payloads = [b"alpha", b"bravo-charlie", b"d", bytes(20)]
    repairs = fec.encode(payloads, 2)
    return [bytes((4,)) + join_records([bytes((0,)) + payloads[0], bytes((2,)) + payloads[2],
                                        bytes((0x80,)) + repairs[0],
                                        bytes((0x81,)) + repairs[1]]),
            bytes((4,)) + join_records([bytes((index,)) + payload
                                        for index, payload in enumerate(payloads[1:], 1)]
                                       + [bytes((0x81,)) + repairs[1]])]


def _config_seeds() -> List[bytes]:
    return [(MODELS / "bridge_paper.xml").read_bytes(), (MODELS / "bridge_drc.xml").read_bytes(),
            b'<modules><module name="a" id="1" statuses="idle run"/></modules>\n'
            b'<custom_modules><module name="c" id="3"><connection port_to_open="/x" '
            b'source_port="/y" target_port="/z" location="robot" direction="robot_to_pilot" '
            b'channel="udp" streaming="false"/></module></custom_modules>']


TARGETS: Dict[str, Target] = {target.name: target for target in (
    Target("bottle_binary", bottle_binary, YARP, _bottle_seeds, doc="yarp_lite.bottle.decode"),
    Target("bottle_text", bottle_text_target, YARP, _text_seeds,
           doc="yarp_lite.bottle_text.parse / is_complete"),
    Target("connection_header", connection_header, YARP, _header_seeds,
           doc="carrier magic, sender name, contact (framing, carriers, contact)"),
    Target("message_stream", message_stream, YARP, _stream_seeds,
           doc="framing.MessageDecoder: index, port command, payload"),
    Target("udp_datagrams", udp_datagrams, YARP, _udp_seeds,
           doc="carriers.datagram: CRC, numbering, reassembly"),
    Target("text_lines", text_lines, YARP, _line_seeds, doc="lines.split_line, Contact.parse"),
    Target("nameserver", nameserver, YARP, _nameserver_seeds,
           doc="nameserver.service: text and Bottle commands"),
    Target("admin", admin_target, YARP, _admin_seeds, doc="admin: port commands, admin Bottles"),
    Target("bridge_frames", bridge_frames, BRIDGE, _frame_seeds,
           doc="bridge.wire.frames: FrameSplitter, parse_body"),
    Target("bridge_datagrams", bridge_datagrams, BRIDGE, _datagram_seeds,
           doc="bridge.wire.datagrams.decode"),
    Target("bridge_link", bridge_link, BRIDGE, _link_seeds,
           doc="bridge.wire.link.LinkConnection: handshake, tags, frames"),
    Target("bridge_sealed_datagrams", bridge_sealed_datagrams, BRIDGE, _sealed_seeds,
           doc="bridge.wire.link.DatagramOpener: counters, tags, replay window"),
    Target("tiles", tiles_target, BRIDGE, _tile_seeds,
           doc="bridge.wire.tiles: decode_tile, Canvas"),
    Target("state_codec", state_target, BRIDGE, _state_seeds,
           doc="bridge.wire.state_codec.StateDecoder"),
    Target("status", status_target, BRIDGE + YARP, _status_seeds,
           doc="bridge.status.from_bottle"),
    Target("compact", compact_target, BRIDGE, _compact_seeds,
           doc="bridge.wire.compact: decode, decode_delta"),
    Target("fec", fec_target, BRIDGE, _fec_seeds, doc="bridge.wire.fec.recover"),
    Target("controlboard", controlboard_target, YARP, _controlboard_seeds,
           doc="walkman.hal.controlboard: respond, decode_stream, decode_joint_data"),
    Target("chain_board", chain_board_target, YARP, _chain_board_seeds,
           doc="walkman.hal.chain.ChainBoard behind rpc:i and command:i, stepped"),
    Target("config", config_target, (ConfigError,), _config_seeds, max_len=8192,
           doc="bridge.config.parse (XML)"),
)}
