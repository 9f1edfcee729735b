"""The link protocol between the two bridges, sans-IO: handshake, keys, sealed frames.

Theory of operation
-------------------
The two bridges share a secret key (a file on both PCs, see :class:`LinkKey`).
Nothing here touches a socket: :class:`LinkConnection` takes the bytes a TCP
connection received and returns events, and returns the bytes to send, as
h11's ``Connection`` does; :class:`DatagramSealer` and :class:`DatagramOpener`
do the same for single UDP datagrams.  The channels are thin socket and thread
layers around them, and tests and fuzzers drive them without a network.

Handshake (each side runs the same code, whichever dialled)::

    -> HELLO  side, config fingerprint, journal session, 16-byte fresh nonce
    <- HELLO  (the peer's)
    -> AUTH   proof = HMAC(session key, "proof" + our side)
    <- AUTH   (the peer's, checked)
    -> RESUME highest reliable number accepted from the peer's session  [sealed]
    <- RESUME (the peer's)                                                [checked]

Nothing about our state (not even how many commands we accepted) leaves before
the peer has proved the key, and UDP keys are only offered to the datagram
receiver then, so a stranger's handshake cannot displace the real peer's.

The session key is HKDF-SHA256 (RFC 5869) of the shared key over both HELLOs
(so over both nonces): a proof is only valid for this connection, a recorded
handshake cannot be replayed, and a peer that does not know the key cannot
finish.  From the session key come four directional keys: TCP robot->pilot,
TCP pilot->robot, and the same two for UDP, so a frame cannot be reflected back
to its sender.

Every frame after AUTH carries an 8-byte tag, HMAC-SHA256(direction key,
counter || body) truncated to 64 bits, where the counter is the frame's number
in that direction of the connection.  TCP delivers in order, so the counter is
implicit: a tampered, injected, dropped or replayed frame fails its tag, and
the connection (whose stream can no longer be trusted) is dropped and redialled.
The tag replaces the CRC of protocol 1, so a frame costs 6 bytes more than it
did.

UDP datagrams are not ordered, so each carries its counter:
``varint(counter) datagram tag[8]`` with the tag over both.  The receiver
keeps a sliding window of the counters it accepted (:class:`ReplayWindow`,
as IPsec and DTLS do): a counter seen before or older than the window is a
replay and is dropped.  UDP keys come from the TCP handshake, so perception only
flows once the bridges have authenticated each other; the receiver also keeps
the previous connection's key for the datagrams still in flight.

Why these primitives: HMAC-SHA256 from Python's standard library (``hmac``,
``hashlib``, ``secrets``), no new dependency and no home-made construction --
HKDF and truncated HMAC tags are the standard ones (RFC 5869, RFC 2104 /
NIST SP 800-107).  We need authenticity, integrity and replay protection,
not secrecy (the paper's link carries joint states and camera images), so an
AEAD cipher would only add bytes on a link where Table 1 counts bits.  A 64-bit
tag means a forger's chance per try is 2**-64, and every failed try is
counted, logged and costs them the connection.  Without a key (``--no-auth``)
the same code runs with a well-known key: the tags then still catch corrupted
bytes, but prove nothing.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Tuple, Union

from bridge.errors import BridgeProtocolError, BridgeUsageError, NeedMoreData
from bridge.wire import frames
from bridge.wire.frames import Auth, DataFrame, Frame, Hello, Resume
from bridge.wire.varint import Buffer, get_varint, varint

TAG_SIZE = 8
KEY_BYTES = 32
#: The replay window of a UDP receiver, in datagrams (a 1 MB cloud is ~700).
REPLAY_WINDOW = 4096
_PUBLIC_KEY = b"walkman-bridge: no key (--no-auth)"
_SIDES = ("robot", "pilot")


class AuthenticationFailed(BridgeProtocolError):
    """The peer does not know our key (or runs without one): the handshake ends."""


class ForgedInput(BridgeProtocolError):
    """A frame or datagram whose tag is wrong: forged, tampered with or corrupted."""


class ReplayedInput(BridgeProtocolError):
    """A datagram with a valid tag that was already accepted (or is too old to tell)."""


# -- the shared key --------------------------------------------------------------------


@dataclass(frozen=True)
class LinkKey:
    """The secret both bridges hold; ``keyed`` is False for ``--no-auth``."""

    secret: bytes
    keyed: bool = True
    source: str = ""

    @classmethod
    def none(cls) -> "LinkKey":
        return cls(_PUBLIC_KEY, keyed=False, source="--no-auth")

    @classmethod
    def from_file(cls, path: Union[str, Path]) -> "LinkKey":
        """Read a key file, refusing it (as ssh does) when others may read it."""
        path = Path(path)
        try:
            info = path.stat()
            text = path.read_text(encoding="ascii").strip()
        except FileNotFoundError:
            raise BridgeUsageError(f"key file {path} does not exist; create one with "
                                   f"'walkman-bridge --gen-key {path}' and copy it to the "
                                   f"other PC") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise BridgeUsageError(f"key file {path}: cannot read: {exc}") from None
        if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise BridgeUsageError(
                f"key file {path} is accessible by others (mode {stat.S_IMODE(info.st_mode):04o})"
                f"; run 'chmod 600 {path}'")
        try:
            secret = bytes.fromhex(text)
        except ValueError:
            raise BridgeUsageError(f"key file {path} does not hold a hex key (as written by "
                                   f"--gen-key)") from None
        if len(secret) < 16:
            raise BridgeUsageError(f"key file {path} holds {len(secret)} bytes; at least 16 "
                                   f"are needed (--gen-key writes {KEY_BYTES})")
        return cls(secret, keyed=True, source=str(path))


def generate_key_file(path: Union[str, Path]) -> Path:
    """Write a new random key, readable by its owner only; never overwrite one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise BridgeUsageError(f"key file {path} exists already; not overwriting it") from None
    with os.fdopen(fd, "w") as handle:
        handle.write(secrets.token_hex(KEY_BYTES) + "\n")
    return path


