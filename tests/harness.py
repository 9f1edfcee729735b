"""Test harness: real processes on free ports, isolated YARP configuration, cleanup.

Every integration test builds a :class:`YarpWorld`: a private
``YARP_CONFIG_HOME``/``YARP_DATA_HOME``, a name server (real ``yarpserver`` or
``yarp-lite server``) on a free socket, and helpers to start the companion
tools of either implementation.  A world may require port authentication
(``auth_key``: an ``auth.conf`` in its configuration folder);
:meth:`YarpWorld.variant_env` gives a process another key, or none, on the
same network.  Processes run in their own session and are
killed with their whole group when the test ends, pass or fail.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from nodekit.exits import describe_exit
from system.processes import Proc, wait_until  # noqa: F401 (re-exported)
from yarp_lite import auth, freeport, nameconfig, reference
from yarp_lite.errors import NetworkError
from yarp_lite.nameclient import NameClient

REPO = Path(__file__).resolve().parents[1]


def reference_yarp_prefix() -> Optional[Path]:
    return reference.prefix()


REFERENCE_MISSING = reference.MISSING
compile_cpp = reference.compile_cpp


def missing_reference() -> None:
    """Skip the calling test, or fail it when CI demands the reference build."""
    from requirements import demand

    demand("reference")


def pick(implementations: dict, name: str) -> "Implementation":
    """One implementation of an interop pairing; the reference one must be built."""
    impl = implementations[name]
    if impl is None:
        missing_reference()
    return impl


def pair_id(pair) -> str:
    """A readable test id for a pairing, e.g. ``yarp-yarp_lite``."""
    return "-".join(pair)


def free_port(span: int = 1) -> int:
    return freeport.free_port(span)



class ManualClock:
    """A clock the test moves (``clock.now += 1``): what is passed where code takes a clock
    (``time.monotonic``), so its delays and deadlines pass at once and exactly."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now

@dataclass
class Implementation:
    """One YARP implementation: how to run its server and its companion tool."""

    name: str
    server: List[str]
    tool: List[str]


def lite_implementation() -> Implementation:
    python = sys.executable
    return Implementation("yarp_lite", [python, "-m", "yarp_lite", "server"],
                          [python, "-m", "yarp_lite"])


def real_implementation() -> Optional[Implementation]:
    prefix = reference_yarp_prefix()
    if prefix is None:
        return None
    # stdbuf: YARP's tools print through stdio, fully buffered into a pipe.
    line_buffered = ["stdbuf", "-oL", "-eL"]
    return Implementation("yarp", [*line_buffered, str(prefix / "bin" / "yarpserver")],
                          [*line_buffered, str(prefix / "bin" / "yarp")])


def write_auth_conf(directory: Path, key: Optional[str]) -> Optional[Path]:
    """An ``auth.conf`` holding ``key`` in ``directory`` (none when ``key`` is None)."""
    if key is None:
        return None
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / auth.FILE_NAME
    path.write_text(f"[{auth.GROUP}]\nkey {key}\n")
    return path


