"""Persistent connections and topics, kept in SQLite (``SubscriberOnSql``).

A subscription ``src -> dest`` (optionally with a carrier, ``udp://dest``)
asks the name server to make that connection whenever both ports are alive,
and to make it again after either restarts.  Topics are virtual ports:
``src -> /topic`` and ``/topic -> dest`` mean ``src -> dest``.  A port is
*alive* from its ``announce`` until its ``unregister``.  Modes ``from``/``to``
make a subscription expire with its source/destination (``--persist-from``).

This module only decides: :meth:`Subscriptions.welcome` and friends return the
connections to make or break, and the server hands them to its connector.
The schema is yarpserver's, so a ``--subdb`` file can move between the two.
"""

from __future__ import annotations

import sqlite3
import threading
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

from yarp_lite.bottle import Bottle

_SCHEMA = """
CREATE TABLE IF NOT EXISTS subscriptions (
    id INTEGER PRIMARY KEY, src TEXT, dest TEXT, srcFull TEXT, destFull TEXT, mode TEXT);
CREATE TABLE IF NOT EXISTS topics (id INTEGER PRIMARY KEY, topic TEXT, structure TEXT);
CREATE TABLE IF NOT EXISTS live (id INTEGER PRIMARY KEY, name TEXT UNIQUE, stamp DATETIME);
CREATE TABLE IF NOT EXISTS structures (name TEXT PRIMARY KEY, yarp TEXT);
"""


def split_name(text: str) -> Tuple[str, str]:
    """``ParseName``: ``udp://read`` -> (``udp``, ``/read``); ``/read`` -> (``""``, ``/read``)."""
    mid = text.find(":/")
    if mid > 0:
        carrier, name = text[:mid], text[mid + 2:]
        return carrier.lstrip("/"), name
    return "", text


@dataclass(frozen=True)
class Action:
    """A connection the server should make (``connect``) or break."""

    source: str
    target: str
    connect: bool


Lookup = Callable[[str], Optional[str]]  # port name -> its registered carrier, or None


