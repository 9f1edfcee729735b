"""Which robot answers, and how it groups its joints: a Walk-Man HAL or a plain YARP robot.

A Walk-Man HAL (or the bridge's copy of it) answers ``[get] chains`` on
``/<robot>/rpc:i`` with every chain and its joints.  Any other YARP robot is
found chain by chain: a control board ``/<robot>/<chain>/rpc:i`` for each of
the model's chains (:data:`walkman.model.description.CHAINS`), its axes counted
(``[get] [axes]``) and named (``[get] [name] j``).  Our HAL registers its robot
port before its chains, so a chain seen without it is a plain robot's, not a
HAL half started.  Both are asked again until ``timeout``: a module may start
before its robot.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Dict, List

from walkman.hal import protocol
from walkman.hal.protocol import HalProtocolError
from walkman.model.description import CHAINS
from walkman.model.description import Robot as RobotModel
from yarp_lite import network
from yarp_lite.bottle import Vocab
from yarp_lite.errors import NetworkError, YarpError
from yarp_lite.nameclient import NameClient

log = logging.getLogger("walkman.robot")


@dataclass(frozen=True)
class Grouping:
    """The robot's chains and their joints (by the model's names), and whether it is a
    plain YARP robot (``stateExt:o``, no ``[get] chains``, no ``stateSI:o``)."""

    chains: Dict[str, List[str]]
    standard: bool


def find_grouping(nameclient: NameClient, robot: str, model: RobotModel, owner: str,
                  timeout: float) -> Grouping:
    """Ask the HAL for its chains; failing that, find a plain YARP robot's parts."""
    deadline = time.monotonic() + timeout
    said = 0.0
    answer = ""
    rpc_name = protocol.robot_rpc_name(robot)
    while True:
        try:
            contact = nameclient.query(rpc_name)
            if contact is not None:
                reply = network.request(contact, [Vocab("get"), "chains"], timeout=5)
                grouping = {str(group[0]): [str(j) for j in group[1:]] for group in reply
                            if isinstance(group, list) and group}
                if grouping:
                    return Grouping(grouping, standard=False)
                # A HAL (or a bridge's copy of it) that is not ready yet: ask again.
                answer = f"; it answered {str(reply)[:120]}"
            else:
                parts = find_parts(nameclient, robot, model, owner)
                if parts and nameclient.query(rpc_name) is None:
                    return Grouping(parts, standard=True)
        except YarpError as exc:
            log.debug("%s: looking for the robot at %s: %s", owner, rpc_name, exc)
        now = time.monotonic()
        if now > deadline:
            raise NetworkError(f"no robot answered at {rpc_name} nor at "
                               f"/{robot}/<chain>/rpc:i within {timeout:g} s")
        if now - said > 5:
            log.info("%s: waiting for the robot (%s)%s", owner, rpc_name, answer)
            said = now
        time.sleep(0.3)


def find_parts(nameclient: NameClient, robot: str, model: RobotModel,
               owner: str) -> Dict[str, List[str]]:
    """A plain YARP robot: its control boards named after our chains, joints by name
    (``[get] [name] j``) or, when the names are not ours, by our order."""
    known = set(model.joint_names)
    parts: Dict[str, List[str]] = {}
    for chain in CHAINS:
        contact = nameclient.query(protocol.port_names(robot, chain)["rpc"])
        if contact is None:
            continue
        ours = [j.name for j in model.joints if j.chain == chain]
        axes = network.request(contact, [Vocab("get"), Vocab("axes")], timeout=5)
        if len(axes) < 3 or str(axes[-1]) != "ok" or not isinstance(axes[2], int):
            raise HalProtocolError(f"/{robot}/{chain}: [get] [axes] answered {axes}")
        names = []
        for axis in range(int(axes[2])):
            reply = network.request(contact, [Vocab("get"), Vocab("name"), axis], timeout=5)
            names.append(str(reply[2]) if len(reply) > 2 and str(reply[-1]) == "ok" else "")
        if all(name in known for name in names):
            parts[chain] = names
        elif len(names) == len(ours):
            log.info("%s: /%s/%s names its axes %s; taking them as %s", owner, robot, chain,
                     names, ours)
            parts[chain] = ours
        else:
            raise HalProtocolError(f"/{robot}/{chain} has {len(names)} axes {names}; "
                                   f"the model's {chain} has {len(ours)}: {ours}")
    return parts