# -- key derivation --------------------------------------------------------------------


def _mac(key: bytes, *parts: bytes) -> bytes:
    mac = hmac.new(key, digestmod=hashlib.sha256)
    for part in parts:
        mac.update(part)
    return mac.digest()


def _hkdf(secret: bytes, salt: bytes, info: bytes) -> bytes:
    """HKDF-SHA256 (RFC 5869) for one 32-byte output block."""
    return _mac(_mac(salt, secret), info, b"\x01")


@dataclass(frozen=True)
class SessionKeys:
    """Everything one connection derives from the shared key and both HELLOs."""

    proof_robot: bytes
    proof_pilot: bytes
    tcp: Dict[str, bytes]      # direction "robot>pilot" / "pilot>robot" -> key
    udp: Dict[str, bytes]

    @classmethod
    def derive(cls, key: LinkKey, robot_hello: bytes, pilot_hello: bytes) -> "SessionKeys":
        session = _hkdf(key.secret, b"walkman-bridge 2", robot_hello + pilot_hello)

        def expand(label: str) -> bytes:
            return _mac(session, label.encode())

        directions = ("robot>pilot", "pilot>robot")
        return cls(expand("proof robot")[:frames.PROOF_SIZE],
                   expand("proof pilot")[:frames.PROOF_SIZE],
                   {d: expand("tcp " + d) for d in directions},
                   {d: expand("udp " + d) for d in directions})


def _direction(sender: str) -> str:
    return f"{sender}>{'pilot' if sender == 'robot' else 'robot'}"


def frame_tag(key: bytes, counter: int, body: Buffer) -> bytes:
    return _mac(key, counter.to_bytes(8, "big"), bytes(body))[:TAG_SIZE]


# -- the TCP connection ------------------------------------------------------------------


@dataclass(frozen=True)
class PeerHello:
    """The peer's HELLO checked: call :meth:`LinkConnection.send_auth` next."""

    hello: Hello


@dataclass(frozen=True)
class PeerAuthenticated:
    """The peer proved the key: call :meth:`LinkConnection.send_resume` next."""

    session: int


@dataclass(frozen=True)
class LinkUp:
    """The peer proved the key and said what it already has from us."""

    peer_session: int
    peer_accepted: int


