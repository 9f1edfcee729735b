"""The name server's table of ports, their properties, and socket-number allocation.

Follows ``NameServiceOnTriples`` and ``AllocatorOnTriples`` of yarpserver:
numbers are handed out from ``server port + 2`` upwards and stay stable per
port name (a port re-registering gets its previous number back when free);
freed numbers are reused only once the range is exhausted.  Anonymous ports
(``register ...``) are named ``/tmp/port/N``.  Stored in SQLite, in memory by
default or in the ``--portdb`` file.
"""

from __future__ import annotations

import sqlite3
import threading
from dataclasses import dataclass
from typing import Dict, List, Optional

from yarp_lite.contact import Contact

MIN_OFFSET = 2
MAX_OFFSET = 9999
#: Bytes of properties (keys and values) one port may hold: ``set`` beyond it is refused,
#: so a peer repeating ``set`` with new keys cannot grow the server without bound.
MAX_PROPERTY_BYTES = 64 * 1024

_SCHEMA = """
CREATE TABLE IF NOT EXISTS ports (
    name TEXT PRIMARY KEY, host TEXT, port INTEGER, carrier TEXT, type TEXT,
    seq INTEGER);
CREATE TABLE IF NOT EXISTS properties (
    name TEXT, key TEXT, value TEXT, seq INTEGER);
CREATE INDEX IF NOT EXISTS properties_by_name ON properties (name, key);
CREATE TABLE IF NOT EXISTS counters (key TEXT PRIMARY KEY, value INTEGER);
CREATE TABLE IF NOT EXISTS numbers (
    number INTEGER PRIMARY KEY, in_use INTEGER, preferred_by TEXT);
CREATE TABLE IF NOT EXISTS anonymous (name TEXT PRIMARY KEY, in_use INTEGER);
"""


class RegistryFull(Exception):
    """Every socket number of the server's range is in use."""


class PropertyLimit(Exception):
    """A ``set`` would make one port's properties larger than :data:`MAX_PROPERTY_BYTES`."""


@dataclass(frozen=True)
class Registration:
    name: str
    host: str
    port: int
    carrier: str
    type: str = "*"

    def contact(self) -> Contact:
        return Contact(self.name, self.carrier, self.host, self.port)


