"""A pilot that sends numbered commands and insists until each is accepted.

``python pilot_sender.py TARGET FIRST LAST [INTERVAL]`` sends ``(count N) N``
for N in FIRST..LAST to TARGET (e.g. ``/counter/command:i``) over tcp, which
YARP acknowledges; when a write fails it reconnects and sends the same N again,
as a pilot GUI would.  Prints ``sent N`` after each acknowledged write, and
``not accepted N`` once when N first fails (tests wait for it to know the
pilot noticed an outage).  LAST ``-``: until its stdin closes (a test that
needs the pilot commanding through phases of unknown length), then ``last N``.
"""

import sys
import threading
import time

from yarp_lite.bottle import Bottle
from yarp_lite.port import Port


def main() -> int:
    target, first = sys.argv[1], int(sys.argv[2])
    interval = float(sys.argv[4]) if len(sys.argv) > 4 else 0.05
    told = threading.Event()
    if sys.argv[3] == "-":
        last = sys.maxsize
        threading.Thread(target=lambda: (sys.stdin.read(), told.set()), daemon=True).start()
    else:
        last = int(sys.argv[3])
    port = Port()
    port.open(f"/test/sender{first}", wait=60)
    number, refused = first, None
    while number <= last and not told.is_set():
        if (port.output_count or port.add_output(target, quiet=True)) and \
                port.write(Bottle([Bottle(["count", number]), number])) and port.output_count:
            print(f"sent {number}", flush=True)
            number += 1
            time.sleep(interval)
            continue
        if refused != number:
            print(f"not accepted {number}", flush=True)
            refused = number
        time.sleep(0.2)
    if told.is_set():
        print(f"last {number - 1}", flush=True)
    port.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
