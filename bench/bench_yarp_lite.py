#!/usr/bin/env python3
"""yarp_lite against real YARP 3.5 (C++) and rospy, side by side, in one run.

Measures on loopback, each peer in its own process:

* RPC round trip of a 10-int Bottle (median, p99) -- yarp_lite<->yarp_lite,
  C++<->C++ (``cpp/yarp_bench.cpp`` linked to the reference build), rospy
  topic ping-pong over TCPROS, and the mixed yarp_lite<->C++ pairs;
* the server side alone: one real C++ client against ``yarp rpcserver --echo``
  and ``yarp-lite rpcserver --echo``, a C++ ``Port`` and a Python ``RpcServer``,
  interleaved round by round;
* one-way throughput of Bottles holding a 1 MB blob;
* name server cost: one ``query`` round trip, and 100 concurrent
  registrations, against ``yarp-lite server`` and ``yarpserver``.

Usage: ``.venv/bin/python bench/bench_yarp_lite.py [--quick | --smoke]``.  Needs the
reference build (``launch_scripts/build_reference_yarp.sh``) for the C++
columns and Debian's ROS for the rospy column; missing ones are reported,
not faked.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Dict, List, Optional

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from yarp_lite import reference  # noqa: E402
from yarp_lite.freeport import free_port  # noqa: E402
from host import say_machine  # noqa: E402  (bench/ is the script's folder)

PYTHON = sys.executable


# -- roles run in child processes ------------------------------------------------------


def role_lite_rpc_server(name: str) -> None:
    from yarp_lite.rpc import RpcServer

    RpcServer(name, handler=lambda bottle: bottle)
    print("ready", flush=True)
    time.sleep(3600)


def role_lite_rpc_client(target: str, count: int) -> None:
    from yarp_lite.bottle import Bottle
    from yarp_lite.rpc import RpcClient

    client = RpcClient("/bench/lite/client", target)
    request = Bottle(list(range(10)))
    for _ in range(200):
        client.call(request)
    samples = []
    for _ in range(count):
        started = time.perf_counter()
        client.call(request)
        samples.append((time.perf_counter() - started) * 1e6)
    print(json.dumps(_stats(samples)), flush=True)
    client.close()


class _RateMeter:
    """Counts messages of a stream; the first one only starts the clock."""

    def __init__(self, count: int) -> None:
        self.count, self.seen, self.bytes = count, 0, 0
        self.first = self.last = 0.0
        self.done = threading.Event()

    def on_message(self, size: int) -> None:
        now = time.perf_counter()
        if self.seen == 0:
            self.first = now
        else:
            self.bytes += size
        self.last = now
        self.seen += 1
        if self.seen >= self.count:
            self.done.set()

    def report(self) -> None:
        self.done.wait(120)
        print(json.dumps({"mb_per_s": self.bytes / (self.last - self.first) / 1e6}), flush=True)


def role_lite_sink(name: str, count: int) -> None:
    from yarp_lite.port import Port

    meter = _RateMeter(count)
    port = Port(name, reader=lambda bottle: meter.on_message(len(bottle[0])))
    print("ready", flush=True)
    meter.report()
    port.close()


def role_lite_source(name: str, target: str, count: int, size: int) -> None:
    from yarp_lite import network
    from yarp_lite.bottle import Bottle
    from yarp_lite.port import Port

    port = Port(name)
    assert network.connect(name, target).ok
    message = Bottle([b"\x5a" * size])
    from yarp_lite.carriers import BottlePayload
    for _ in range(count):
        port.write(BottlePayload(message))
    time.sleep(0.5)
    port.close()


def role_ros_ponger() -> None:
    import rospy
    from std_msgs.msg import Int32MultiArray

    rospy.init_node("ponger", disable_signals=True)
    publisher = rospy.Publisher("/pong", Int32MultiArray, queue_size=None, tcp_nodelay=True)
    rospy.Subscriber("/ping", Int32MultiArray, publisher.publish, tcp_nodelay=True)
    print("ready", flush=True)
    rospy.spin()


def role_ros_pinger(count: int) -> None:
    import rospy
    from std_msgs.msg import Int32MultiArray

    rospy.init_node("pinger", disable_signals=True)
    arrived = threading.Event()
    rospy.Subscriber("/pong", Int32MultiArray, lambda _: arrived.set(), tcp_nodelay=True)
    publisher = rospy.Publisher("/ping", Int32MultiArray, queue_size=None, tcp_nodelay=True)
    message = Int32MultiArray(data=list(range(10)))
    deadline = time.time() + 20
    while time.time() < deadline:  # wait until the loop is connected both ways
        arrived.clear()
        publisher.publish(message)
        if arrived.wait(0.2):
            break
    samples = []
    for index in range(count + 200):
        arrived.clear()
        started = time.perf_counter()
        publisher.publish(message)
        arrived.wait(5)
        if index >= 200:
            samples.append((time.perf_counter() - started) * 1e6)
    print(json.dumps(_stats(samples)), flush=True)
    rospy.signal_shutdown("done")


def role_ros_sink(count: int) -> None:
    import rospy
    from std_msgs.msg import UInt8MultiArray

    rospy.init_node("sink", disable_signals=True)
    meter = _RateMeter(count)
    rospy.Subscriber("/blob", UInt8MultiArray, lambda message: meter.on_message(len(message.data)),
                     tcp_nodelay=True)
    print("ready", flush=True)
    meter.report()


def role_ros_source(count: int, size: int) -> None:
    import rospy
    from std_msgs.msg import UInt8MultiArray

    rospy.init_node("source", disable_signals=True)
    publisher = rospy.Publisher("/blob", UInt8MultiArray, queue_size=None, tcp_nodelay=True)
    while publisher.get_num_connections() == 0:
        time.sleep(0.05)
    message = UInt8MultiArray(data=b"\x5a" * size)
    for _ in range(count):
        publisher.publish(message)
    time.sleep(1)


ROLES = {"lite-rpc-server": role_lite_rpc_server, "lite-rpc-client": role_lite_rpc_client,
         "lite-sink": role_lite_sink, "lite-source": role_lite_source,
         "ros-ponger": role_ros_ponger, "ros-pinger": role_ros_pinger,
         "ros-sink": role_ros_sink, "ros-source": role_ros_source}


def _stats(samples: List[float]) -> Dict[str, float]:
    ordered = sorted(samples)
    return {"median_us": statistics.median(ordered), "p99_us": ordered[int(len(ordered) * 0.99)]}


# -- orchestration ----------------------------------------------------------------------


class Bench:
    #: Samples per figure: the full run, ``--quick``'s, ``--smoke``'s (every table once,
    #: too few samples to read: the test suite's check that the script runs whole).
    SAMPLES = {"full": {"rpc": 10000, "blobs": 400, "rounds": (15, 3000), "queries": 1000},
               "quick": {"rpc": 2000, "blobs": 100, "rounds": (5, 1000), "queries": 300},
               "smoke": {"rpc": 200, "blobs": 20, "rounds": (1, 200), "queries": 50}}

    def __init__(self, mode: str = "full") -> None:
        self.samples = self.SAMPLES[mode]
        self.rpc_count = self.samples["rpc"]
        self.blob_count = self.samples["blobs"]
        self.tmp = Path(tempfile.mkdtemp(prefix="yarp-lite-bench-"))
        self.env = dict(os.environ, YARP_CONFIG_HOME=str(self.tmp / "config"),
                        YARP_DATA_HOME=str(self.tmp / "data"), PYTHONUNBUFFERED="1")
        self.children: List[subprocess.Popen] = []
        self.prefix = reference.prefix()
        self.cpp = reference.compile_cpp(HERE / "cpp" / "yarp_bench.cpp", "yarp_bench") \
            if self.prefix else None

    def spawn(self, argv: List, env: Optional[dict] = None, wait_ready: bool = True):
        argv = [str(arg) for arg in argv]
        # A child nobody reads (no "ready" to wait for) must not write into a pipe: yarpserver
        # logs every request and blocked once the pipe was full (10 000 ports, bench_scale).
        child = subprocess.Popen(argv, env=env or self.env,
                                 stdout=subprocess.PIPE if wait_ready else subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL, text=True)
        self.children.append(child)
        if wait_ready:
            seen = []
            while True:
                line = child.stdout.readline()
                seen.append(line)
                if line.strip() == "ready":
                    break
                if not line:
                    raise RuntimeError(f"{argv} did not start: {''.join(seen)!r}")
        return child

    def run(self, argv: List, env: Optional[dict] = None, timeout: float = 300) -> str:
        return subprocess.run([str(arg) for arg in argv], env=env or self.env, capture_output=True, text=True,
                              timeout=timeout).stdout

    def role(self, name: str, *args) -> List[str]:
        return [PYTHON, str(Path(__file__)), "--role", name, *map(str, args)]

    def close(self) -> None:
        for child in self.children:
            child.kill()
            child.wait()

    def start_name_server(self, real: bool, socket_number: int) -> subprocess.Popen:
        if real:
            argv = [str(self.prefix / "bin" / "yarpserver"), "--socket", str(socket_number),
                    "--write"]
        else:
            argv = [PYTHON, "-m", "yarp_lite", "server", "--socket", str(socket_number),
                    "--ip", "127.0.0.1", "--write", "--silent"]
        child = self.spawn(argv, wait_ready=False)
        from yarp_lite.nameclient import NameClient
        from yarp_lite.nameconfig import read_server_address

        deadline = time.time() + 20
        while time.time() < deadline:
            address = read_server_address("/root", self.env)
            if address and address.port == socket_number and \
                    NameClient(address=address, environ=self.env).ping():
                return child
            time.sleep(0.1)
        raise RuntimeError("name server did not start")

    # -- measurements ---------------------------------------------------------------------

    def rpc_lite_lite(self, spin: bool = True) -> dict:
        env = dict(self.env, YARP_LITE_SPIN_US="150" if spin else "0")
        name = "/bench/lite/echo" + ("" if spin else "0")
        self.spawn(self.role("lite-rpc-server", name), env=env)
        return json.loads(self.run(self.role("lite-rpc-client", name, self.rpc_count), env=env))

    def rpc_cpp_cpp(self) -> dict:
        self.spawn([str(self.cpp), "rpc-server", "/bench/cpp/echo"])
        words = _line_starting(self.run([str(self.cpp), "rpc-client", "/bench/cpp/echo",
                                         self.rpc_count]), "rpc").split()
        return {"median_us": float(words[1]), "p99_us": float(words[2])}

    def rpc_lite_to_cpp(self) -> dict:
        self.spawn([str(self.cpp), "rpc-server", "/bench/cpp/echo2"])
        return json.loads(self.run(self.role("lite-rpc-client", "/bench/cpp/echo2",
                                             self.rpc_count)))

    def rpc_cpp_to_lite(self) -> dict:
        self.spawn(self.role("lite-rpc-server", "/bench/lite/echo2"))
        words = _line_starting(self.run([str(self.cpp), "rpc-client", "/bench/lite/echo2",
                                         self.rpc_count]), "rpc").split()
        return {"median_us": float(words[1]), "p99_us": float(words[2])}

    def server_side(self) -> Dict[str, List[float]]:
        """One real C++ client against four echo servers, in turn, round after round.

        The pairs compared: the ``rpcserver --echo`` tools (real ``yarp`` and
        ``yarp-lite``), and the library servers (a C++ ``Port`` replying from its
        reader, and a Python :class:`~yarp_lite.rpc.RpcServer`).  Each round runs
        every server once, in a rotated order, so load drifts hit all alike.
        """
        from yarp_lite.nameclient import NameClient
        from yarp_lite.nameconfig import read_server_address

        servers = {
            "yarp rpcserver": [str(self.prefix / "bin" / "yarp"), "rpcserver", "--echo",
                               "/bench/s/real_tool"],
            "yarp-lite rpcserver": [PYTHON, "-m", "yarp_lite", "rpcserver", "--echo",
                                    "/bench/s/lite_tool"],
            "C++ Port": [str(self.cpp), "rpc-server", "/bench/s/cpp"],
            "yarp_lite RpcServer": self.role("lite-rpc-server", "/bench/s/lite"),
        }
        names = {label: argv[-1] for label, argv in servers.items()}
        client = NameClient(address=read_server_address("/root", self.env), environ=self.env)
        for label, argv in servers.items():
            self.spawn(argv, wait_ready=False)
        deadline = time.time() + 30
        while not all(client.query(name) for name in names.values()):
            if time.time() > deadline:
                raise RuntimeError("echo servers did not register")
            time.sleep(0.2)
        rounds, count = self.samples["rounds"]
        medians: Dict[str, List[float]] = {label: [] for label in servers}
        labels = list(servers)
        for turn in range(rounds):
            for label in labels[turn % 4:] + labels[:turn % 4]:
                words = _line_starting(self.run([str(self.cpp), "rpc-client", names[label],
                                                 count]), "rpc").split()
                medians[label].append(float(words[1]))
        return medians

    def throughput_lite(self) -> float:
        sink = self.spawn(self.role("lite-sink", "/bench/lite/sink", self.blob_count))
        self.run(self.role("lite-source", "/bench/lite/source", "/bench/lite/sink",
                           self.blob_count, 1 << 20))
        return json.loads(sink.stdout.readline())["mb_per_s"]

    def throughput_cpp(self) -> float:
        sink = self.spawn([str(self.cpp), "sink", "/bench/cpp/sink", self.blob_count])
        self.run([str(self.cpp), "source", "/bench/cpp/source", "/bench/cpp/sink",
                  self.blob_count, 1 << 20])
        return float(_last_line_starting(sink, "sink").split()[1])


    def with_roscore(self, measure):
        import shutil

        if shutil.which("roscore") is None:
            return None
        port = free_port()
        env = dict(self.env, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOME=str(self.tmp / "ros"),
                   ROS_LOG_DIR=str(self.tmp / "ros" / "log"), ROS_HOSTNAME="127.0.0.1")
        core = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            deadline = time.time() + 30
            while time.time() < deadline:
                if subprocess.run(["rostopic", "list"], env=env, capture_output=True).returncode == 0:
                    break
                time.sleep(0.3)
            return measure(env)
        finally:
            import signal as signals
            os.killpg(core.pid, signals.SIGINT)
            try:
                core.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(core.pid, signals.SIGKILL)

    def rpc_rospy(self) -> Optional[dict]:
        def measure(env):
            self.spawn(self.role("ros-ponger"), env=env)
            return json.loads(self.run(self.role("ros-pinger", self.rpc_count), env=env))
        return self.with_roscore(measure)

    def throughput_rospy(self) -> Optional[float]:
        def measure(env):
            sink = self.spawn(self.role("ros-sink", self.blob_count), env=env)
            self.run(self.role("ros-source", self.blob_count, 1 << 20), env=env)
            return json.loads(sink.stdout.readline())["mb_per_s"]
        return self.with_roscore(measure)

    def name_server_costs(self, real: bool) -> dict:
        from yarp_lite.nameclient import NameClient
        from yarp_lite.nameconfig import read_server_address

        address = read_server_address("/root", self.env)
        client = NameClient(address=address, environ=self.env)
        client.register("/bench/query/target")
        samples = []
        for _ in range(self.samples["queries"]):
            started = time.perf_counter()
            client.query("/bench/query/target")
            samples.append((time.perf_counter() - started) * 1e6)
        errors: List[Exception] = []

        def register(index: int) -> None:
            try:
                NameClient(address=address, environ=self.env).register(f"/bench/many/{index}")
            except Exception as exc:  # noqa: BLE001 - reported below
                errors.append(exc)
        threads = [threading.Thread(target=register, args=(i,)) for i in range(100)]
        started = time.perf_counter()
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        wall = time.perf_counter() - started
        return {"query_median_us": statistics.median(samples),
                "register_100_s": wall, "register_errors": len(errors)}


def _line_starting(text: str, word: str) -> str:
    return next(line for line in text.splitlines() if line.startswith(word + " "))


def _last_line_starting(child: subprocess.Popen, word: str) -> str:
    for line in child.stdout:
        if line.startswith(word + " "):
            return line
    raise RuntimeError(f"no '{word}' line from {child.args}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sizes = parser.add_mutually_exclusive_group()
    sizes.add_argument("--quick", action="store_const", const="quick", dest="mode",
                       default="full", help="fewer samples (a first look)")
    sizes.add_argument("--smoke", action="store_const", const="smoke", dest="mode",
                       help="every table once, too few samples to read (the test suite's run)")
    parser.add_argument("--role", nargs="+", help=argparse.SUPPRESS)
    parser.add_argument("--json", help="also write the figures to this file")
    options = parser.parse_args()
    if options.role:  # a child: its stdout is its figures, nothing else
        name, *args = options.role
        ROLES[name](*[int(a) if a.lstrip("-").isdigit() else a for a in args])
        return 0
    say_machine()

    bench = Bench(options.mode)
    results: Dict[str, object] = {}
    try:
        print("yarp_lite benchmark (loopback, one process per peer)", flush=True)
        bench.start_name_server(real=False, socket_number=free_port())
        print("  RPC round trips ...", flush=True)
        results["rpc_lite"] = bench.rpc_lite_lite(spin=True)
        results["rpc_lite_nospin"] = bench.rpc_lite_lite(spin=False)
        if bench.cpp:
            results["rpc_cpp"] = bench.rpc_cpp_cpp()
            results["rpc_lite_to_cpp"] = bench.rpc_lite_to_cpp()
            results["rpc_cpp_to_lite"] = bench.rpc_cpp_to_lite()
            print("  server side, one C++ client, interleaved ...", flush=True)
            results["server_side"] = bench.server_side()
        results["rpc_rospy"] = bench.rpc_rospy()
        print("  1 MB throughput ...", flush=True)
        results["mb_lite"] = bench.throughput_lite()
        if bench.cpp:
            results["mb_cpp"] = bench.throughput_cpp()
        results["mb_rospy"] = bench.throughput_rospy()
        print("  name server ...", flush=True)
        results["ns_lite"] = bench.name_server_costs(real=False)
        if bench.prefix:
            bench.close()
            bench.children = []
            bench.start_name_server(real=True, socket_number=free_port())
            results["ns_real"] = bench.name_server_costs(real=True)
    finally:
        bench.close()
    report(results)
    if options.json:
        Path(options.json).write_text(json.dumps(results, indent=2))
    return 0


def report(results: Dict[str, object]) -> None:
    def rpc(key: str) -> str:
        value = results.get(key)
        return f"{value['median_us']:8.1f} {value['p99_us']:8.1f}" if value else "   (n/a)         "

    def mb(key: str) -> str:
        value = results.get(key)
        return f"{value:10.0f}" if value else "     (n/a)"
    print()
    print("RPC round trip, 10-int Bottle (microseconds)   median      p99")
    print(f"  yarp_lite  <-> yarp_lite                      {rpc('rpc_lite')}")
    print(f"  yarp_lite  <-> yarp_lite (busy-poll off)      {rpc('rpc_lite_nospin')}")
    print(f"  YARP C++   <-> YARP C++  (reference)          {rpc('rpc_cpp')}")
    print(f"  yarp_lite client -> YARP C++ server           {rpc('rpc_lite_to_cpp')}")
    print(f"  YARP C++ client -> yarp_lite server           {rpc('rpc_cpp_to_lite')}")
    print(f"  rospy TCPROS topic ping-pong                  {rpc('rpc_rospy')}")
    if results.get("rpc_lite") and results.get("rpc_cpp"):
        ratio = results["rpc_lite"]["median_us"] / results["rpc_cpp"]["median_us"]
        print(f"  ratio yarp_lite / C++ (median)                {ratio:8.2f}   (goal <= 1.0)")
    sides = results.get("server_side")
    if sides:
        rounds = len(next(iter(sides.values())))
        print()
        print(f"Server side: a C++ RpcClient against each echo server, {rounds} interleaved rounds")
        print("  (microseconds: median of the rounds' medians, and the rounds' range)")
        middle = {label: statistics.median(values) for label, values in sides.items()}
        for label, values in sides.items():
            print(f"  {label:<28} {middle[label]:8.1f}   {min(values):7.1f} .. {max(values):7.1f}")
        print(f"  ratio yarp-lite rpcserver / yarp rpcserver    "
              f"{middle['yarp-lite rpcserver'] / middle['yarp rpcserver']:6.2f}   (goal <= 1.0)")
        print(f"  ratio RpcServer / C++ Port                    "
              f"{middle['yarp_lite RpcServer'] / middle['C++ Port']:6.2f}   (goal <= 1.0)")
    print()
    print("One-way throughput, Bottles with a 1 MB blob (MB/s)")
    print(f"  yarp_lite  -> yarp_lite                     {mb('mb_lite')}")
    print(f"  YARP C++   -> YARP C++  (reference)         {mb('mb_cpp')}")
    print(f"  rospy TCPROS                                {mb('mb_rospy')}")
    if results.get("mb_lite") and results.get("mb_cpp"):
        print(f"  ratio yarp_lite / C++                       "
              f"{results['mb_lite'] / results['mb_cpp']:10.2f}   (goal >= 0.5)")
    print()
    print("Name server                          yarp-lite server     yarpserver")
    lite, real = results.get("ns_lite") or {}, results.get("ns_real") or {}
    print(f"  query round trip (median, us)      {lite.get('query_median_us', 0):16.1f} "
          f"{real.get('query_median_us', float('nan')):14.1f}")
    print(f"  100 concurrent registrations (s)   {lite.get('register_100_s', 0):16.3f} "
          f"{real.get('register_100_s', float('nan')):14.3f}")
    print(f"  failed registrations               {lite.get('register_errors', 0):16d} "
          f"{real.get('register_errors', 0):14d}")


if __name__ == "__main__":
    sys.exit(main())