@dataclass(frozen=True)
class FrameReceived:
    frame: DataFrame


Event = Union[PeerHello, PeerAuthenticated, LinkUp, FrameReceived]

#: Both halves of a connection, as h11 has them: what we sent, what the peer sent.
OUR_PHASES: Dict[str, Dict[str, str]] = {
    "idle": {"send_hello": "hello_sent"},
    "hello_sent": {"send_auth": "auth_sent"},
    "auth_sent": {"send_resume": "up"},
    "up": {},
}
THEIR_PHASES: Dict[str, Dict[str, str]] = {
    "idle": {"hello": "hello_received"},
    "hello_received": {"auth": "authenticated"},
    "authenticated": {"resume": "up"},
    "up": {"data": "up"},
}


class LinkConnection:
    """One TCP connection's link protocol: bytes in, events out, bytes to send back."""

    def __init__(self, side: str, key: LinkKey, fingerprint: bytes, session: int,
                 max_frame: int = frames.DEFAULT_MAX_FRAME,
                 nonce: Optional[bytes] = None) -> None:
        if side not in _SIDES:
            raise BridgeUsageError(f"side must be robot or pilot, not {side!r}")
        self.side = side
        self.key = key
        self.our_phase = "idle"
        self.their_phase = "idle"
        self._hello = Hello(side, fingerprint, session,
                            nonce if nonce is not None else secrets.token_bytes(frames.NONCE_SIZE),
                            key.keyed)
        self._our_hello_body = frames.hello_body(self._hello)
        self._peer_hello: Optional[Hello] = None
        self._keys: Optional[SessionKeys] = None
        self._splitter = frames.FrameSplitter(max_frame)
        self._send_counter = 0
        self._receive_counter = 0

    # -- phases --------------------------------------------------------------------

    def _ours(self, event: str) -> None:
        nxt = OUR_PHASES[self.our_phase].get(event)
        if nxt is None:
            raise BridgeUsageError(f"link ({self.side}): cannot {event} in our phase "
                                   f"{self.our_phase}")
        self.our_phase = nxt

    def _theirs(self, event: str, what: str) -> None:
        nxt = THEIR_PHASES[self.their_phase].get(event)
        if nxt is None:
            raise BridgeProtocolError(f"link: the peer sent {what} while {self.their_phase}")
        self.their_phase = nxt

    @property
    def established(self) -> bool:
        return self.our_phase == "up" and self.their_phase == "up"

    @property
    def udp_keys(self) -> Optional[Tuple[bytes, bytes]]:
        """(our sending key, our receiving key), once the peer proved the key.

        Offer the receiving key to the :class:`DatagramOpener` at
        :class:`PeerAuthenticated` (the peer may send with it before our side is
        up) and install both at :class:`LinkUp`.
        """
        if self._keys is None or self.their_phase not in ("authenticated", "up"):
            return None
        peer = "pilot" if self.side == "robot" else "robot"
        return self._keys.udp[_direction(self.side)], self._keys.udp[_direction(peer)]

    @property
    def buffered(self) -> int:
        return self._splitter.pending

    # -- sending -------------------------------------------------------------------

    def start(self) -> bytes:
        """Our HELLO, the first bytes of every connection."""
        self._ours("send_hello")
        return frames.wrap(self._our_hello_body)

    def send_auth(self) -> bytes:
        """Our proof of the key, once the peer's HELLO is known."""
        if self._keys is None:
            raise BridgeUsageError("link: AUTH before the peer's HELLO")
        self._ours("send_auth")
        proof = self._keys.proof_robot if self.side == "robot" else self._keys.proof_pilot
        return frames.wrap(frames.auth_body(Auth(proof)))

    def send_resume(self, accepted: int) -> bytes:
        """The sealed RESUME, once the peer proved the key."""
        if self.their_phase not in ("authenticated", "up"):
            raise BridgeUsageError("link: RESUME before the peer proved the key")
        self._ours("send_resume")
        return self._seal(frames.resume_body(Resume(accepted)))

    def send_data(self, body: bytes) -> bytes:
        """Seal one data frame body (from :func:`bridge.wire.frames.data_body`)."""
        if self.our_phase != "up":
            raise BridgeUsageError(f"link: data before the handshake ({self.our_phase})")
        return self._seal(body)

    def _seal(self, body: bytes) -> bytes:
        assert self._keys is not None
        tag = frame_tag(self._keys.tcp[_direction(self.side)], self._send_counter, body)
        self._send_counter += 1
        return frames.wrap(body, tag)

    # -- receiving -----------------------------------------------------------------

    def receive_data(self, data: Buffer) -> List[Event]:
        """Feed received bytes and take every event they complete; raises a
        :class:`BridgeProtocolError` on any violation (events before it are lost:
        a handshake answers each event before the next, so it uses :meth:`next_event`)."""
        self.feed(data)
        events: List[Event] = []
        while (event := self.next_event()) is not None:
            events.append(event)
        return events

    def feed(self, data: Buffer) -> None:
        """Buffer received bytes; :meth:`next_event` takes what they complete."""
        self._splitter.feed(data)

    def next_event(self) -> Optional[Event]:
        """The next event, None when more bytes are needed, or a
        :class:`BridgeProtocolError` for the first violation: a side answers the peer's
        HELLO with its AUTH before it judges the peer's AUTH read in the same bytes, so
        the peer learns the outcome from our proof instead of a bare close."""
        while True:
            sealed = self.their_phase in ("authenticated", "up")
            record = self._splitter.next_record(
                TAG_SIZE if sealed else 0,
                None if sealed else frames.MAX_HANDSHAKE_FRAME)
            if record is None:
                return None
            body, tag = record
            if sealed:
                self._check_tag(body, tag)
            event = self._on_frame(frames.parse_body(body))
            if event is not None:
                return event

    def _check_tag(self, body: bytes, tag: bytes) -> None:
        assert self._keys is not None
        peer = "pilot" if self.side == "robot" else "robot"
        expected = frame_tag(self._keys.tcp[_direction(peer)], self._receive_counter, body)
        if not hmac.compare_digest(expected, tag):
            raise ForgedInput(f"frame {self._receive_counter} from the peer fails its "
                              f"authentication tag (forged, tampered with or corrupted)")
        self._receive_counter += 1

    def _on_frame(self, frame: Frame) -> Optional[Event]:
        if isinstance(frame, Hello):
            self._theirs("hello", "HELLO")
            self._check_hello(frame)
            self._peer_hello = frame
            peer_body = frames.hello_body(frame)
            robot, pilot = (self._our_hello_body, peer_body) if self.side == "robot" \
                else (peer_body, self._our_hello_body)
            self._keys = SessionKeys.derive(self.key, robot, pilot)
            return PeerHello(frame)
        if isinstance(frame, Auth):
            self._theirs("auth", "AUTH")
            assert self._keys is not None and self._peer_hello is not None
            expected = self._keys.proof_pilot if self.side == "robot" else self._keys.proof_robot
            if not hmac.compare_digest(expected, frame.proof):
                raise AuthenticationFailed(self._why_auth_failed(self._peer_hello))
            return PeerAuthenticated(self._peer_hello.session)
        if isinstance(frame, Resume):
            self._theirs("resume", "RESUME")
            assert self._peer_hello is not None
            return LinkUp(self._peer_hello.session, frame.accepted)
        self._theirs("data", "a data frame")
        return FrameReceived(frame)

    def _check_hello(self, hello: Hello) -> None:
        ours = self._hello
        if hello.side == ours.side:
            raise BridgeProtocolError(f"peer is also the {ours.side} side")
        if hello.fingerprint != ours.fingerprint:
            raise BridgeProtocolError("peer runs a different bridge configuration "
                                      "(ids would not match); use the same file on both sides")
        if hello.keyed != self.key.keyed:
            # Said at once, on both sides: waiting for the AUTH frames let the first side to
            # notice close the connection before the other could name the mismatch.
            raise AuthenticationFailed(self._why_auth_failed(hello))

    def _why_auth_failed(self, hello: Hello) -> str:
        if hello.keyed and not self.key.keyed:
            return ("authentication failed: the peer has a key and we run with --no-auth; "
                    "give both bridges the same key file")
        if not hello.keyed and self.key.keyed:
            return ("authentication failed: the peer runs without a key (--no-auth); "
                    "give both bridges the same key file")
        return ("authentication failed: the peer does not hold our key (the key files "
                "differ, or it is not our bridge)")


