"""``yarp-lite``: the ``yarp`` companion tool, for yarp_lite.

Same verbs, arguments and output as YARP 3.5's ``yarp`` (``Companion.cpp``),
so scripts and habits carry over: ``yarp-lite server``, ``yarp-lite read /r``,
``yarp-lite write /w /r``, ``yarp-lite connect --persist /a /b``,
``yarp-lite name list``, ``yarp-lite admin rpc /port``...  Results go to
standard output; port activity and errors to standard error as
``[INFO] ...`` lines.  Exit status 0 on success, 1 on failure, 2 on a usage
error.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence

from yarp_lite import __version__, nameconfig, network
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import format_bottle, parse
from yarp_lite.carriers import BottlePayload
from yarp_lite.connection import OutgoingConnection
from yarp_lite.contact import Contact
from yarp_lite.errors import AuthenticationError, LocalProtocolError, NetworkError, YarpError
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("yarp_lite.cli")

COMMANDS: Dict[str, "Command"] = {}


class UsageError(Exception):
    """Wrong arguments: the message says what is wrong and the right form."""


class Command:
    def __init__(self, name: str, summary: str, usage: str,
                 run: Callable[[List[str], bool], int]) -> None:
        self.name, self.summary, self.usage, self.run = name, summary, usage, run


def command(name: str, summary: str, usage: str):
    def register(function: Callable[[List[str], bool], int]):
        COMMANDS[name] = Command(name, summary, usage, function)
        return function
    return register


def out(text: str = "") -> None:
    """Print one line in one write.

    ``print`` writes the text and its newline separately; with an unbuffered stdout
    (``PYTHONUNBUFFERED``, as under a supervisor) a log line from another thread, sent to
    stderr on the same pipe, could land between them ("30.0[INFO] ..."), breaking the line
    a user or script reads.
    """
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _stdin_lines():
    for line in sys.stdin:
        yield line.rstrip("\n").rstrip("\r")


# --------------------------------------------------------------------------
# Name server and configuration


@command("server", "run a name server (drop-in for yarpserver)",
         "yarp-lite server [--ip IP] [--socket N] [--write] [--read] [--portdb FILE] "
         "[--subdb FILE] [--namespace NAME] [--silent]")
def cmd_server(args: List[str], admin: bool) -> int:
    from yarp_lite.nameserver.server import NameServer, ServerOptions

    options = ServerOptions()
    flags = {"--write": "write", "--read": "read", "--silent": "silent"}
    values = {"--ip": ("ip", str), "--socket": ("socket", int), "--portdb": ("portdb", str),
              "--subdb": ("subdb", str), "--namespace": ("namespace", str)}
    index = 0
    while index < len(args):
        arg = args[index]
        if arg in flags:
            setattr(options, flags[arg], True)
        elif arg in values:
            if index + 1 >= len(args):
                raise UsageError(f"{arg} needs a value")
            field, kind = values[arg]
            try:
                setattr(options, field, kind(args[index + 1]))
            except ValueError:
                raise UsageError(f"{arg} expects a number, got {args[index + 1]!r}") from None
            index += 1
        elif arg.isdigit() and not options.socket:
            options.socket = int(arg)  # "yarp server 10000"
        else:
            raise UsageError(f"unknown option {arg!r}")
        index += 1
    if options.socket and not 0 < options.socket < 65536:
        raise UsageError(f"--socket must be a TCP port number, got {options.socket}")
    server = NameServer(options)
    try:
        server.start()
    except LocalProtocolError as exc:
        log.error("%s", exc)
        return 1
    except OSError as exc:
        log.error("cannot listen on %s:%s: %s", server.address.host if server.address else "?",
                  server.address.port if server.address else "?", exc.strerror or exc)
        return 1
    server.serve_forever()
    return 0


@command("where", "report where the name server is running", "yarp-lite where")
def cmd_where(args: List[str], admin: bool) -> int:
    space = nameconfig.namespace()
    address = nameconfig.read_server_address(space)
    if address is not None:
        out(f"Looking for name server on {address.host}, port number {address.port}")
        out("If there is a long delay, try:")
        out("  yarp-lite conf --clean")
    if address is not None and NameClient().ping():
        out(f"Name server {space} is available at ip {address.host} port {address.port}")
        return 0
    out("== No valid YARP name server is available.")
    if address is not None:
        out("== Here is the expected configuration:")
        out(f"==   host: {address.host} port number: {address.port}")
        out(f"==   namespace: {space}")
    else:
        out(f"== No configuration file {nameconfig.config_file(space)}")
    out("== Start one with:  yarp-lite server")
    return 1


@command("conf", "report or set the location of the name server",
         "yarp-lite conf [HOST PORT [yarp] | --clean]")
def cmd_conf(args: List[str], admin: bool) -> int:
    path = nameconfig.config_file()
    if not args:
        out(str(path))
        return 0
    if args == ["--clean"]:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
        out("Cleared configuration file:")
        out(f"  {path}")
        return 0
    if len(args) in (2, 3) and args[1].isdigit():
        previous = nameconfig.read_server_address()
        current = nameconfig.ServerAddress(args[0], int(args[1]),
                                           args[2] if len(args) == 3 else "yarp")
        nameconfig.write_server_address(current)
        out("Configuration file:")
        out(f"  {path}")
        if previous is not None:
            out("Stored:")
            out(f"  host {previous.host} port number {previous.port} ({previous.mode} name server)")
        out("Now stores:")
        out(f"  host {current.host} port number {current.port} ({current.mode} name server)")
        return 0
    raise UsageError("expected 'yarp-lite conf', 'yarp-lite conf HOST PORT' or "
                     "'yarp-lite conf --clean'")


@command("namespace", "set or query the name of the name server (default /root)",
         "yarp-lite namespace [NAME]")
def cmd_namespace(args: List[str], admin: bool) -> int:
    if args:
        if not args[0].startswith("/"):
            raise UsageError(f"a namespace is a port name starting with '/', got {args[0]!r}")
        path = nameconfig.set_namespace(" ".join(args))
        out(f"Setting namespace in: {path}")
        out("Remove this file to revert to the default namespace (/root)")
    out(f"YARP namespace: {nameconfig.namespace()}")
    return 0


@command("name", "send commands to the name server",
         "yarp-lite name (list | query PORT | register PORT [CARRIER HOST NUMBER] | "
         "unregister PORT | set PORT KEY VALUE... | get PORT KEY | check PORT KEY VALUE | "
         "route A B | help | bot ...)")
def cmd_name(args: List[str], admin: bool) -> int:
    if not args:
        raise UsageError("say what to ask the name server, e.g. 'yarp-lite name list'")
    client = NameClient()
    key = args[0]
    if key == "query":
        if len(args) != 2:
            raise UsageError("yarp-lite name query PORT")
        contact = client.query(args[1])
        if contact is None:
            log.error("%s not known.", args[1])
            return 1
        out(f"registration name {contact.name} ip {contact.host} port {contact.port} "
            f"type {contact.carrier}")
        return 0
    if key == "register":
        if len(args) < 2:
            raise UsageError("yarp-lite name register PORT [CARRIER [HOST [NUMBER]]]")
        carrier = args[2] if len(args) > 2 else "..."
        host = args[3] if len(args) > 3 else "..."
        number = int(args[4]) if len(args) > 4 and args[4].isdigit() else None
        contact = client.register(args[1], carrier, host, number)
        out(f"registration name {contact.name} ip {contact.host} port {contact.port} "
            f"type {contact.carrier}")
        return 0
    if key == "unregister":
        if len(args) != 2:
            raise UsageError("yarp-lite name unregister PORT")
        client.unregister(args[1])
        out("Unregistered name.")
        return 0
    if key == "bot":
        reply = client.bottle(parse(" ".join(args)))
        out(format_bottle(reply))
        return 0
    for line in client.text(" ".join(args)):
        out(line)
    return 0


@command("clean", "remove registrations of ports that no longer answer",
         "yarp-lite clean [--timeout SECONDS]")
def cmd_clean(args: List[str], admin: bool) -> int:
    timeout = 2.0
    if args:
        if len(args) != 2 or args[0] != "--timeout":
            raise UsageError("yarp-lite clean [--timeout SECONDS]")
        try:
            timeout = float(args[1])
        except ValueError:
            raise UsageError(f"--timeout expects seconds, got {args[1]!r}") from None
    client = NameClient()
    out("Requesting list of ports from name server... ")
    ports = client.list()
    out(f"got {len(ports)} port{'s' if len(ports) != 1 else ''}")
    for contact in ports:
        if contact.name in ("fallback", client.namespace) or contact.carrier == "mcast":
            out(f"Ignoring {contact.name}")
            continue
        out(f"Testing {contact.name} at {contact.uri()}")
        try:
            OutgoingConnection.open(contact, "admin", "text", timeout=timeout,
                                    retry_refused=0.0).abort()
        except AuthenticationError as exc:
            log.error("%s answers but refused our key, keeping it: %s", contact.name, exc)
        except YarpError:
            out(f"* No response, removing port {contact.name}")
            client.unregister(contact.name)
    return 0


# --------------------------------------------------------------------------
# Connections


def _print_outcome(outcome: network.Outcome) -> int:
    if outcome.message:
        (log.info if outcome.ok else log.error)("%s", outcome.message.rstrip("\r\n"))
    return 0 if outcome.ok else 1


@command("connect", "create a connection between two ports",
         "yarp-lite connect [--persist | --persist-from | --persist-to] SOURCE DEST [CARRIER]")
def cmd_connect(args: List[str], admin: bool) -> int:
    mode, persist = "", False
    if args and args[0] in ("--persist", "--persist-from", "--persist-to"):
        persist = True
        mode = {"--persist": "", "--persist-from": "from", "--persist-to": "to"}[args[0]]
        args = args[1:]
    if persist and len(args) < 2:
        reply = NameClient().subscriptions(args[0] if args else "")
        entries = [item for item in reply[1:] if isinstance(item, list)]
        for entry in entries:
            entry = Bottle(entry)
            line = f"Persistent connection {entry.find('src', '?')} -> {entry.find('dest', '?')}"
            if entry.find("mode"):
                line += f" [{entry.find('mode')}]"
            out(line)
        if not entries:
            out("No persistent connections.")
        return 0
    if len(args) not in (2, 3):
        raise UsageError("give a sender port and a receiver port (and optionally a carrier)")
    carrier = args[2] if len(args) == 3 else ""
    return _print_outcome(network.connect(args[0], args[1], carrier, persist=persist,
                                          mode=mode))


@command("disconnect", "remove a connection between two ports",
         "yarp-lite disconnect [--persist] SOURCE DEST")
def cmd_disconnect(args: List[str], admin: bool) -> int:
    persist = bool(args) and args[0] == "--persist"
    if persist:
        args = args[1:]
    if len(args) != 2:
        raise UsageError("must have two arguments, a sender port and receiver port")
    return _print_outcome(network.disconnect(args[0], args[1], persist=persist))


@command("exists", "check if a port or connection is alive",
         "yarp-lite exists PORT | yarp-lite exists SOURCE DEST")
def cmd_exists(args: List[str], admin: bool) -> int:
    if len(args) == 1:
        return 0 if network.exists(args[0]) else 1
    if len(args) == 2:
        if network.is_connected(args[0], args[1]):
            return 0
        log.info("No connection from %s to %s found", args[0], args[1])
        return 1
    raise UsageError("please specify a port name, or a source and destination")


@command("wait", "wait for a port (or a connection) to be alive",
         "yarp-lite wait PORT [DEST] [--timeout SECONDS]")
def cmd_wait(args: List[str], admin: bool) -> int:
    timeout: Optional[float] = None
    if "--timeout" in args:
        at = args.index("--timeout")
        try:
            timeout = float(args[at + 1])
        except (IndexError, ValueError):
            raise UsageError("--timeout expects seconds") from None
        args = args[:at] + args[at + 2:]
    if len(args) == 1:
        log.info("Waiting for %s...", args[0])
        return 0 if network.wait_for_port(args[0], timeout) else 1
    if len(args) == 2:
        log.info("Waiting for %s->%s...", args[0], args[1])
        return 0 if network.wait_for_connection(args[0], args[1], timeout) else 1
    raise UsageError("please specify a single port name, or a source and destination")


@command("ping", "get live information about a port", "yarp-lite ping PORT")
def cmd_ping(args: List[str], admin: bool) -> int:
    if len(args) != 1:
        raise UsageError("yarp-lite ping PORT")
    try:
        for line in network.describe(args[0]):
            out(format_bottle(parse(line)))
    except NetworkError as exc:
        log.error("%s", exc)
        return 1
    return 0


# --------------------------------------------------------------------------
# Data


class _BottlePrinter:
    """``BottleReader``: print what arrives; a ``(1 "<EOF>")`` message ends it."""

    def __init__(self, show_envelope: bool = False, trim: int = -1) -> None:
        self.done = threading.Event()
        self.show_envelope = show_envelope
        self.trim = trim
        self.port: Optional[Port] = None

    def __call__(self, bottle: Bottle) -> None:
        text = format_bottle(bottle)
        if len(bottle) == 2 and type(bottle[0]) is int and isinstance(bottle[1], str) \
                and not isinstance(bottle[1], Vocab):
            if bottle[0] == 1:
                self.done.set()
                return None
            text = str(bottle[1])
        if self.show_envelope and self.port is not None and self.port.envelope:
            out(self.port.envelope + " ")
        out(text[:self.trim] if self.trim > 0 else text)
        return None


@command("read", "read from the network and print to standard output",
         "yarp-lite read PORT [SOURCE] [envelope] [trim [N]]")
def cmd_read(args: List[str], admin: bool) -> int:
    if not args:
        raise UsageError("yarp-lite read PORT [SOURCE] [envelope] [trim [N]]")
    name, source, envelope, trim = args[0], None, False, -1
    rest = args[1:]
    while rest:
        word = rest.pop(0)
        if word == "envelope":
            envelope = True
        elif word == "trim":
            trim = int(rest.pop(0)) if rest and rest[0].isdigit() else 80
        else:
            source = word
    printer = _BottlePrinter(envelope, trim)
    port = Port(reader=printer)
    printer.port = port
    port.open(name)
    try:
        if source:
            _print_outcome(network.connect(source, port.name))
        printer.done.wait()
    except KeyboardInterrupt:
        pass  # Ctrl-C is how the user ends the read; finally closes the port
    finally:
        port.close()
    return 0


def _write_loop(port: Port, verbatim: bool, admin: bool) -> None:
    for line in _stdin_lines():
        if line and ord(line[0]) < 32 and line[0] not in "\t":
            break
        bottle = Bottle([0, line]) if verbatim else parse(line)
        if admin:
            for unit_route in port.output_routes():
                contact = NameClient().query(unit_route.target)
                if contact is not None:
                    out(format_bottle(network.request(contact, bottle, admin=True)))
        else:
            port.write(bottle)
    if verbatim:
        port.write(Bottle([1, "<EOF>"]))


@command("write", "write to the network from standard input",
         "yarp-lite write PORT [TARGET...] [verbatim]")
def cmd_write(args: List[str], admin: bool) -> int:
    if not args:
        raise UsageError("please supply the port name, and optionally some targets")
    verbatim = "verbatim" in args[1:]
    targets = [target for target in args[1:] if target != "verbatim"]
    port = Port()
    port.open(args[0])
    try:
        for target in targets:
            outcome = network.connect(port.name, target)
            if not outcome.ok:
                _print_outcome(outcome)
                return 1
        _write_loop(port, verbatim, admin)
    except KeyboardInterrupt:
        pass  # Ctrl-C is how the user ends the write; finally closes the port
    finally:
        port.close()
    return 0


@command("readwrite", "read from one port and write to another",
         "yarp-lite readwrite READ_PORT WRITE_PORT")
def cmd_readwrite(args: List[str], admin: bool) -> int:
    if len(args) != 2:
        raise UsageError("please supply the read and write port names")
    printer = _BottlePrinter()
    reader = Port(reader=printer)
    reader.open(args[0])
    writer = Port()
    writer.open(args[1])
    try:
        _write_loop(writer, True, admin)
    except KeyboardInterrupt:
        pass  # Ctrl-C is how the user ends it; finally closes both ports
    finally:
        writer.close()
        reader.close()
    return 0


def _print_response(reply: Bottle) -> None:
    if reply and isinstance(reply[0], Vocab) and str(reply[0]) == "many":
        out("Responses:")
        items = reply[1:]
        if len(reply) == 2 and isinstance(reply[1], list):
            items = reply[1]
        for item in items:
            out(f"  {item}" if isinstance(item, str) and not isinstance(item, Vocab)
                else f"  {format_bottle([item])}")
    else:
        out(f"Response: {format_bottle(reply)}")


@command("rpc", "write commands to a port, and read replies",
         "yarp-lite [admin] rpc TARGET [LOCAL_NAME]")
def cmd_rpc(args: List[str], admin: bool) -> int:
    if not args:
        raise UsageError("yarp-lite [admin] rpc TARGET")
    target = args[0]
    sender = args[1] if len(args) > 1 else "anon_rpc"
    client = NameClient()
    requested = Contact.parse(target)
    lines = _stdin_lines()
    pending: Optional[str] = None
    first = True
    while True:
        contact = requested if requested.host else client.query(requested.name)
        if contact is None:
            log.error("Cannot make connection: %s is not registered", requested.name)
            return 1
        try:
            connection = OutgoingConnection.open(
                contact, sender, requested.carrier or ("text_ack" if admin else "tcp"))
        except YarpError as exc:
            log.error("Cannot make connection: %s", exc)
            return 1
        if not first:
            log.info("Target disappeared, reconnecting...")
        first = False
        try:
            while True:
                line = pending if pending is not None else next(lines, None)
                pending = None
                if line is None:
                    connection.close()
                    return 0
                try:
                    reply = connection.send("a" if admin else "d",
                                            BottlePayload(parse(line)),
                                            want_reply=True)
                except NetworkError:
                    pending = line
                    break
                _print_response(reply if reply is not None else Bottle())
        except KeyboardInterrupt:
            connection.close()
            return 0


@command("rpcserver", "make a test RPC server to receive and reply to Bottles",
         "yarp-lite rpcserver [--single] [--stop] [--echo] PORT")
def cmd_rpcserver(args: List[str], admin: bool) -> int:
    echo = stop = False
    while args and args[0].startswith("--"):
        option = args.pop(0)
        if option == "--echo":
            echo = True
        elif option == "--stop":
            stop = True
        elif option == "--single":
            pass
        else:
            raise UsageError(f"option not recognized: {option}")
    if len(args) != 1:
        raise UsageError("yarp-lite rpcserver [--single] [--stop] [--echo] /port/name")
    lines = _stdin_lines()
    waiting = "Waiting for a message..."
    serial = threading.Lock()  # one message at a time, as YARP's read: replies pair up

    def answer(request: Bottle, then: str = waiting) -> Bottle:
        """Show the message and choose its reply: itself, or the next line of stdin."""
        with serial:
            shown = f"Message: {format_bottle(request)}\nReply: "
            if echo:  # one write per message, before the reply leaves
                out(shown + (f"\n{then}" if then else ""))
                return request
            out(shown)
            reply = parse(next(lines, None) or "")
            if then:
                out(then)
            return reply

    # With --stop we read and reply here, so the reply has left when we return; else each
    # message is answered on its connection's own thread (no hand-off to this one).
    port = Port(rpc=True, reader=None if stop else answer)
    port.open(args[0])
    try:
        out(waiting)
        if stop:
            request = port.read(will_reply=True)
            if request is not None:
                port.reply(answer(request, then=""))
            return 0
        while port.is_open:
            time.sleep(0.5)
        return 0
    except KeyboardInterrupt:
        return 0
    finally:
        port.close()


CLOCK_OPTIONS = {"name": str, "period": float, "rtf": float, "systemTime": None, "help": None}


def _clock_options(args: List[str]) -> Dict[str, object]:
    """``yarp clock``'s options (YARP's ``Property::fromCommand``: ``--key [value]``)."""
    options: Dict[str, object] = {}
    rest = list(args)
    while rest:
        word = rest.pop(0)
        key = word[2:] if word.startswith("--") else ""
        if key not in CLOCK_OPTIONS:
            raise UsageError(f"unknown option {word!r}: yarp-lite clock takes "
                             f"{' '.join('--' + k for k in CLOCK_OPTIONS)}")
        kind = CLOCK_OPTIONS[key]
        if kind is None:
            options[key] = True
            continue
        if not rest:
            raise UsageError(f"--{key} needs a value")
        text = rest.pop(0)
        try:
            options[key] = kind(text)
        except ValueError:
            raise UsageError(f"--{key} takes a number, not {text!r}") from None
    for key in ("period", "rtf"):
        value = options.get(key)
        if value is not None and not 0 < float(value) < float("inf"):
            raise UsageError(f"--{key} must be above 0, not {value}")
    return options


@command("clock", "publish a clock time on a YARP port (programs with YARP_CLOCK follow it)",
         "yarp-lite clock [--name PORT] [--period MS] [--rtf FACTOR] [--systemTime]")
def cmd_clock(args: List[str], admin: bool) -> int:
    from yarp_lite import clock_wire, time as yarp_time

    options = _clock_options(args)
    if options.get("help"):
        out("This command publishes a clock time through a YARP port")
        out("period:     update period [ms]. Default 30")
        out("name:       name of yarp port to be opened. Default: check YARP_CLOCK "
            "environment variable; if missing use '/clock'")
        out("rtf:        real time factor: elapsed time is multiplied by it. Default 1")
        out("systemTime: start the published time at the system time, else from 0")
        return 1      # as yarp clock --help
    name = str(options.get("name") or yarp_time.source_from_environment() or
               yarp_time.DEFAULT_SOURCE)
    period = float(options.get("period", 30.0)) / 1000.0
    rtf = float(options.get("rtf", 1.0))
    system = bool(options.get("systemTime"))
    log.info("Clock configuration is the following:")
    log.info("period %.3f msec", period * 1000)
    log.info("name   %s", name)
    log.info("rtf    %.3f", rtf)
    log.info("system %s", "true" if system else "false")
    wall = yarp_time.SystemClock()   # a clock source follows no network clock
    port = Port()
    port.open(name)
    start, offset = wall.now(), (time.time() if system else 0.0)
    pacer = yarp_time.Pacer(period, wall)
    log.info("yarp clock running happily...")
    try:
        while True:
            port.write(clock_wire.encode_tick((wall.now() - start) * rtf + offset))
            pacer.wait()
    except KeyboardInterrupt:
        pass  # Ctrl-C is how the user stops the clock; finally closes the port
    finally:
        port.close()
    return 0


@command("version", "get version information", "yarp-lite version")
def cmd_version(args: List[str], admin: bool) -> int:
    out(f"YARP version 3.5.0 (yarp_lite {__version__})")
    return 0


@command("help", "get this list", "yarp-lite help [COMMAND]")
def cmd_help(args: List[str], admin: bool) -> int:
    if args and args[0] in COMMANDS:
        out(f"Usage: {COMMANDS[args[0]].usage}")
        return 0
    out("Usage:")
    out("  yarp-lite [admin] <command> [arg1 [arg2 ...]]")
    out("")
    out("Here are commands you can use:")
    out("")
    for name in sorted(COMMANDS):
        out(f"{name:<16} {COMMANDS[name].summary}")
    return 0


def configure_logging(verbose: bool = False) -> None:
    level = logging.DEBUG if verbose or os.environ.get("YARP_LITE_DEBUG") else logging.INFO
    logging.basicConfig(level=level, format="[%(levelname)s] %(message)s", stream=sys.stderr)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """The ``yarp-lite`` tool; a reader that closes our output (``| head``) ends it quietly."""
    try:
        return _run(list(sys.argv[1:] if argv is None else argv))
    except BrokenPipeError:
        # As the real yarp, which SIGPIPE ends: no traceback.  stdout is dead, so point it
        # at /dev/null or the interpreter's own flush at exit fails again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE


def _run(args: List[str]) -> int:
    configure_logging("--verbose" in args)
    args = [arg for arg in args if arg != "--verbose"]
    admin = False
    if args and args[0] == "admin":
        admin, args = True, args[1:]
    if not args:
        return cmd_help([], admin)
    name, rest = args[0], args[1:]
    if name in ("--version", "-v"):
        name = "version"
    if name in ("--help", "-h"):       # as the real ``yarp --help``: the usage
        return cmd_help([], admin)
    chosen = COMMANDS.get(name)
    if chosen is None:
        log.error("unknown command %r; 'yarp-lite help' lists them", name)
        return 2
    try:
        return chosen.run(rest, admin)
    except UsageError as exc:
        log.error("%s", exc)
        log.error("usage: %s", chosen.usage)
        return 2
    except YarpError as exc:
        log.error("%s", exc)
        return 1


if __name__ == "__main__":
    sys.exit(main())