class Subscriptions:
    def __init__(self, path: str) -> None:
        self.db = sqlite3.connect(path, check_same_thread=False, isolation_level=None)
        self.lock = threading.RLock()
        with self.lock:
            self.db.executescript(_SCHEMA)

    def close(self) -> None:
        with self.lock:
            self.db.close()

    # -- subscriptions ---------------------------------------------------------------

    def add(self, src: str, dest: str, mode: str, lookup: Lookup) -> List[Action]:
        self.remove(src, dest)
        src_carrier, src_name = split_name(src)
        dest_carrier, dest_name = split_name(dest)
        with self.lock:
            if src_carrier == "topic":
                self._set_topic(src_name)
            if dest_carrier == "topic":
                self._set_topic(dest_name)
            self.db.execute("INSERT INTO subscriptions (src, dest, srcFull, destFull, mode) "
                            "VALUES (?, ?, ?, ?, ?)",
                            (src_name, dest_name, src, dest, mode or None))
        if src_carrier != "topic" and dest_carrier != "topic":
            return self._check(src_name, dest_name, src, dest, mode, lookup)
        return self.hookup(dest_name if src_carrier == "topic" else src_name, lookup)

    def wanted(self, src: str, dest: str) -> bool:
        """Whether a subscription asks for ``src -> dest`` and both ports are alive now.  A
        break decided when one of them left is stale once it is back (a module restarted
        under the same names): applied late, it would cut the new process's connection."""
        src_name, dest_name = split_name(src)[1], split_name(dest)[1]
        with self.lock:
            row = self.db.execute(
                "SELECT 1 FROM subscriptions WHERE src = ? AND dest = ? "
                "AND EXISTS (SELECT NULL FROM live WHERE name = ?) "
                "AND EXISTS (SELECT NULL FROM live WHERE name = ?)",
                (src_name, dest_name, src_name, dest_name)).fetchone()
        return row is not None

    def remove(self, src: str, dest: str) -> bool:
        with self.lock:
            cursor = self.db.execute("DELETE FROM subscriptions WHERE src = ? AND dest = ?",
                                     (split_name(src)[1], split_name(dest)[1]))
        return cursor.rowcount >= 0

    def listing(self, port: str = "") -> Bottle:
        """``subscriptions (subscription (src ..) (dest ..) [(mode ..)] [(topic s d)])...``"""
        query = ("SELECT s.srcFull, s.destFull, EXISTS(SELECT topic FROM topics WHERE topic = s.src), "
                 "EXISTS(SELECT topic FROM topics WHERE topic = s.dest), s.mode "
                 "FROM subscriptions s")
        args: tuple = ()
        if port:
            query += " WHERE s.src = ? OR s.dest = ?"
            args = (port, port)
        query += " ORDER BY s.src, s.dest"
        reply = Bottle(["subscriptions"])
        with self.lock:
            rows = self.db.execute(query, args).fetchall()
        for src, dest, src_topic, dest_topic, mode in rows:
            entry = Bottle(["subscription", Bottle(["src", src]), Bottle(["dest", dest])])
            if mode:
                entry.append(Bottle(["mode", mode]))
            if src_topic or dest_topic:
                entry.append(Bottle(["topic", src_topic, dest_topic]))
            reply.append(entry)
        return reply

    # -- topics ------------------------------------------------------------------------

    def set_topic(self, name: str, structure: str, active: bool, lookup: Lookup) -> List[Action]:
        with self.lock:
            if structure or not active:
                self.db.execute("DELETE FROM topics WHERE topic = ?", (name,))
                if not active:
                    return []
            self._set_topic(name, structure)
            rows = self.db.execute(
                "SELECT s1.src, s2.dest, s1.srcFull, s2.destFull FROM subscriptions s1, "
                "subscriptions s2, topics t WHERE (t.topic = ? AND s1.dest = t.topic AND "
                "s2.src = t.topic)", (name,)).fetchall()
        actions: List[Action] = []
        for src, dest, src_full, dest_full in rows:
            actions += self._check(src, dest, src_full, dest_full, "", lookup)
        return actions

    def _set_topic(self, name: str, structure: str = "") -> None:
        exists = self.db.execute("SELECT topic FROM topics WHERE topic = ?", (name,)).fetchone()
        if structure or not exists:
            self.db.execute("INSERT INTO topics (topic, structure) VALUES (?, ?)",
                            (name, structure or None))

    def topics(self) -> List[str]:
        with self.lock:
            return [row[0] for row in self.db.execute("SELECT topic FROM topics")]

    def is_topic(self, name: str) -> bool:
        with self.lock:
            return self.db.execute("SELECT 1 FROM topics WHERE topic = ?",
                                   (name,)).fetchone() is not None

    def set_type(self, family: str, structure: str, value: str) -> bool:
        if family != "yarp":
            return False
        with self.lock:
            self.db.execute("INSERT OR REPLACE INTO structures (name, yarp) VALUES (?, ?)",
                            (structure, value))
        return True

    def get_type(self, family: str, structure: str) -> str:
        if family != "yarp":
            return ""
        with self.lock:
            row = self.db.execute("SELECT yarp FROM structures WHERE name = ?",
                                  (structure,)).fetchone()
        return row[0] if row and row[0] else ""

    # -- liveness ----------------------------------------------------------------------

    def welcome(self, port: str, activity: int, lookup: Lookup) -> List[Action]:
        """A port announced itself (1), stopped answering (0) or unregistered (-1)."""
        with self.lock:
            if activity > 0:
                self.db.execute("INSERT OR IGNORE INTO live (name, stamp) "
                                "VALUES (?, DATETIME('now'))", (port,))
            elif activity == 0:
                self.db.execute("DELETE FROM live WHERE name = ? AND "
                                "stamp < DATETIME('now', '-30 seconds')", (port,))
            else:
                self.db.execute("DELETE FROM live WHERE name = ?", (port,))
        if activity > 0:
            return self.hookup(port, lookup)
        if activity < 0:
            return self.breakdown(port, lookup)
        return []

    def hookup(self, port: str, lookup: Lookup) -> List[Action]:
        with self.lock:
            rows = self.db.execute(
                "SELECT src, dest, srcFull, destFull, mode FROM subscriptions WHERE "
                "(src = ? OR dest = ?) AND EXISTS (SELECT NULL FROM live WHERE name = src) "
                "AND EXISTS (SELECT NULL FROM live WHERE name = dest) "
                "UNION SELECT s1.src, s2.dest, s1.srcFull, s2.destFull, NULL "
                "FROM subscriptions s1, subscriptions s2, topics t "
                "WHERE (s1.dest = t.topic AND s2.src = t.topic) AND (s1.src = ? OR s2.dest = ?) "
                "AND EXISTS (SELECT NULL FROM live WHERE name = s1.src) "
                "AND EXISTS (SELECT NULL FROM live WHERE name = s2.dest)",
                (port, port, port, port)).fetchall()
        actions: List[Action] = []
        for src, dest, src_full, dest_full, mode in rows:
            actions += self._check(src, dest, src_full, dest_full, mode or "", lookup)
        return actions

    def breakdown(self, port: str, lookup: Lookup) -> List[Action]:
        with self.lock:
            rows = self.db.execute(
                "SELECT src, dest, srcFull, destFull, mode FROM subscriptions WHERE "
                "((src = ? AND (mode IS NOT NULL OR EXISTS (SELECT NULL FROM live WHERE name = dest))) "
                "OR (dest = ? AND (mode IS NOT NULL OR EXISTS (SELECT NULL FROM live WHERE name = src))))",
                (port, port)).fetchall()
        actions: List[Action] = []
        for src, dest, src_full, dest_full, mode in rows:
            source_dropped = port == src
            survivor = dest if source_dropped else src
            if lookup(survivor) is not None and not source_dropped:
                actions.append(Action(src_full, dest_full, False))
            if mode == "from" and source_dropped:
                self.remove(src, dest)
            elif mode == "to" and not source_dropped:
                self.remove(src, dest)
        return actions

    def _check(self, src: str, dest: str, src_full: str, dest_full: str, mode: str,
               lookup: Lookup) -> List[Action]:
        src_carrier, dest_carrier = lookup(src), lookup(dest)
        actions: List[Action] = []
        if src_carrier is not None and dest_carrier is not None:
            if src_carrier != "topic" and dest_carrier != "topic" \
                    and not self.is_topic(src) and not self.is_topic(dest):
                actions.append(Action(src_full, dest_full, True))
        if mode == "from" and src_carrier is None:
            self.remove(src, dest)
        elif mode == "to" and dest_carrier is None:
            self.remove(src, dest)
        return actions
