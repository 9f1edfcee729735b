"""YARP's port authentication (``auth.conf``, AuthHMAC) without any I/O.

Theory of operation
-------------------
When an ``auth.conf`` with ``[AUTH] key ...`` is found, real YARP 3.5
(``impl/AuthHMAC.cpp``, ``impl/TcpFace.cpp``) authenticates *every* TCP
connection -- to ports and to the name server, whatever the carrier -- before
the 8-byte carrier header.  Both sides prove they know the key with
HMAC-SHA256 over fresh 8-byte nonces; each message is ``nonce + mac``
(40 bytes), and each mac covers every nonce sent so far:

=====  ==================  ===========================================
 msg    direction            bytes
=====  ==================  ===========================================
 1      acceptor -> caller   nonce1, HMAC(key, nonce1)
 2      caller -> acceptor   nonce2, HMAC(key, nonce1 nonce2)
 3      acceptor -> caller   nonce3, HMAC(key, nonce1 nonce2 nonce3)
=====  ==================  ===========================================

The side that accepted the socket (``TcpFace::read``, ``authSource``) speaks
first; the side that connected (``TcpFace::write``, ``authDest``) checks the
challenge before answering, so a wrong key is seen by the caller at message 1
and by the acceptor at message 2.  Each read and write may take 2 s.  Real
YARP then drops the connection without closing its socket; we close ours.

:class:`Handshake` is that exchange as a state machine over bytes (h11
style: :meth:`~Handshake.receive_data` in, :meth:`~Handshake.data_to_send`
out).  Its whole life is the transition table :data:`_TRANSITIONS`.

Where the key comes from (``AuthHMAC::AuthHMAC``): ``auth.conf`` found the way
the ResourceFinder singleton's ``findFile`` finds it (:func:`candidates`),
read as a ``Property`` configuration file (:func:`parse_auth_conf`), group
``[AUTH]``, value ``key`` *as a string*: a number (``key 1234``) reads as an
empty string, which leaves authentication off with a warning, as in YARP.
"""

from __future__ import annotations

import codecs
import enum
import hashlib
import hmac
import logging
import os
import secrets
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Mapping, Optional, Set, Tuple

from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import format_bottle, format_value, is_complete, parse
from yarp_lite.errors import AuthenticationError, LocalProtocolError, RemoteProtocolError
from yarp_lite.lines import split_line

log = logging.getLogger("yarp_lite.auth")

NONCE_LENGTH = 8
DIGEST_LENGTH = 32
MESSAGE_LENGTH = NONCE_LENGTH + DIGEST_LENGTH
#: YARP's read and write timeout while authenticating (``TcpFace``), seconds.
TIMEOUT = 2.0
FILE_NAME = "auth.conf"
GROUP = "AUTH"


def new_nonce() -> bytes:
    return secrets.token_bytes(NONCE_LENGTH)


def sign(key: bytes, *nonces: bytes) -> bytes:
    """HMAC-SHA256 of the concatenated nonces: the mac of each message."""
    return hmac.new(key, b"".join(nonces), hashlib.sha256).digest()


# --------------------------------------------------------------------------
# Configuration


@dataclass(frozen=True)
class AuthConfig:
    """The key this process authenticates with; ``key is None`` means off.

    ``path`` is the ``auth.conf`` used (None when none was found) and
    ``note`` says, for messages, where the key came from or why there is none.
    """

    key: Optional[bytes]
    path: Optional[Path] = None
    note: str = "authentication off"

    @property
    def enabled(self) -> bool:
        return self.key is not None

    @classmethod
    def with_key(cls, key: str, path: Optional[Path] = None) -> "AuthConfig":
        where = f"key from {path}" if path else "key given in code"
        return cls(key.encode("utf-8", "surrogateescape"), path, where)


DISABLED = AuthConfig(None)

Environ = Mapping[str, str]


def _dir_from(env: Environ, key: str, alt_key: str, alt_default: str) -> str:
    """``environment::get_string(key, altKey, altDefault, "/yarp")``: set-but-empty counts."""
    if key in env:
        return env[key]
    return env.get(alt_key, alt_default) + "/yarp"


def _dirs_from(env: Environ, key: str, alt_key: str, alt_default: str) -> List[str]:
    """``environment::get_path(...)``: a ``:`` list; the fallback gets ``/yarp`` appended."""
    if key in env:
        return [part for part in env[key].split(":") if part]
    return [part + "/yarp" for part in env.get(alt_key, alt_default).split(":") if part]


