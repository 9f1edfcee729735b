"""A rogue host on the DRC radio attacks the robot's bridge while the pilot works.  Needs root.

The issue's "done when": a third network namespace on the same emulated link
(an attacker on the DRC wireless) connects to the TCP port, sends forged
commands and replays captured frames and datagrams; the robot executes none
of it and the real pilot keeps working throughout.

The rogue (``rogue.py``) first sniffs the radio while the bridges connect and
the pilot commands, then attacks in two phases.  Phase one must not disturb the
pilot at all: TCP from its own address (a forged handshake, garbage, the
captured stream replayed), the same from the pilot's host (a rogue process
there, past the address check), and UDP from its own address and with the
pilot's address spoofed (forged commands, tampered and replayed datagrams).
Phase two injects a captured command frame into the live connection with the
pilot's address and sequence numbers: no protocol over TCP can resynchronise a
stream after that, so the robot drops the connection, and the pilot reconnects
and goes on with nothing lost and nothing twice.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Dict, List

import pytest

from netem.emulation import EmulatedLink
from bridge.status import from_bottle
from bridge_harness import HERE, PYTHON, Side, TwoPCs
from harness import Implementation, Proc, dump_outputs_if_failed, wait_until
from pilot_side import bridge_status, send, switch, wait_nothing_in_flight
from walkman.modules.witness import read_log
from yarp_lite.bottle_text import parse

pytestmark = pytest.mark.requires("root")

CONFIG = """<bridge period="0.5" gather="0.4">
  <modules>
    <module name="counter" id="3"/>
  </modules>
  <custom_modules>
    <module name="joystick" id="9">
      <connection port_to_open="/axes:i" source_port="/axes:o" target_port="/axes:i"
                  location="pilot" direction="pilot_to_robot" channel="udp" streaming="true"/>
    </module>
  </custom_modules>
</bridge>
"""
STRANGER_DATAGRAMS, FORGED_DATAGRAMS, REPLAYED_DATAGRAMS = 5, 10, 20
ATTACKED = ("stranger", "unauthenticated", "forged", "replayed", "malformed")


@pytest.fixture
def link():
    emulated = EmulatedLink(f"wr{os.getpid() % 100000}", 30)
    try:
        emulated.up()
        emulated.add_intruder()
        emulated.apply("drc")
        yield emulated
    finally:
        emulated.down()


@pytest.fixture
def pcs(tmp_path, lite, link, monkeypatch, request):
    config = tmp_path / "bridge.xml"
    config.write_text(CONFIG)
    monkeypatch.setenv("COUNTER_LOG", str(tmp_path / "executed.log"))
    two = TwoPCs(tmp_path, lite, config, link=link)
    two.log = tmp_path / "executed.log"
    yield two
    dump_outputs_if_failed(request, two.robot.world.processes + two.pilot.world.processes)
    two.close()


@pytest.fixture
def rogue(pcs, link, tmp_path, request):
    """Start ``rogue.py VERB`` on a host of the link (the rogue's, or the pilot's)."""
    started: List[Proc] = []

    def start(verb: str, *extra: str, host: str = "rogue") -> Proc:
        argv = [PYTHON, str(HERE / "rogue.py"), verb, str(tmp_path / "capture.json"),
                "--robot", link.address("robot"), "--pilot", link.address("pilot"),
                "--tcp-port", str(pcs.tcp_port), "--udp-port", str(pcs.udp_ports["robot"]),
                *extra]
        proc = Proc(link.exec_argv(host, argv), dict(os.environ), f"rogue {verb} on {host}")
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.kill()
        print(f"\n----- {proc.name} -----\n{proc.output()}")  # what it did, pass or fail


def status(side: Side, lite: Implementation) -> Dict:
    """The bridge's status as a dict (``rpc status`` answers ``Response: <bottle>``)."""
    text = bridge_status(side, lite)
    reply = next(line for line in text.splitlines() if line.startswith("Response: "))
    return from_bottle(parse(reply[len("Response: "):]))


def attacked(side: Side, lite: Implementation) -> Dict[str, int]:
    """What the bridge dropped for the reasons an attack can cause."""
    dropped = status(side, lite)["dropped"]
    return {reason: int(dropped.get(reason, 0)) for reason in ATTACKED}


def run(proc: Proc, timeout: float = 30.0) -> None:
    assert proc.wait(timeout) == 0, proc.output()


def executed_lines(log: Path) -> List[str]:
    """Everything the module executed, rogue or not: ``name seq`` each."""
    return [f"{e.name} {e.seq}" for e in read_log(log)]


