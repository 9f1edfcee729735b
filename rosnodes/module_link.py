"""One GYM module's ports as the pilot gateway holds them (:mod:`rosnodes.gateway`).

For a module ``M`` the gateway opens, under its station's prefix, ``M/switch:o`` and
``M/command:o`` (to the module's ``/M/switch:i`` and ``/M/command:i``) and ``M/status:i``,
``M/warning:i``, ``M/receipt:i`` (from its outputs); a :class:`~nodekit.connections.
ConnectionKeeper` keeps every connection made, through restarts on either side.  Its
readers may be called as soon as a port opens, so everything they touch exists first.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from typing import List, Optional

from nodekit.connections import ConnectionKeeper
from walkman.gym.interfaces import COMMAND, RECEIPT, STATUS, SWITCH, WARNING
from walkman.gym.lifecycle import lifecycle_of_status
from yarp_lite.bottle import Bottle
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port

log = logging.getLogger("walkman.gateway")

#: How long a message waits for the connection to its module before it is refused (s).
CONNECT_GRACE = 10.0


def lifecycle_of(state: str) -> str:
    """The lifecycle word (``running``...) of one of a module's own states."""
    return lifecycle_of_status(state).value


@dataclass(frozen=True)
class Sent:
    """What became of a message to a module: sent (with its number), or why not."""

    ok: bool
    message: str = ""
    seq: int = 0


@dataclass(frozen=True)
class HeardStatus:
    """A module's last status, as it came and as decoded."""

    seq: int
    state: str
    data: list
    bottle: Bottle

    @property
    def code(self) -> str:
        return str(self.bottle[1])



class ModuleLink:
    """One module's YARP ports (:data:`GYM_PORTS`), as the pilot sees them."""

    def __init__(self, module: str, statuses: List[str], prefix: str, nameclient: NameClient,
                 keeper: ConnectionKeeper, on_status, on_warning, on_receipt) -> None:
        self.module = module
        self.statuses = statuses
        # Everything the readers touch exists before a port opens: a message may arrive at once.
        self.last_status: Optional[HeardStatus] = None
        self.changed = threading.Condition()
        self.warnings: List[str] = []
        base = f"{prefix}/{module}"
        self.switch = Port(nameclient=nameclient).open(f"{base}/switch:o", wait=math.inf)
        self.command = Port(nameclient=nameclient).open(f"{base}/command:o", wait=math.inf)
        self.status = Port(nameclient=nameclient, reader=lambda b: on_status(self, b))
        self.status.open(f"{base}/status:i", wait=math.inf)
        self.warning = Port(nameclient=nameclient, reader=lambda b: on_warning(self, b))
        self.warning.open(f"{base}/warning:i", wait=math.inf)
        self.receipt = Port(nameclient=nameclient, reader=lambda b: on_receipt(self, b))
        self.receipt.open(f"{base}/receipt:i", wait=math.inf)
        keeper.want(self.switch.name, SWITCH.of(module), self.switch, ours_is_source=True)
        keeper.want(self.command.name, COMMAND.of(module), self.command, ours_is_source=True)
        for theirs, ours in ((STATUS, self.status), (WARNING, self.warning),
                             (RECEIPT, self.receipt)):
            keeper.want(theirs.of(module), ours.name, ours, ours_is_source=False)

    def send(self, port: Port, bottle: Bottle) -> Sent:
        # A pilot's first command may come before the connection keeper made the
        # connection (just after start-up, or a restart of the bridge): wait for it a while
        # rather than drop the command.
        deadline = time.monotonic() + CONNECT_GRACE
        if port.output_count == 0:
            log.info("%s: no connection to /%s yet; the message waits for it up to %g s",
                     port.name, self.module, CONNECT_GRACE)
        while port.output_count == 0:
            if time.monotonic() > deadline:
                return Sent(False, f"/{self.module} is not reachable (no connection to its "
                                   f"port within {CONNECT_GRACE:g} s)")
            time.sleep(0.05)
        if not port.write(bottle):
            return Sent(False, f"/{self.module} did not accept the message")
        return Sent(True)

    @property
    def lifecycle(self) -> str:
        return lifecycle_of(self.last_status.state) if self.last_status else "unknown"

    def close(self) -> None:
        for port in (self.switch, self.command, self.status, self.warning, self.receipt):
            port.close()