def _search_dirs(env: Environ) -> Tuple[List[str], List[str]]:
    """([config home, data home, *config dirs], [*data dirs]): user+sysadmin, installed."""
    home = env.get("HOME", "")
    config_home = _dir_from(env, "YARP_CONFIG_HOME", "XDG_CONFIG_HOME", home + "/.config")
    data_home = _dir_from(env, "YARP_DATA_HOME", "XDG_DATA_HOME", home + "/.local/share")
    user = [directory for directory in (config_home, data_home) if directory]
    user += _dirs_from(env, "YARP_CONFIG_DIRS", "XDG_CONFIG_DIRS", "/etc/xdg")
    return user, _dirs_from(env, "YARP_DATA_DIRS", "XDG_DATA_DIRS", "/usr/local/share:/usr/share")


def _pathd_dirs(env: Environ, data_dirs: List[str], exists: Callable[[str], bool],
                read: Callable[[str], str]) -> List[str]:
    """Bundle paths of the first ``<data dir>/config/path.d`` (``[search NAME]`` + ``path``)."""
    for data_dir in data_dirs:
        pathd = f"{data_dir}/config/path.d"
        if exists(pathd):
            sections = parse_property(read(pathd), env)
            found: List[str] = []
            for name in sections.get("search", [])[1:]:
                for line in sections.get(str(name), [])[1:]:
                    if isinstance(line, list) and line and _as_text(line[0]) == "path":
                        found += [_as_text(item) for item in line[1:]]
                        break
            return found
    return []


def candidates(environ: Optional[Environ] = None, cwd: Optional[str] = None,
               exists: Callable[[str], bool] = os.path.exists,
               read: Callable[[str], str] = lambda path: _read_config(Path(path))) -> List[str]:
    """Where ``ResourceFinder::getResourceFinderSingleton().findFile("auth.conf")`` looks.

    The unconfigured singleton searches (``ResourceFinderOptions::ModuleDefault``):
    the current directory; ``robots/$YARP_ROBOT_NAME`` (``default``) under the
    user, system and installed directories; then ``$YARP_CONFIG_HOME``,
    ``$YARP_DATA_HOME``, each of ``$YARP_CONFIG_DIRS`` and ``$YARP_DATA_DIRS``
    (XDG fallbacks + ``/yarp``), then the bundles of ``config/path.d``.
    ``exists``/``read`` are injectable so tests need no real filesystem.
    """
    env = os.environ if environ is None else environ
    here = os.getcwd() if cwd is None else cwd
    user, data_dirs = _search_dirs(env)
    installed = [*user, *data_dirs, *_pathd_dirs(env, data_dirs, exists, read)]
    robot = env.get("YARP_ROBOT_NAME", "default")
    robot_dirs = [f"{base}/robots/{robot}" for base in installed
                  if exists(f"{base}/robots/{robot}")]
    unique: List[str] = []
    for directory in (here, *robot_dirs, *installed):
        path = f"{directory}/{FILE_NAME}"
        if path not in unique:
            unique.append(path)
    return unique


def _read_config(path: Path) -> str:
    """``Property::readFile`` with ``allowDir``: a directory reads as its ``*.ini`` files."""
    if path.is_dir():
        parts = []
        for entry in sorted(path.iterdir(), key=lambda item: item.name.encode()):
            if entry.name.endswith(".ini"):
                parts.append(entry.read_text("utf-8", "surrogateescape") + "\n[]\n")
        return "".join(parts)
    return path.read_text("utf-8", "surrogateescape")


def _strip_comment(line: str) -> str:
    """``//`` anywhere and ``#`` after a space end a line, outside double quotes."""
    if "//" not in line and "#" not in line:
        return line
    quoted, prespace, slashes = False, True, 0
    for index, ch in enumerate(line):
        if ch == '"':
            quoted = not quoted
        if quoted:
            slashes, prespace = 0, False
            continue
        if ch == "/":
            slashes += 1
            if slashes == 2:
                return line[:index - 1]
        else:
            slashes = 0
            if ch == "#" and prespace:
                return line[:max(index - 1, 0)] if index else ""
        prespace = ch in " \t"
    return line