# -- UDP datagrams --------------------------------------------------------------------


#: Bytes a sealed datagram adds to the datagram inside it (counter up to 2**35, tag).
SEAL_OVERHEAD = 5 + TAG_SIZE


class DatagramSealer:
    """Numbers and tags our datagrams with one UDP key."""

    def __init__(self, key: bytes) -> None:
        self.key = key
        self.counter = 0

    def seal(self, inner: bytes) -> bytes:
        counter = varint(self.counter)
        self.counter += 1
        return counter + inner + _mac(self.key, counter, inner)[:TAG_SIZE]


class ReplayWindow:
    """Which counters were accepted: the highest one and a bitmap below it."""

    def __init__(self, size: int = REPLAY_WINDOW) -> None:
        self.size = size
        self.highest = -1
        self._seen = 0      # bit i: counter highest - i was accepted

    def check(self, counter: int) -> None:
        """Raise :class:`ReplayedInput` if ``counter`` cannot be accepted."""
        if counter > self.highest:
            return
        offset = self.highest - counter
        if offset >= self.size:
            raise ReplayedInput(f"datagram {counter} is older than the replay window "
                                f"(newest {self.highest})")
        if self._seen >> offset & 1:
            raise ReplayedInput(f"datagram {counter} was already received")

    def accept(self, counter: int) -> None:
        self.check(counter)
        if counter > self.highest:
            shift = counter - self.highest
            self._seen = (self._seen << shift | 1) & ((1 << self.size) - 1) \
                if shift < self.size else 1
            self.highest = counter
        else:
            self._seen |= 1 << (self.highest - counter)


