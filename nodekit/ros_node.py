"""rospy's one node per process, started when the master answers and kept registered.

Theory of operation
-------------------
:class:`RosNode` waits for the local master (so a node may start before
roscore), and every second checks that the master still knows our topics -- a
restarted roscore forgets every node, and rospy never registers again by
itself -- registering them again when it does not.  Actions queued with
:meth:`RosNode.when_ready` run once the node is registered (topics, services).
A roscpp node living in the same process (librviz's, in the Pilot Interface)
never registers again either: :meth:`RosNode.adopt` makes it ours to register,
through its own XML-RPC slave API (its subscriptions, their publishers pushed
to it with ``publisherUpdate``, its publications).

rospy reads the handshake of every inbound connection in its accept thread,
with no deadline and no size limit: one silent client stalls every topic and
service of the node, and a header that declares 2 GB is buffered until it
arrives.  :func:`guard_tcpros` (installed by :class:`RosNode`) gives each
handshake a thread of its own, a deadline and a size limit, so our nodes keep
serving under hostile peers.  At most :data:`MAX_HANDSHAKES` are read at once;
when a new connection finds them all taken, the one that has waited longest is
cut, not the newcomer: a flood of silent connections then cannot lock a real
client out (it says its header at once, so it is never the oldest for long).

rospy connects a subscription to a publisher in a thread per publisher update, and
two updates close together (the master's ``publisherUpdate`` beside the subscriber's
own registration) connect it twice at once: each finds no connection yet, the second
added closes the first, and when the publisher's side kept the other of the two, both
ends are closed and rospy never connects again (a 3-D view that ignored every drag).
:func:`one_connection_per_publisher` makes the connects to one publisher of one topic
take turns, so the second finds the first and leaves it alone.
"""

from __future__ import annotations

import logging
import os
import threading
from typing import Any, Callable, Dict, List, Optional, Set

log = logging.getLogger("nodekit.ros")

HANDSHAKE_TIMEOUT = 5.0
MAX_HANDSHAKE_BYTES = 1 << 20
#: Inbound handshakes read at once; a further connection cuts the one waiting longest.
MAX_HANDSHAKES = 64


class _HandshakeBudget:
    """A socket seen by rospy's header reader: its ``recv`` stops at the byte limit."""

    def __init__(self, sock: Any) -> None:
        self._sock = sock
        self.received = 0

    def recv(self, size: int) -> bytes:
        from rosgraph.network import ROSHandshakeException

        data = self._sock.recv(size)
        self.received += len(data)
        if self.received > MAX_HANDSHAKE_BYTES:
            raise ROSHandshakeException(f"handshake header over {MAX_HANDSHAKE_BYTES} bytes: "
                                        f"refused")
        return data


def guard_tcpros() -> None:
    """Bound rospy's inbound TCPROS handshakes in time, size and threads (idempotent)."""
    from rosgraph import network
    from rospy.impl import tcpros_base

    if getattr(tcpros_base, "_walkman_guarded", False):
        return
    import socket
    from collections import OrderedDict

    read_header = network.read_ros_handshake_header
    serve = tcpros_base.TCPROSServer._tcp_server_callback
    waiting: "OrderedDict[Any, Any]" = OrderedDict()   # socket -> its peer, oldest first
    lock = threading.Lock()

    def bounded_read(sock: Any, buffer: Any, buff_size: int) -> Dict[str, str]:
        previous = sock.gettimeout()
        sock.settimeout(HANDSHAKE_TIMEOUT if previous is None
                        else min(previous, HANDSHAKE_TIMEOUT))
        try:
            return read_header(_HandshakeBudget(sock), buffer, buff_size)
        finally:
            try:
                sock.settimeout(previous)
            except OSError:   # closed meanwhile (rospy dropping a duplicate): the read's
                pass          # own error is the one to report
            with lock:
                waiting.pop(sock, None)   # read (or failed): no longer one to cut

    def threaded(server: Any, sock: Any, address: Any) -> None:
        with lock:
            cut = waiting.popitem(last=False) if len(waiting) >= MAX_HANDSHAKES else None
            waiting[sock] = address
        if cut is not None:
            log.warning("TCPROS: %d handshakes already waiting; cut the oldest, from %s:%s",
                        MAX_HANDSHAKES, *cut[1][:2])
            try:
                cut[0].shutdown(socket.SHUT_RDWR)   # its reader sees the end and gives up
            except OSError:
                pass  # already closed by its reader: nothing left to cut

        # rospy logs and closes on any failure; bounded_read takes the socket off the list.
        threading.Thread(target=serve, args=(server, sock, address), name="tcpros handshake",
                         daemon=True).start()

    tcpros_base.read_ros_handshake_header = bounded_read
    tcpros_base.TCPROSServer._tcp_server_callback = threaded
    tcpros_base._walkman_guarded = True