def _lookup(name: str, env: Environ, known: Dict[str, list]) -> str:
    """``Property::expand``'s value of ``$name``: environment, CONFIG_PATH, earlier keys."""
    value = env.get(name, "") if name else ""
    if not value and name in known and len(known[name]) > 1:
        value = _as_text(known[name][1])
    if not value and name == "__YARP__":
        value = "1"
    return value.replace("\\", "\\\\")


def _expand(text: str, env: Environ, known: Dict[str, list]) -> str:
    """``$VAR`` and ``${VAR}`` as ``Property::expand`` replaces them (unknown: empty)."""
    if "$" not in text:
        return text
    out: List[str] = []
    name = ""
    in_var = paren = escaped = False
    for index in range(len(text) + 1):
        ch = text[index] if index < len(text) else ""
        if escaped:
            if in_var:
                name += ch
            else:
                out.append("\\" + ch)
            escaped = False
            continue
        if ch == "\\":
            escaped = True
            continue
        if in_var:
            if ch.isalnum() or ch == "_":
                name += ch
                continue
            if ch in "({" and ch and not name:
                paren = True
                continue
            in_var = False
            out.append(_lookup(name, env, known))
            name = ""
            if paren and ch in ("}", ")"):
                continue
        if not in_var:
            if ch == "$":
                in_var, paren = True, False
                continue
            out.append(ch)
    return "".join(out)


def parse_property(text: str, environ: Optional[Environ] = None,
                   config_path: str = "") -> Dict[str, list]:
    """``Property::fromConfig`` as far as ``auth.conf`` needs it.

    Returns each top-level key and each ``[group]`` as YARP stores them: a
    list whose first item is the name (``{"AUTH": ["AUTH", ["key", "s3"]]}``).
    Lines join while brackets or quotes are open; ``key = value`` drops the
    ``=``; a repeated group appends to the first (so the first ``key`` wins);
    ``[include ...]`` and ``[import ...]`` are not followed.
    """
    env = dict(os.environ if environ is None else environ)
    if config_path and "CONFIG_PATH" not in env:
        env["CONFIG_PATH"] = config_path
    data = (text + "\n").encode("utf-8", "surrogateescape")
    sections: Dict[str, list] = {}
    tag = ""
    start = 0
    while True:
        found = split_line(data, start)
        if found is None:
            break
        line, start = found
        while found is not None and not is_complete(line):
            found = split_line(data, start)
            if found is not None:
                line, start = line + found[0], found[1]
        if found is None:
            break  # input ended inside brackets or quotes: YARP drops that line
        line = _expand(_strip_comment(line), env, sections)
        if line.startswith("[") and "]" in line:
            inner = line[1:line.index("]")]
            words = parse(inner) if " " in inner else Bottle()
            if len(words) > 1 and str(words[0]) in ("include", "import"):
                tag = ""  # other files are not followed
                continue
            if len(words) == 2:  # [search icub]: "icub" joins group "search", lines go to icub
                sections.setdefault(str(words[0]), [str(words[0])]).append(str(words[1]))
                inner = str(words[1])
            tag = inner
            if tag:
                sections.setdefault(tag, [tag])
            continue
        words = list(parse(line))
        if not words:
            continue
        if len(words) > 1 and words[1] == "=":
            words = [words[0], *words[2:]]
        if tag:
            sections[tag].append(words)
        else:
            sections[_as_text(words[0])] = words
    return sections


def key_of(sections: Dict[str, list]) -> Tuple[Optional[str], str]:
    """``config.findGroup("AUTH").find("key").asString()``: (key, why not).

    ``Bottle::find`` takes the first ``(key value...)`` line; ``asString`` of
    a number or a list is empty, which YARP reports as no key.
    """
    group = sections.get(GROUP)
    if group is None:
        return None, f'no "{GROUP}" group'
    value: object = None
    for index, item in enumerate(group):
        if isinstance(item, list):
            if item and _as_text(item[0]) == "key":
                value = item[1] if len(item) > 1 else None
                break
        elif _as_text(item) == "key":
            value = group[index + 1] if index + 1 < len(group) else None
            break
    text = _as_string(value)
    if text:
        return text, ""
    return None, f'no "key" found in "{GROUP}" group'


def _as_text(value: object) -> str:
    """``Value::toString``: strings bare, vocabs without brackets, lists unwrapped."""
    if isinstance(value, (list, Bottle)):
        return format_bottle(value)
    text = format_value(value)
    if isinstance(value, Vocab):
        return text[1:-1] if text.startswith("[") else text  # true / false stay words
    return value if isinstance(value, str) else text


