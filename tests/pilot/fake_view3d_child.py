"""A stand-in for :mod:`pilot.view3d_child` that speaks the protocol without librviz.

Run by the process layer's tests as ``python -m tests.pilot.fake_view3d_child --fd N
--pi P --markers M [--forget NODE ...]``; ``FAKE_VIEW3D`` says how to behave:

Every mode but ``exit`` waits for the PI's ``go`` (a warm spare waits long) first.

``ok``      window at once, then answers pings; an ``add`` comes back as ``moved`` with
            x + 1 (the pilot dragged it)
``deaf``    window, then never answers a ping (hung)
``exit``    exits with status 3 before any window (a broken installation)
``segv``    window, then dies of SIGSEGV with faulthandler's stacks in ``stacks.txt``
``garbage`` window, then a line that is not JSON, then waits to be killed
"""

from __future__ import annotations

import argparse
import faulthandler
import os
import signal
import socket
import sys

from pilot.view3d_protocol import (AddMarker, Decoder, Direction, Go, MarkerMoved, Ping, Pong,
                                   RosNodes, WindowReady, encode)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--fd", type=int, required=True)
    parser.add_argument("--pi", required=True)
    parser.add_argument("--markers", required=True)
    options = parser.parse_args()
    mode = os.environ.get("FAKE_VIEW3D", "ok")
    if mode == "exit":
        return 3
    sock = socket.socket(fileno=options.fd)
    decoder = Decoder(Direction.TO_CHILD)
    backlog: list = []
    while not any(isinstance(m, Go) for m in backlog):
        data = sock.recv(4096)
        if not data:
            return 0                    # closed while a spare
        decoder.feed(data)
        backlog += decoder.messages()
    sock.sendall(encode(WindowReady(4242, os.getpid())))
    sock.sendall(encode(RosNodes(f"/{options.pi}_view3d_{os.getpid()}",
                                 {f"/rviz_{os.getpid()}": "http://127.0.0.1:1/"})))
    if mode == "garbage":
        sock.sendall(b"{not json\n")
        signal.pause()
    if mode == "segv":
        faulthandler.enable(open("stacks.txt", "w"))
        os.kill(os.getpid(), signal.SIGSEGV)
    while not decoder.ended:
        if not backlog:
            decoder.feed(sock.recv(4096))
        messages, backlog = backlog + decoder.messages(), []
        for message in messages:
            if isinstance(message, Ping) and mode != "deaf":
                sock.sendall(encode(Pong(message.seq)))
            elif isinstance(message, AddMarker):
                x, *rest = message.pose
                sock.sendall(encode(MarkerMoved(message.name, (x + 1, *rest))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