def test_a_rogue_on_the_radio_gets_nothing_executed(pcs: TwoPCs, lite, link: EmulatedLink,
                                                    rogue: Callable[..., Proc]) -> None:
    capture = rogue("capture", "--device", link.device("rogue"), "--timeout", "180",
                    "--datagrams", str(REPLAYED_DATAGRAMS))
    capture.wait_for("^sniffing on", 30)  # before the bridges connect: it hears the handshake
    pcs.start_name_servers()
    pcs.robot.start([PYTHON, "-m", "walkman.gym.supervisor", "witness",
                     "--name", "/counter"], "counter module").wait_for("ready for the pilot", 60)
    pcs.start_bridge(pcs.robot)
    pcs.start_bridge(pcs.pilot)
    pcs.wait_linked(60)
    # The pilot's joystick: a stream over UDP, pilot to robot, for the rogue to capture.
    pcs.pilot.python(str(HERE / "pilot_sender.py"), "/joystick/axes:i", "1000000", "9999999",
                     "0.05", name="joystick")
    switch(pcs, lite, "start", 2)
    sender = send(pcs, 1, None, interval=0.1)   # until told: through every phase
    run(capture, 60)

    def progress() -> int:
        return len(executed_lines(pcs.log))

    # Phase one: nothing the rogue does may disturb the pilot's connection.
    before, executed_before = attacked(pcs.robot, lite), progress()
    connects = {side.name: status(side, lite)["tcp"]["connects"] for side in pcs.sides.values()}
    run(rogue("tcp"))
    run(rogue("udp", "--stranger", str(STRANGER_DATAGRAMS), "--forged", str(FORGED_DATAGRAMS),
              "--replays", str(REPLAYED_DATAGRAMS)))
    run(rogue("tcp", host="pilot"))
    executed_during = progress()
    assert sender.popen.poll() is None, "the pilot stopped commanding before the attack ended"
    expected = {
        "stranger": 3 + STRANGER_DATAGRAMS,  # every connection and datagram from the rogue's address
        "unauthenticated": 2,                # forged and replayed handshakes from the pilot's host
        "malformed": 1,                      # garbage from the pilot's host
        "forged": FORGED_DATAGRAMS,          # forged commands and tampered datagrams as the pilot
        "replayed": REPLAYED_DATAGRAMS,      # captured datagrams sent again as the pilot
    }

    def counted() -> Dict[str, int]:
        now = attacked(pcs.robot, lite)
        return {reason: now[reason] - before[reason] for reason in ATTACKED}

    try:
        wait_until(lambda: counted() == expected, 15, message="the robot counting each attack")
    except AssertionError:
        raise AssertionError(f"the robot counted {counted()}, expected {expected}") from None
    print(f"\nthe robot bridge counted in phase one: {expected}")
    for side in pcs.sides.values():
        now = status(side, lite)
        assert (now["link"], now["tcp"]["connects"]) == ("up", connects[side.name]), \
            f"the {side.name} bridge's link was disturbed: {now['link']}, " \
            f"{now['tcp']['connects']} connects"
    assert executed_during > executed_before, "no pilot command arrived during the attack"

    # Phase two: a captured command frame injected into the live stream.  The robot refuses it
    # and drops the connection; the pilot reconnects and goes on commanding.  Landing on a
    # frame boundary, the frame fails its tag (forged).  If the pilot's own next segment
    # reached the robot first at that sequence number (the rogue, beside CPU burners, sent
    # late: fc98), the robot's TCP keeps only the injected bytes past it, which misframe the
    # stream (malformed).  Either way one refusal, and nothing of it executed.
    refusals_before = attacked(pcs.robot, lite)
    run(rogue("inject", "--device", link.device("rogue")))  # exits 0 once the robot hung up

    def reconnected() -> bool:
        now = status(pcs.robot, lite)
        return (now["link"], now["tcp"]["connects"]) == ("up", connects["robot"] + 1)

    wait_until(reconnected, 30, message="the pilot reconnecting after the injection")
    refusals = attacked(pcs.robot, lite)
    grown = {reason: refusals[reason] - refusals_before[reason] for reason in ATTACKED}
    assert grown in ({**dict.fromkeys(ATTACKED, 0), "forged": 1},
                     {**dict.fromkeys(ATTACKED, 0), "malformed": 1}), grown
    resumed = progress()
    wait_until(lambda: progress() > resumed, 30, message="the pilot's commands after reconnecting")
    assert sender.popen.poll() is None, "the pilot stopped commanding before phase two ended"

    sender.close_stdin()                         # the attacks are over: the pilot stops
    assert sender.wait(120) == 0, sender.output()
    last = int(sender.wait_for(r"^last (\d+)", 10).group(1))
    assert last > executed_during, sender.output()
    wait_nothing_in_flight(pcs, lite)
    assert executed_lines(pcs.log) == [f"count {n}" for n in range(1, last + 1)]
    final = status(pcs.robot, lite)
    assert (final["internal_errors"], final["tcp"]["internal_errors"],
            final["udp"]["internal_errors"]) == (0, 0, 0), "the attack hit a bug in the bridge"
    print(f"\nthe robot bridge dropped, in all: {final['dropped']}")
