"""``walkman-bridge``: one side of the robot/pilot bridge.

Usage::

    walkman-bridge --gen-key ~/.config/walkman/bridge.key   # once; copy it to the other PC
    walkman-bridge --side robot --config models/bridge_drc.xml --peer 169.254.10.2 --key K
    walkman-bridge --side pilot --config models/bridge_drc.xml --peer 169.254.10.1 --key K
    walkman-bridge --check models/bridge_drc.xml      # validate, print the id table

Both sides must use the same configuration file (the handshake compares a
fingerprint) and the same key file (the handshake proves it both ways; every
frame and datagram then carries an authentication tag, see :mod:`bridge.wire.link`).
The key file must be readable by its owner only, as ssh wants of its keys;
``--no-auth`` runs without one, for a closed lab network.  The robot side listens on ``--port`` and the pilot side dials
it; both send UDP to the peer's ``--udp-port``.  Talk to a running bridge with
``yarp rpc /bridge/<side>/rpc:i`` (``status``) or read
``/bridge/<side>/status:o``.
"""

from __future__ import annotations

import argparse
import logging
import re
import signal
import sys
import threading
from pathlib import Path
from typing import List, Optional

from bridge import config as bridge_config
from bridge.config import ConfigError
from bridge.errors import BridgeUsageError
from bridge.transport.journal import default_state_dir
from bridge.wire.link import LinkKey, generate_key_file
from nodekit import stacks
from nodekit.logs import configure_logging
from walkman.realtime import BRIDGE_PRIORITY, make_process_realtime

DEFAULT_TCP_PORT = 10150
DEFAULT_UDP_PORT = 10151