@dataclass
class YarpWorld:
    """An isolated YARP network: config dirs, one name server, and child processes."""

    root: Path
    server_impl: Implementation
    socket_number: int = 0
    namespace: str = "/root"
    processes: List[Proc] = field(default_factory=list)
    server: Optional[Proc] = None
    #: Prefix for every command, e.g. ``ip netns exec wm_robot`` for an emulated host.
    wrap: Sequence[str] = ()
    #: Address the name server announces (another host's processes may use it).
    ip: str = "127.0.0.1"
    #: Key every process of this world authenticates with (None: no auth.conf).
    auth_key: Optional[str] = None

    def __post_init__(self) -> None:
        self.config = self.root / "config"
        self.data = self.root / "data"
        self.config.mkdir(parents=True, exist_ok=True)
        self.data.mkdir(parents=True, exist_ok=True)
        write_auth_conf(self.config, self.auth_key)
        if not self.socket_number:
            # the server hands out the numbers after its own: room for a robot's ports
            self.socket_number = free_port(span=400)

    @property
    def env(self) -> Dict[str, str]:
        env = dict(os.environ)
        env.update({"YARP_CONFIG_HOME": str(self.config), "YARP_DATA_HOME": str(self.data),
                    # a module's command journal and a bridge's, this world's own
                    "XDG_STATE_HOME": str(self.root / "state"), "PYTHONUNBUFFERED": "1"})
        env.pop("YARP_NAMESPACE", None)
        env.pop("YARP_PORT_PREFIX", None)
        if self.namespace != "/root":
            env["YARP_NAMESPACE"] = self.namespace
        return env

    def variant_env(self, name: str, auth_key: Optional[str]) -> Dict[str, str]:
        """The environment of a process on this network with another key (None: none).

        Its configuration folder links to this world's ``yarp.conf``, so it
        finds the same name server, and holds its own ``auth.conf``.
        """
        folder = self.root / f"variant-{name}"
        folder.mkdir(parents=True, exist_ok=True)
        link = folder / nameconfig.config_file(self.namespace, self.env).name
        if not link.is_symlink():
            link.symlink_to(nameconfig.config_file(self.namespace, self.env))
        (folder / auth.FILE_NAME).unlink(missing_ok=True)
        write_auth_conf(folder, auth_key)
        return {**self.env, "YARP_CONFIG_HOME": str(folder)}

    def apply_to_process(self, monkeypatch) -> None:
        """Point in-process yarp_lite code at this world (via monkeypatch)."""
        for key, value in self.env.items():
            if key.startswith("YARP") or key == "XDG_STATE_HOME":
                monkeypatch.setenv(key, value)
        if self.namespace == "/root":
            monkeypatch.delenv("YARP_NAMESPACE", raising=False)

    def start_server(self, extra: Sequence[str] = ()) -> Proc:
        argv = [*self.server_impl.server, "--socket", str(self.socket_number), "--ip",
                self.ip, "--write", *extra]
        self.server = self.start(argv, f"{self.server_impl.name} server")
        wait_until(self._server_answers, timeout=20, message=f"{self.server_impl.name} server")
        return self.server

    def _server_answers(self) -> bool:
        if self.server is not None and self.server.popen.poll() is not None:
            raise AssertionError("name server exited:\n" + self.server.output())
        if self.wrap:  # in another network namespace: trust what the server says
            return self.server is not None and "Ready" in self.server.output()
        conf = nameconfig.config_file(self.namespace, self.env)
        if not conf.is_file() or not conf.read_text().split():
            return False
        host = conf.read_text().split()[0]
        client = NameClient(self.namespace, nameconfig.ServerAddress(host, self.socket_number),
                            timeout=2.0, environ=self.env)
        try:  # through yarp_lite, so an authenticating server is asked with the world's key
            return client.query(self.namespace) is not None
        except NetworkError:
            return False

    def stop_server(self) -> None:
        if self.server is not None:
            self.server.kill(signal.SIGKILL)
            self.server = None

    def start(self, argv: Sequence[str], name: str = "", stdin: bool = False,
              env: Optional[Dict[str, str]] = None) -> Proc:
        proc = Proc([*self.wrap, *argv], env or self.env, name or " ".join(argv[:3]),
                    stdin=stdin)
        self.processes.append(proc)
        return proc

    def tool(self, impl: Implementation, *args: str, stdin: bool = False,
             env: Optional[Dict[str, str]] = None) -> Proc:
        return self.start([*impl.tool, *args], f"{impl.name} {' '.join(args)}", stdin=stdin,
                          env=env)

    def run_tool(self, impl: Implementation, *args: str, timeout: float = 60.0,
                 input_text: Optional[str] = None, env: Optional[Dict[str, str]] = None,
                 cwd: Optional[Path] = None) -> subprocess.CompletedProcess:
        return subprocess.run([*self.wrap, *impl.tool, *args], env=env or self.env,
                              capture_output=True, text=True, timeout=timeout, input=input_text,
                              cwd=str(cwd or REPO))

    def close(self) -> None:
        for proc in reversed(self.processes):
            proc.kill()
        self.processes.clear()
        freeport.release(self.socket_number)


def dump_outputs_if_failed(request, processes) -> None:
    """Show what the child processes printed when the test failed (their logs explain it).

    From a fixture's teardown the test's report says (``report_call``, set by
    ``pytest_runtest_makereport`` in conftest); from a ``finally`` inside the test (a context
    manager of its own), the failure is the exception on its way out -- the report does not
    exist yet.
    """
    report = getattr(request.node, "report_call", None)
    failing = sys.exc_info()[0]
    if not (report is not None and report.failed) and \
            (failing is None or issubclass(failing, GeneratorExit)):
        return
    kept = REPO / "out" / "failed" / _file_name(request.node.name, 120)
    kept.mkdir(parents=True, exist_ok=True)
    for number, proc in enumerate(processes):
        whole = proc.output()
        # How it ended matters as much as what it said: a program that vanished without a
        # word was killed (SIGKILL) or crashed (SIGSEGV without faulthandler).
        ended = describe_exit(proc.popen.poll())
        (kept / f"{number:02d}-{_file_name(proc.name, 60)}.log").write_text(
            f"{whole}\n----- {proc.name} (pid {proc.popen.pid}): {ended} -----\n")
        tail = "\n".join(whole.splitlines()[-40:])
        print(f"\n----- output of {proc.name}, pid {proc.popen.pid}, {ended} (last 40 lines; "
              f"all of it in {kept}) -----\n{tail}")


def _file_name(text: str, length: int) -> str:
    return re.sub(r"[^\w.-]+", "_", text)[:length]