class Registry:
    """Thread-safe port registry (one lock; every method is one transaction).

    Listings come sorted by name and property values sorted by value, the
    order yarpserver's SQLite index gives them.
    """

    def __init__(self, path: str, server_port: int, reset: bool = False) -> None:
        self.db = sqlite3.connect(path, check_same_thread=False, isolation_level=None)
        self.lock = threading.RLock()
        self.min_number = server_port + MIN_OFFSET
        self.max_number = server_port + MAX_OFFSET
        with self.lock:
            self.db.executescript(_SCHEMA)
            if reset:
                self.db.executescript("DELETE FROM ports; DELETE FROM properties; "
                                      "DELETE FROM counters; DELETE FROM numbers; "
                                      "DELETE FROM anonymous;")

    # -- queries -------------------------------------------------------------------

    def get(self, name: str) -> Optional[Registration]:
        with self.lock:
            row = self.db.execute("SELECT name, host, port, carrier, type FROM ports "
                                  "WHERE name = ?", (name,)).fetchone()
        return Registration(*row) if row else None

    def names(self) -> List[str]:
        with self.lock:
            return [row[0] for row in self.db.execute("SELECT name FROM ports ORDER BY name")]

    def count(self) -> int:
        with self.lock:
            return self.db.execute("SELECT COUNT(*) FROM ports").fetchone()[0]

    def property(self, name: str, key: str) -> List[str]:
        with self.lock:
            return [row[0] for row in self.db.execute(
                "SELECT value FROM properties WHERE name = ? AND key = ? ORDER BY value",
                (name, key))]

    def properties(self, name: str) -> Dict[str, List[str]]:
        result: Dict[str, List[str]] = {}
        with self.lock:
            for key, value in self.db.execute(
                    "SELECT key, value FROM properties WHERE name = ? ORDER BY seq", (name,)):
                result.setdefault(key, []).append(value)
        return result

    # -- changes -------------------------------------------------------------------

    def register(self, name: str, carrier: str, host: str, port: int,
                 type_name: str = "*") -> Registration:
        """Store a registration; ``port <= 0`` allocates a number, ``...`` a name."""
        with self.lock:
            self.db.execute("BEGIN")
            try:
                if name == "..." or name.startswith("="):
                    base = self._anonymous_name()
                    name = base if name == "..." else base + name
                if port <= 0:
                    port = self._allocate(name)
                else:
                    self._mark_number(port, name)
                seq = self._next("seq")
                self.db.execute("INSERT OR REPLACE INTO ports VALUES (?, ?, ?, ?, ?, ?)",
                                (name, host, port, carrier, type_name, seq))
                self.db.execute("COMMIT")
            except BaseException:
                self.db.execute("ROLLBACK")
                raise
        return Registration(name, host, port, carrier, type_name)

    def unregister(self, name: str) -> Optional[Registration]:
        with self.lock:
            existing = self.get(name)
            self.db.execute("DELETE FROM ports WHERE name = ?", (name,))
            self.db.execute("DELETE FROM properties WHERE name = ?", (name,))
            self.db.execute("UPDATE anonymous SET in_use = 0 WHERE name = ?", (name,))
            if existing is not None:
                self.db.execute("UPDATE numbers SET in_use = 0 WHERE number = ?",
                                (existing.port,))
        return existing

    def set_property(self, name: str, key: str, values: List[str]) -> bool:
        """Replace ``key``'s values; False when ``name`` is not registered.

        Raises :class:`PropertyLimit` when the port's properties would exceed
        :data:`MAX_PROPERTY_BYTES` (nothing is changed then).
        """
        with self.lock:
            if self.get(name) is None:
                return False
            (held,) = self.db.execute(
                "SELECT COALESCE(SUM(LENGTH(key) + LENGTH(value)), 0) FROM properties "
                "WHERE name = ? AND key != ?", (name, key)).fetchone()
            wanted = held + sum(len(key) + len(value) for value in values)
            if wanted > MAX_PROPERTY_BYTES:
                raise PropertyLimit(f"properties of {name} would take {wanted} bytes "
                                    f"(limit {MAX_PROPERTY_BYTES})")
            self.db.execute("DELETE FROM properties WHERE name = ? AND key = ?", (name, key))
            for value in values:
                self.db.execute("INSERT INTO properties VALUES (?, ?, ?, ?)",
                                (name, key, value, self._next("prop")))
        return True

    # -- allocation ----------------------------------------------------------------

    def _next(self, key: str) -> int:
        row = self.db.execute("SELECT value FROM counters WHERE key = ?", (key,)).fetchone()
        value = (row[0] if row else 0) + 1
        self.db.execute("INSERT OR REPLACE INTO counters VALUES (?, ?)", (key, value))
        return value

    def _anonymous_name(self) -> str:
        row = self.db.execute("SELECT name FROM anonymous WHERE in_use = 0 LIMIT 1").fetchone()
        name = row[0] if row else f"/tmp/port/{self._next('tmpid')}"
        self.db.execute("INSERT OR REPLACE INTO anonymous VALUES (?, 1)", (name,))
        return name

    def _mark_number(self, number: int, name: str) -> None:
        self.db.execute("INSERT OR REPLACE INTO numbers VALUES (?, 1, ?)", (number, name))

    def _allocate(self, name: str) -> int:
        row = self.db.execute("SELECT number FROM numbers WHERE preferred_by = ? AND in_use = 0",
                              (name,)).fetchone()
        if row:
            number = row[0]
        else:
            row = self.db.execute("SELECT value FROM counters WHERE key = 'regid'").fetchone()
            last = row[0] if row else self.min_number - 1
            if last < self.max_number:
                number = last + 1
                self.db.execute("INSERT OR REPLACE INTO counters VALUES ('regid', ?)", (number,))
            else:
                row = self.db.execute("SELECT number FROM numbers WHERE in_use = 0 "
                                      "ORDER BY number LIMIT 1").fetchone()
                if row is None:
                    raise RegistryFull(
                        f"all socket numbers {self.min_number}..{self.max_number} are in use; "
                        "make sure programs close their ports, or run 'yarp-lite clean'")
                number = row[0]
        self._mark_number(number, name)
        return number

    def close(self) -> None:
        with self.lock:
            self.db.close()
