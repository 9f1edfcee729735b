"""Datagrams and a TCP stream across an emulated link, timed (run inside a host's namespace).

Both hosts of :class:`netem.emulation.EmulatedLink` share this machine's monotonic clock,
so a time printed by the sender and one printed by the receiver subtract to a one-way
delay.  Verbs, one process each::

    receive ADDRESS PORT              print "listening", then "got SEQ SIZE TIME" per datagram
    send ADDRESS PORT SIZE COUNT GAP [FIRST]
                                      COUNT datagrams of SIZE bytes, GAP s apart (0: back to
                                      back), numbered from FIRST (0); "sent SEQ TIME" before
                                      each, "done" at the end
    sink ADDRESS PORT BYTES           accept one TCP connection, read BYTES; print
                                      "first TIME" and "last TIME" (first and last byte read)
    source ADDRESS PORT BYTES         print "start TIME", connect and write BYTES; "done"

A datagram's first 4 bytes are its sequence number.  The frame on the wire is SIZE + 42
bytes (UDP 8, IPv4 20, Ethernet 14).
"""

from __future__ import annotations

import socket
import struct
import sys
import time
from typing import List

#: UDP, IPv4 and Ethernet headers: what a datagram adds to its payload on the cable.
HEADERS = 8 + 20 + 14


def receive(address: str, port: int) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, 33, 8 << 20)  # SO_RCVBUFFORCE: a burst waits here
    sock.bind((address, port))
    print("listening", flush=True)
    while True:
        data = sock.recv(65536)
        now = time.monotonic()
        print(f"got {struct.unpack_from('!I', data)[0]} {len(data)} {now:.6f}", flush=True)


def send(address: str, port: int, size: int, count: int, gap: float, first: int = 0) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    lines: List[str] = []
    for seq in range(first, first + count):
        payload = struct.pack("!I", seq) + b"x" * (size - 4)
        now = time.monotonic()
        sock.sendto(payload, (address, port))
        lines.append(f"sent {seq} {now:.6f}")
        if gap:
            print(lines.pop(), flush=True)
            time.sleep(gap)
    print("\n".join([*lines, "done"]), flush=True)  # back to back: printed afterwards


def sink(address: str, port: int, total: int) -> None:
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind((address, port))
    server.listen(1)
    print("listening", flush=True)
    connection, _ = server.accept()
    received, first = 0, None
    while received < total:
        data = connection.recv(1 << 16)
        if not data:
            break
        if first is None:
            first = time.monotonic()
            print(f"first {first:.6f}", flush=True)
        received += len(data)
    print(f"last {time.monotonic():.6f} {received}", flush=True)


def source(address: str, port: int, total: int) -> None:
    print(f"start {time.monotonic():.6f}", flush=True)
    with socket.create_connection((address, port), timeout=600) as connection:
        chunk = b"x" * (1 << 16)
        left = total
        while left > 0:
            left -= connection.send(chunk[:left])
        connection.shutdown(socket.SHUT_WR)
        connection.recv(1)  # the sink closes once it has everything
    print("done", flush=True)


def main(argv: List[str]) -> int:
    verb, address, port, *rest = argv
    if verb == "receive":
        receive(address, int(port))
    elif verb == "send":
        send(address, int(port), int(rest[0]), int(rest[1]), float(rest[2]),
             int(rest[3]) if len(rest) > 3 else 0)
    elif verb == "sink":
        sink(address, int(port), int(rest[0]))
    elif verb == "source":
        source(address, int(port), int(rest[0]))
    else:
        print(f"unknown verb {verb!r}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
