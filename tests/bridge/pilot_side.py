"""What the bridge tests' pilot does and checks: numbered commands, switches, bridge status.

Shared by ``test_bridge_processes`` (loopback) and ``test_emulated_network``
(emulated hosts): the witness module on the robot (:mod:`walkman.modules.witness`)
writes each command it executes to ``$COUNTER_LOG``; the pilot sends with
``pilot_sender.py`` and asks the bridges over their ``/bridge/<side>/rpc:i``.
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

from bridge_harness import HERE, Side, TwoPCs
from harness import Implementation, Proc, wait_until
from system.processes import WaitTimeout
from walkman.modules.witness import read_log


def executed(log: Path) -> List[int]:
    """The sequence numbers of the ``count`` commands the witness executed, in order."""
    return [e.seq for e in read_log(log) if e.name == "count"]


def send(pcs: TwoPCs, first: int, last: Optional[int], interval: float = 0.05) -> Proc:
    """``(count N) N`` for N in first..last to the module, insisting until each is accepted;
    ``last`` None: until the sender's stdin is closed (it then prints ``last N``)."""
    return pcs.pilot.python(str(HERE / "pilot_sender.py"), "/counter/command:i", str(first),
                            "-" if last is None else str(last), str(interval),
                            name=f"sender {first}-{'' if last is None else last}",
                            stdin=last is None)


GYM_PORTS = ("switch:i", "command:i", "status:o", "warning:o")


def shown(pcs: TwoPCs, lite: Implementation, module: str = "counter") -> bool:
    """Does the pilot's name server show each of the module's four ports (the bridge's
    stand-ins, open while the module runs on the robot)?"""
    return all(exists(pcs.pilot, lite, f"/{module}/{port}") for port in GYM_PORTS)


def wait_shown(pcs: TwoPCs, lite: Implementation, module: str = "counter") -> None:
    wait_until(lambda: shown(pcs, lite, module), 60,
               message=f"the robot's /{module} shown on the pilot's name server")


def switch(pcs: TwoPCs, lite: Implementation, word: str, seq: int) -> None:
    """``yarp write`` to the module's switch, once the pilot's name server shows the module."""
    wait_shown(pcs, lite)
    result = pcs.pilot.world.run_tool(lite, "write", f"/test/switch{seq}", "/counter/switch:i",
                                      input_text=f"{word} {seq}\n")
    assert result.returncode == 0, result.stdout + result.stderr


def bridge_status(side: Side, lite: Implementation) -> str:
    """The bridge's ``status`` reply as text, e.g. ``... (link up) ... (queued_commands 0)``."""
    return side.world.run_tool(lite, "rpc", f"/bridge/{side.name}/rpc:i",
                               input_text="status\n").stdout


def exists(side: Side, tool: Implementation, *names: str) -> bool:
    """``exists PORT`` (alive) or ``exists SOURCE TARGET`` (connected), on ``side``'s network."""
    return side.world.run_tool(tool, "exists", *names).returncode == 0


def wait_nothing_in_flight(pcs: TwoPCs, lite: Implementation, timeout: float = 30.0) -> None:
    """Until no command can arrive any more: none queued on the pilot, none undelivered on the robot.

    After this, what the module executed is final: a duplicate would have to
    come from one of these queues.
    """
    def settled() -> bool:
        return ("(queued_commands 0)" in bridge_status(pcs.pilot, lite)
                and "(undelivered 0)" in bridge_status(pcs.robot, lite))
    try:
        wait_until(settled, timeout, message="the bridges' queues to empty")
    except WaitTimeout as exc:
        raise WaitTimeout(f"{exc}\npilot: {bridge_status(pcs.pilot, lite)}\n"
                          f"robot: {bridge_status(pcs.robot, lite)}") from None