def parse_rate(text: str) -> float:
    """``9600``, ``600k``, ``1M`` (bits per second)."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmM]?)(?:bit/s|bps)?\s*", text)
    if not match:
        raise argparse.ArgumentTypeError(f"{text!r} is not a rate like 9600, 600k or 1M")
    value = float(match.group(1)) * {"": 1, "k": 1e3, "m": 1e6}[match.group(2).lower()]
    if value <= 0:
        raise argparse.ArgumentTypeError("a rate must be positive")
    return value


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"port {value} is outside 1..65535")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="walkman-bridge", description="One side of the Walk-Man robot/pilot bridge.")
    parser.add_argument("--check", metavar="CONFIG",
                        help="validate a configuration and print its flows, then exit")
    parser.add_argument("--gen-key", metavar="FILE", type=Path,
                        help="write a new random key to FILE (mode 600), then exit")
    parser.add_argument("--side", choices=("robot", "pilot"))
    parser.add_argument("--config", type=Path, help="bridge XML (same file on both sides)")
    parser.add_argument("--peer", help="host name or address of the other side")
    auth = parser.add_mutually_exclusive_group()
    auth.add_argument("--key", type=Path, metavar="FILE",
                      help="the key file both bridges share (from --gen-key; mode 600)")
    auth.add_argument("--no-auth", action="store_true",
                      help="run without a key: frames are checked but not authenticated")
    parser.add_argument("--port", type=_port, default=DEFAULT_TCP_PORT,
                        help=f"TCP channel port (default {DEFAULT_TCP_PORT})")
    parser.add_argument("--udp-port", type=_port, default=DEFAULT_UDP_PORT,
                        help=f"our UDP port (default {DEFAULT_UDP_PORT})")
    parser.add_argument("--peer-udp-port", type=_port,
                        help="the peer's UDP port (default: same as --udp-port)")
    role = parser.add_mutually_exclusive_group()
    role.add_argument("--listen", dest="listen", action="store_true", default=None,
                      help="accept the TCP connection (default on the robot side)")
    role.add_argument("--dial", dest="listen", action="store_false",
                      help="open the TCP connection (default on the pilot side)")
    parser.add_argument("--udp-rate", type=parse_rate,
                        help="pace UDP output to this many bit/s (e.g. 600k); default: "
                             "unpaced")
    parser.add_argument("--link-rate", type=parse_rate,
                        help="what the link carries, bit/s (e.g. 9600 or 1M): the bridge "
                             "keeps the radio's queue short, so a stop-all never waits behind "
                             "telemetry (streaming data waits for room); default: no budget")
    parser.add_argument("--link-timeout", type=float, default=5.0,
                        help="seconds of silence before the link is declared down")
    parser.add_argument("--queue-limit", type=int, default=1000,
                        help="reliable messages kept while the link is down (default 1000)")
    parser.add_argument("--fsync", action="store_true",
                        help="sync every reliable message to disk, so queued commands also "
                             "survive a power cut (costs the disk's sync time per command)")
    parser.add_argument("--state-dir", type=Path,
                        help="where the journal lives (default "
                             "$XDG_STATE_HOME/walkman-bridge/<side>)")
    parser.add_argument("-v", "--verbose", action="store_true")
    return parser


def describe(config: bridge_config.BridgeConfig) -> str:
    lines = [f"{config.path}: period {config.period:g} s, gather {config.gather:g} s",
             f"{'id':>3} {'kind':>4}  {'flow':<34} {'from':<6} {'via':<4} {'mode':<9} ports"]
    for c in config.channels:
        mode = "reliable" if c.reliable else "latest"
        if c.middleware == "ros":
            ports = f"ROS {c.ros_type}"
        else:
            ports = f"{c.feed_port or '(writers)'} -> {c.listen_port} | {c.emit_port} -> " \
                    f"{c.deliver_port or '(readers)'}"
        lines.append(f"{c.id:>3} {c.kind:>4}  {c.label:<34} {c.source:<6} {c.transport:<4} "
                     f"{mode:<9} {ports}")
    if config.robot_state:
        state = config.robot_state
        lines.append(f"{state.id:>3} {state.key.kind:>4}  {state.robot + '/state':<34} "
                     f"{'robot':<6} {state.transport:<4} {'latest':<9} "
                     f"/{state.robot}/<chain>/stateSI:o, "
                     f"{config.state_rate:g} Hz")
    if config.emergency_stop:
        stop = config.emergency_stop
        lines.append(f"{stop.id:>3} {0:>4}  {'stop_all':<34} {'pilot':<6} {'both':<4} "
                     f"{'urgent':<9} rpc stop_all/release; TCP + {stop.copies} datagrams")
        lines.append(f"{stop.id:>3} {1:>4}  {'stop_all/ack':<34} {'robot':<6} {'both':<4} "
                     f"{'urgent':<9} holds /{stop.robot}/rpc:i and every module")
    return "\n".join(lines)


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    options = parser.parse_args(argv)
    if options.gen_key:
        try:
            path = generate_key_file(options.gen_key)
        except (BridgeUsageError, OSError) as exc:
            print(f"walkman-bridge: {exc}", file=sys.stderr)
            return 1
        print(f"wrote a new bridge key to {path}; copy it (mode 600) to the other PC")
        return 0
    if options.check:
        try:
            print(describe(bridge_config.load(Path(options.check))))
        except ConfigError as exc:
            print(f"walkman-bridge: {exc}", file=sys.stderr)
            return 1
        return 0
    missing = [flag for flag, value in (("--side", options.side), ("--config", options.config),
                                        ("--peer", options.peer)) if not value]
    if missing:
        parser.error(f"missing {', '.join(missing)}")
    try:
        text = options.config.read_text()
        config = bridge_config.parse(text, str(options.config))
    except OSError as exc:
        print(f"walkman-bridge: {options.config}: cannot read: {exc.strerror}", file=sys.stderr)
        return 1
    except ConfigError as exc:
        print(f"walkman-bridge: {exc}", file=sys.stderr)
        return 1
    key_file = options.key or config.key_file
    if not key_file and not options.no_auth:
        parser.error("missing --key FILE (create one with --gen-key FILE and copy it to the "
                     "other PC; or key=\"FILE\" in the XML), or --no-auth to run "
                     "unauthenticated")
    try:
        key = LinkKey.none() if options.no_auth else LinkKey.from_file(key_file)
    except BridgeUsageError as exc:
        print(f"walkman-bridge: {exc}", file=sys.stderr)
        return 1
    # Only now: a refused start must leave the process's logging as it found it.
    configure_logging(f"bridge {options.side}", options.verbose)
    make_process_realtime(BRIDGE_PRIORITY)   # before the first thread (walkman.realtime)
    if not key.keyed:
        logging.getLogger("bridge").warning(
            "running WITHOUT authentication (--no-auth): anyone on the link can command "
            "the robot")
    from bridge.node import Bridge

    try:
        bridge = Bridge(config, text, side=options.side, peer=options.peer,
                        tcp_port=options.port, udp_port=options.udp_port,
                        peer_udp_port=options.peer_udp_port, listen=options.listen,
                        state_dir=options.state_dir or default_state_dir(options.side),
                        udp_rate=options.udp_rate, link_rate=options.link_rate,
                        link_timeout=options.link_timeout,
                        queue_limit=options.queue_limit, fsync=options.fsync, key=key)
        bridge.start()
    except OSError as exc:
        print(f"walkman-bridge: cannot start: {exc}", file=sys.stderr)
        return 1
    stacks.on_signals()   # kill -USR1 <pid>: every thread's stack to stderr (-USR2: wedged)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    logging.getLogger("bridge").info("%s side running (peer %s, tcp %d, udp %d)",
                                     options.side, options.peer, options.port,
                                     options.udp_port)
    done.wait()
    bridge.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