def one_connection_per_publisher() -> None:
    """Serialise rospy's connects of one topic to one publisher (idempotent)."""
    from rospy.impl import masterslave

    handler = masterslave.ROSHandler
    if getattr(handler, "_walkman_serialised", False):
        return
    connect = handler._connect_topic
    locks: Dict[tuple, threading.Lock] = {}
    locks_lock = threading.Lock()

    def connect_in_turn(self: Any, topic: str, pub_uri: str):
        with locks_lock:
            turn = locks.setdefault((topic, pub_uri), threading.Lock())
        with turn:   # rospy's own "already connected" check then sees the first
            return connect(self, topic, pub_uri)

    handler._connect_topic = connect_in_turn
    handler._walkman_serialised = True


class RosNode:
    """rospy's node for this process: started when the master answers, kept registered."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.ready = threading.Event()
        self._stop = threading.Event()
        self._on_ready: List[Callable[[], None]] = []
        self._on_again: List[Callable[[], None]] = []
        self._on_failed: List[Callable[[str], None]] = []
        #: why the node's ROS side did not open (a ready action raised), else ""
        self.failed = ""
        self._adopted: Dict[str, str] = {}     # roscpp node name -> its XML-RPC URI
        self._master_pid: Optional[int] = None
        self._thread = threading.Thread(target=self._run, name="ros node", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def when_ready(self, action: Callable[[], None]) -> None:
        self._on_ready.append(action)

    def when_failed(self, action: Callable[[str], None]) -> None:
        """``action(why)`` runs if a :meth:`when_ready` action raised: the node's topics
        and services are not up, and will not be (a program that cannot serve without them
        says so and ends, rather than wait forever for a thread that is gone)."""
        self._on_failed.append(action)

    def when_registered_again(self, action: Callable[[], None]) -> None:
        """``action`` runs after each master restart, once our topics are registered again
        (for what rospy does not own: a roscpp part of the process, a parameter)."""
        self._on_again.append(action)

    def _master(self, caller: str = ""):
        import rosgraph

        return rosgraph.Master(caller or self.name)

    def adopt(self) -> List[str]:
        """Take on the other ROS nodes of this process (roscpp's: librviz) to register them
        again after a master restart; returns their names."""
        for name, uri in nodes_of_this_process(self._master()).items():
            if name != f"/{self.name.lstrip('/')}" and name not in self._adopted:
                self._adopted[name] = uri
                log.info("ROS node %s (%s) lives in this process: registered again with ours",
                         name, uri)
        return sorted(self._adopted)

    def _run(self) -> None:
        import rosgraph
        import rospy

        announced = False
        while not self._stop.is_set() and not rosgraph.is_master_online():
            if not announced:
                log.info("waiting for the ROS master at %s", rosgraph.get_master_uri())
                announced = True
            self._stop.wait(1.0)
        if self._stop.is_set():
            return
        guard_tcpros()
        one_connection_per_publisher()
        rospy.init_node(self.name, anonymous=False, disable_signals=True)
        self._master_pid = self._pid()
        log.info("ROS node %s registered with %s", rospy.get_name(), rosgraph.get_master_uri())
        for action in self._on_ready:
            try:
                action()
            except Exception as exc:  # noqa: BLE001 -- told, then the owner decides
                self._fail(action, exc)
                return
        self.ready.set()
        while not self._stop.wait(1.0):
            pid = self._pid()
            if pid is not None and pid != self._master_pid:
                log.warning("the ROS master restarted; registering our topics again")
                if self._register_again():
                    self._master_pid = pid
                    for action in self._on_again:
                        action()

    def _fail(self, action: Callable[[], None], exc: Exception) -> None:
        self.failed = (f"{getattr(action, '__qualname__', action)} raised "
                       f"{type(exc).__name__}: {exc}")
        log.error("the ROS side of %s did not open: %s", self.name, self.failed,
                  exc_info=True)
        for failed in self._on_failed:
            failed(self.failed)

    def _pid(self) -> Optional[int]:
        import rosgraph

        try:
            return int(self._master().getPid())
        except (OSError, rosgraph.MasterException):   # master down: keep the old one
            return None

    def _register_again(self) -> bool:
        import rospy
        from rospy.impl.registration import (RegManager, get_registration_listeners,
                                             get_service_manager, get_topic_manager)

        manager = next((l for l in get_registration_listeners().listeners
                        if isinstance(l, RegManager)), None)
        master = self._master()
        uri = rospy.core.get_node_uri()
        try:
            for topic, type_name in get_topic_manager().get_publications():
                master.registerPublisher(topic, type_name, uri)
            for topic, type_name in get_topic_manager().get_subscriptions():
                publishers = master.registerSubscriber(topic, type_name, uri)
                if manager is not None:
                    manager.publisher_update(topic, publishers)
            for service, service_uri in get_service_manager().get_services():
                master.registerService(service, service_uri, uri)
            for name, node_uri in self._adopted.items():
                self._register_foreign(name, node_uri)
        except Exception as exc:  # noqa: BLE001 -- try again next second
            log.warning("registering again failed: %s", exc)
            return False
        return True

    def _register_foreign(self, name: str, uri: str) -> None:
        """Register a node of this process through its slave API, as it would itself."""
        from xmlrpc.client import ServerProxy

        node = ServerProxy(uri)
        master = self._master(name)
        for topic, type_name in node.getSubscriptions(self.name)[2]:
            publishers = master.registerSubscriber(topic, type_name, uri)
            node.publisherUpdate("/master", topic, publishers)
        for topic, type_name in node.getPublications(self.name)[2]:
            master.registerPublisher(topic, type_name, uri)

    def stop(self) -> None:
        self._stop.set()
        if self.ready.is_set():
            import rospy

            rospy.signal_shutdown("node stopping")


def handshaken(subscriber: Any) -> int:
    """How many publishers a rospy ``Subscriber`` has finished its TCPROS handshake with.

    ``get_num_connections`` counts a publisher from the moment rospy starts connecting to
    it, and what the publisher sends before its end of the handshake never arrives (fc3: a
    loaded gateway took the PI's handshake 1.05 s after the PI counted it, and both pilots'
    commands published meanwhile were missing from the PI's log).  rospy learns the
    connection's local end once the publisher's reply header is read: that is the test.
    """
    connections = list(getattr(getattr(subscriber, "impl", None), "connections", None) or [])
    return sum(1 for connection in connections
               if (getattr(connection, "local_endpoint", None) or (None,))[0] is not None)


def nodes_of_this_process(master: Any) -> Dict[str, str]:
    """The nodes the master knows whose XML-RPC server listens in this process (name: URI)."""
    from urllib.parse import urlsplit

    import rosgraph

    publishers, subscribers, services = master.getSystemState()
    names = {n for _, nodes in [*publishers, *subscribers, *services] for n in nodes}
    ports = listening_ports()
    found = {}
    for name in sorted(names):
        try:
            uri = master.lookupNode(name)
            port = urlsplit(uri).port
        except (rosgraph.MasterError, ValueError):
            continue
        if port in ports:
            found[name] = uri
    return found


def listening_ports() -> Set[int]:
    """TCP ports this process listens on (its sockets' inodes in /proc/net/tcp{,6})."""
    inodes: Set[str] = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    ports: Set[int] = set()
    for table in ("/proc/self/net/tcp", "/proc/self/net/tcp6"):
        try:
            with open(table) as rows:
                next(rows)
                for row in rows:
                    fields = row.split()
                    if fields[3] == "0A" and fields[9] in inodes:     # LISTEN
                        ports.add(int(fields[1].rsplit(":", 1)[1], 16))
        except OSError:
            continue
    return ports