def _as_string(value: object) -> str:
    """``Value::asString``: the text of a string or a vocab, else empty (numbers too)."""
    return _as_text(value) if isinstance(value, str) else ""


def parse_auth_conf(text: str, environ: Optional[Environ] = None,
                    config_path: str = "") -> Tuple[Optional[str], str]:
    """The key in an ``auth.conf``'s text, or None and why there is none."""
    return key_of(parse_property(text, environ, config_path))


_reported: Set[Tuple[Optional[str], str]] = set()


def _report_once(path: Optional[Path], message: str, level: int) -> None:
    """YARP says "Authentication enabled." or why not; we say it once per file and outcome."""
    mark = (str(path) if path else None, message)
    if mark not in _reported:
        _reported.add(mark)
        log.log(level, "%s", message)


def load(environ: Optional[Environ] = None, cwd: Optional[str] = None) -> AuthConfig:
    """The key this process would use now (``AuthHMAC``'s constructor).

    Searched on each call, so a changed environment or file counts at once
    (real YARP stops looking after it once found nothing: a process detail,
    not a wire one).  Ports call it when they open, callers per connection,
    as YARP's ``TcpFace`` objects do.
    """
    env = os.environ if environ is None else environ
    searched = candidates(env, cwd)
    path = next((Path(candidate) for candidate in searched if os.path.exists(candidate)), None)
    if path is None:
        return AuthConfig(None, None, "no auth.conf found (looked at " + ", ".join(searched) + ")")
    try:
        text = _read_config(path)
    except OSError as exc:
        _report_once(path, f"cannot read {path}: {exc.strerror or exc}; authentication disabled",
                     logging.WARNING)
        return AuthConfig(None, path, f"{path} is unreadable")
    key, why = parse_auth_conf(text, env, str(path.parent))
    if key is None:
        _report_once(path, f"{path}: {why}; authentication disabled", logging.WARNING)
        return AuthConfig(None, path, f"{path} has {why}")
    _report_once(path, f"Authentication enabled (key from {path})", logging.INFO)
    return AuthConfig.with_key(key, path)


# --------------------------------------------------------------------------
# The handshake


class Role(enum.Enum):
    """Which end of the TCP connection we are; decides who speaks first."""

    ACCEPTOR = "acceptor"    # TcpFace::read -> AuthHMAC::authSource
    CONNECTOR = "connector"  # TcpFace::write -> AuthHMAC::authDest


class State(enum.Enum):
    AWAIT_CHALLENGE = "waiting for the challenge"          # connector, message 1
    AWAIT_ANSWER = "waiting for the answer to our challenge"  # acceptor, message 2
    AWAIT_CONFIRMATION = "waiting for the confirmation"    # connector, message 3
    DONE = "authenticated"
    FAILED = "failed"


@dataclass(frozen=True)
class _Step:
    """What receiving one 40-byte message in a state does."""

    next: State
    reply: bool        # answer with our own nonce + mac
    refusal: str       # why the peer is refused when its mac is wrong


#: Everything that moves a handshake: (role, state) -> step on a complete message.
_TRANSITIONS: Dict[Tuple[Role, State], _Step] = {
    (Role.CONNECTOR, State.AWAIT_CHALLENGE): _Step(
        State.AWAIT_CONFIRMATION, True,
        "the peer's challenge is not signed with our key (a different key, or none, "
        "in its auth.conf?)"),
    (Role.ACCEPTOR, State.AWAIT_ANSWER): _Step(
        State.DONE, True,
        "the peer's answer is not signed with our key (a different key, or none, "
        "in its auth.conf?)"),
    (Role.CONNECTOR, State.AWAIT_CONFIRMATION): _Step(
        State.DONE, False, "the peer's confirmation is not signed with our key"),
}
_FIRST_STATE = {Role.CONNECTOR: State.AWAIT_CHALLENGE, Role.ACCEPTOR: State.AWAIT_ANSWER}