class DatagramOpener:
    """Checks the peer's datagrams against the current, previous and pending keys.

    ``pending`` is the key of a connection still in its handshake: the peer may
    already send with it.  A datagram that verifies under any of them was sealed
    by a holder of the shared key, so accepting it is safe.
    """

    def __init__(self) -> None:
        self._keys: List[Tuple[bytes, ReplayWindow]] = []   # newest first, at most 2
        self._pending: Optional[Tuple[bytes, ReplayWindow]] = None

    @property
    def keyed(self) -> bool:
        return bool(self._keys) or self._pending is not None

    def install(self, key: bytes) -> None:
        """The receiving key of a connection whose peer proved the shared key."""
        if self._pending is not None and self._pending[0] == key:
            entry = self._pending
            self._pending = None
        elif self._keys and self._keys[0][0] == key:
            return
        else:
            entry = (key, ReplayWindow())
        self._keys = [entry, *self._keys][:2]

    def offer(self, key: bytes) -> None:
        """The receiving key of a handshake in progress."""
        if not any(existing == key for existing, _ in self._keys):
            self._pending = (key, ReplayWindow())

    def open(self, raw: Buffer) -> bytes:
        """The datagram inside ``raw``, or a :class:`BridgeProtocolError` subclass."""
        if not self.keyed:
            raise ForgedInput("datagram before the link's first handshake (no key yet)")
        if len(raw) < 1 + TAG_SIZE + 1:
            raise BridgeProtocolError(f"sealed datagram of {len(raw)} bytes is too short")
        try:
            counter, pos = get_varint(raw, 0, "datagram counter")
        except NeedMoreData as exc:
            raise BridgeProtocolError(f"datagram counter cut: {exc}") from None
        end = len(raw) - TAG_SIZE
        if pos >= end:
            raise BridgeProtocolError("sealed datagram holds no datagram")
        head, inner, tag = bytes(raw[:pos]), bytes(raw[pos:end]), bytes(raw[end:])
        candidates = list(self._keys) + ([self._pending] if self._pending else [])
        for key, window in candidates:
            if hmac.compare_digest(_mac(key, head, inner)[:TAG_SIZE], tag):
                window.accept(counter)
                return inner
        raise ForgedInput("datagram fails its authentication tag (forged, tampered with, "
                          "or sealed with another key)")