@dataclass
class Handshake:
    """One side of the three-message exchange; bytes in, bytes out, no I/O.

    Feed whatever arrived to :meth:`receive_data` (any chunking), send what
    :meth:`data_to_send` returns, until :attr:`done`.  A wrong mac raises
    :class:`AuthenticationError` and the machine stays failed.  Bytes that
    arrive after the handshake belong to the carrier: :attr:`trailing`.
    """

    role: Role
    config: AuthConfig
    where: str = ""
    nonce: Callable[[], bytes] = new_nonce
    state: State = field(init=False)
    trailing: bytes = field(init=False, default=b"")
    _nonces: List[bytes] = field(init=False, default_factory=list)
    _inbox: bytearray = field(init=False, default_factory=bytearray)
    _outbox: bytearray = field(init=False, default_factory=bytearray)

    def __post_init__(self) -> None:
        if self.config.key is None:
            raise LocalProtocolError("authentication is off: no key to authenticate with")
        self.state = _FIRST_STATE[self.role]
        if self.role is Role.ACCEPTOR:
            self._say()

    @property
    def done(self) -> bool:
        return self.state is State.DONE

    @property
    def bytes_needed(self) -> int:
        """Bytes still missing from the message awaited now (0 once done)."""
        if self.state in (State.DONE, State.FAILED):
            return 0
        return MESSAGE_LENGTH - len(self._inbox)

    def data_to_send(self) -> bytes:
        out = bytes(self._outbox)
        self._outbox.clear()
        return out

    def receive_data(self, data: bytes) -> None:
        if self.state is State.FAILED:
            raise LocalProtocolError(f"{self.role.value} handshake already failed; "
                                     "the connection must be closed")
        if self.state is State.DONE:
            self.trailing += bytes(data)
            return
        self._inbox += data
        while self.state not in (State.DONE, State.FAILED) and len(self._inbox) >= MESSAGE_LENGTH:
            message = bytes(self._inbox[:MESSAGE_LENGTH])
            del self._inbox[:MESSAGE_LENGTH]
            self._step(message)
        if self.state is State.DONE and self._inbox:
            self.trailing += bytes(self._inbox)
            self._inbox.clear()

    def _step(self, message: bytes) -> None:
        step = _TRANSITIONS[(self.role, self.state)]
        nonce, mac = message[:NONCE_LENGTH], message[NONCE_LENGTH:]
        self._nonces.append(nonce)
        if not hmac.compare_digest(mac, sign(self.config.key, *self._nonces)):
            raise self.failure(step.refusal)
        self.state = step.next
        if step.reply:
            self._say()

    def _say(self) -> None:
        nonce = self.nonce()
        if len(nonce) != NONCE_LENGTH:
            raise LocalProtocolError(f"a nonce is {NONCE_LENGTH} bytes, got {len(nonce)}")
        self._nonces.append(nonce)
        self._outbox += nonce + sign(self.config.key, *self._nonces)

    def failure(self, reason: str) -> AuthenticationError:
        """Mark the handshake failed; the error names the phase and the key's file."""
        phase = self.state.value
        self.state = State.FAILED
        return AuthenticationError(
            f"authentication failed ({self.role.value}, {phase}): {reason}; {self.config.note}",
            self.where)


# --------------------------------------------------------------------------
# A peer that authenticates when we do not


def is_text(data: bytes) -> bool:
    """Could ``data`` be the start of YARP text (name server answers, text carriers)?

    Printable or white space, and UTF-8 (a multi-byte character may be cut at the
    end): a key-holding peer's 40 random bytes of nonce and mac pass the first test
    about once in 120 connections (a CI run printed them as a name server's answer),
    the second practically never.
    """
    if not all(byte >= 0x20 and byte != 0x7F or byte in (0x09, 0x0A, 0x0D) for byte in data):
        return False
    try:
        codecs.getincrementaldecoder("utf-8")().decode(data, final=False)
    except UnicodeDecodeError:
        return False
    return True


def unexpected_answer(config: AuthConfig, where: str, detail: str) -> RemoteProtocolError:
    """The error for a peer whose first bytes are not YARP.

    A port that requires authentication opens every connection with 40
    bytes of nonce and mac; to a caller without a key those look like
    garbage.  When this side has no key, say that this is the likely reason
    (and where we looked for ``auth.conf``) instead of a bare protocol error.
    """
    if config.enabled:
        return RemoteProtocolError(detail, where)
    return AuthenticationError(
        f"authentication failed? {detail}: the peer probably requires authentication "
        f"(an auth.conf with an [AUTH] key), and this program has none: {config.note}", where)
