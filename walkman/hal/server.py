"""``walkman-hal``: the robot driver ("EtherCAT master") remotized on YARP.

Theory of operation
-------------------
One thread steps the backend at 1 kHz of wall-clock time (on a loaded machine slower,
never in long bursts: ``MAX_LAG_S``; modules follow the robot's time).  Before each step
it applies the newest command each chain received; every ``period_ms`` it
snapshots the state of every chain; every 10 ms the F/T sensors and the IMU.  The steps
of one state period run back to back, one wake-up per period (at most 2 ms: the modules'
period): nothing between them is published, and a wake-up costs the machine as much
as a step (an idle HAL used 17 % of a core waking every 1 ms, 13 % every 2 ms).
Snapshots go to a single publisher thread that writes the ports, so a slow
reader can never stall the physics (streams are latest-only: a snapshot not
yet sent is replaced by a newer one).

Each chain is a YARP control board (``controlboardwrapper2``'s protocol,
:mod:`walkman.hal.controlboard`, device :mod:`walkman.hal.chain`):
``/<robot>/<chain>/rpc:i``, ``command:i``, ``state:o`` and ``stateExt:o``
(degrees, Stamp envelopes), plus ``stateSI:o`` (SI, with the state count and
board temperatures: what the bridge carries).  Each F/T sensor is an
``analogServer`` (``/<robot>/<ft>/analog:o`` and its ``/rpc:i``,
:mod:`walkman.hal.analog`), the IMU a ``ServerInertial``
(``/<robot>/inertial``).  ``/<robot>/rpc:i`` tells clients how joints are
grouped, so the grouping can change without touching a module.  Malformed
requests are refused with a log line naming the chain and the problem;
chains without commands hold their last reference.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import threading
import time
from collections import deque
from pathlib import Path
from typing import Deque, Dict, List, Optional, Tuple

import numpy as np

from walkman.hal import analog, controlboard, protocol
from walkman.hal import battery as battery_codec
from walkman.hal import robot_rpc as robot_words
from walkman.hal.arbitration import JointArbiter, owner_of
from walkman.hal.backend import Backend
from walkman.hal.battery import Battery, electric_power
from walkman.hal.chain import ChainBoard
from walkman.hal.clock_server import SimulationTime, StepGate, parse_rtf
from walkman.hal.clock_source import ClockSource
from walkman.hal.config import HalConfig, load_config
from walkman.hal.controlboard import ControlBoardError, JointData, Stamp
from walkman.hal.lockstep import DEFAULT_TIMEOUT, HEARTBEAT_S, LockstepGate
from walkman.hal.protocol import ChainState
from walkman.hal.robot_rpc import RobotWordError
from walkman.inifile import IniError
from walkman.model.mjcf import STATIONS
from walkman.realtime import (HAL_BACKGROUND_PRIORITY, HAL_PRIORITY, PATH_PRIORITY,
                               SWITCH_INTERVAL, make_process_realtime, make_realtime,
                               make_realtime_once)
from yarp_lite import time as yarp_time
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.contact import is_valid_port_name
from yarp_lite.buffered_port import BufferedPort
from yarp_lite.bursts import Burst
from yarp_lite.nameclient import NameClient
from yarp_lite.port import Port
from yarp_lite.rpc import RpcServer

log = logging.getLogger("walkman.hal")

SENSOR_PERIOD_S = protocol.SENSOR_PERIOD_S
WORLD_PERIOD_S = 1.0 / 30
BATTERY_STEP_S = 0.01        # the battery drains by the power of each 10 ms
BATTERY_PERIOD_S = 1.0       # batteryWrapper's default period
STATUS_PERIOD_S = 5.0
#: How far the physics may fall behind the wall clock and catch up by stepping back to back;
#: further behind, simulated time slips instead (an overrun).  Modules run on the robot's time
#: (walkman.hal.clock), so a slip only slows the world down, where a long burst of catch-up
#: steps would leave the controllers' commands far apart in simulated time.
MAX_LAG_S = 0.005
#: The longest run of physics steps back to back (s): the modules' 2 ms period.
MAX_BURST_S = 0.002
PUBLISHED_HISTORY = 2048  # state publications remembered for latency (2 s at 1 kHz)


def steps_per_wakeup(state_every: int, dt: float) -> int:
    """How many physics steps run back to back per wake-up of the physics thread: those of
    one state period (nothing between them is published), at most ``MAX_BURST_S`` of
    them (a command that arrives meanwhile waits for the next burst)."""
    return max(1, min(state_every, int(round(MAX_BURST_S / dt))))


class Publisher(threading.Thread):
    """Writes snapshots to ports; the physics thread never blocks on a socket."""

    def __init__(self, realtime: bool = False) -> None:
        super().__init__(daemon=True, name="hal publisher")
        self.realtime = realtime
        self.cond = threading.Condition()
        self.pending: Dict[int, Tuple[Port, Bottle, str]] = {}
        self.running = True
        self.sent = 0

    def publish(self, port: Port, bottle: Bottle, envelope: str = "") -> None:
        """Queue one message; it leaves at the next :meth:`flush` (one wake-up per tick)."""
        with self.cond:
            self.pending[id(port)] = (port, bottle, envelope)

    def flush(self) -> None:
        with self.cond:
            if self.pending:
                self.cond.notify()

    def run(self) -> None:
        if self.realtime:
            make_realtime(PATH_PRIORITY)
        while True:
            with self.cond:
                while not self.pending and self.running:
                    self.cond.wait(0.5)
                if not self.running:
                    return
                batch, self.pending = list(self.pending.values()), {}
            for port, bottle, envelope in batch:
                # A slow reader misses a state.  A module in lockstep reads on fast_tcp (no
                # acknowledgement to wait for): it gets the round the physics holds at, and if
                # not, the heartbeat brings it (walkman.hal.lockstep).
                port.write(bottle, envelope, skip_busy=True)
                self.sent += 1

    def stop(self) -> None:
        with self.cond:
            self.running = False
            self.cond.notify()


class HalServer:
    def __init__(self, backend: Backend, config: HalConfig,
                 nameclient: Optional[NameClient] = None, realtime: bool = True,
                 battery: Optional[Battery] = None, clock: Optional[str] = None,
                 rtf: Optional[float] = 1.0, paused: bool = False,
                 lockstep_timeout: float = DEFAULT_TIMEOUT) -> None:
        self.backend = backend
        self.battery = battery or Battery()
        self.battery_port: Optional[Port] = None
        self.battery_stamp = Stamp()
        self.config = config
        self.robot = config.robot
        self.nameclient = nameclient or NameClient()
        #: Simulated seconds per wall second the physics keeps to (None: as fast as it can);
        #: only with ``realtime`` (without it the physics never waits).
        self.rtf = rtf
        #: Keep pace with the wall clock, with real-time priority.  Not at ``--rtf max``: a
        #: SCHED_FIFO thread that never sleeps would starve every other program of its core.
        self.realtime = realtime and rtf is not None
        #: Pauses and counted steps (``/clock/rpc``); open unless a clock client pauses it.
        self.gate = StepGate()
        if paused:
            self.gate.pause()                     # as Gazebo's -u: until continueSimulation
        self.clock: Optional[ClockSource] = None
        #: The modules in lockstep (:mod:`walkman.hal.lockstep`); None without a clock.
        self.members: Optional[LockstepGate] = None
        if clock is not None:
            self.members = LockstepGate(lockstep_timeout)
            self.clock = ClockSource(clock, self.gate, SimulationTime(backend.dt),
                                     self.nameclient, self.members)
        self._harness: Optional[str] = None  # asked over rpc, applied by the physics thread
        self._station: Optional[str] = None  # likewise
        self.arbiter = JointArbiter(backend.joint_names, config.policy, config.priorities,
                                    config.release_after)
        self._arbiter_lock = threading.Lock()  # commands arrive on many port threads
        self.chains: Dict[str, ChainBoard] = {
            name: ChainBoard(name, joints, backend, self._arbitrate, self._on_command_seq,
                             lambda owner, text: self._warn(text, owner, "", "wrong mode"),
                             on_halted=lambda owner, text: self._warn(text, owner, "pilot",
                                                                      "halted"))
            for name, joints in config.chains.items()}
        self._malformed: Dict[str, Burst] = {name: Burst() for name in self.chains}
        self._rpc_refusals: Dict[str, Burst] = {}
        self.chain_ports: Dict[str, Dict[str, Port]] = {name: {} for name in self.chains}
        self.rpc_stamps: Dict[str, Stamp] = {name: Stamp() for name in self.chains}
        self.state_stamp = Stamp()
        self.sensor_stamp = Stamp()
        self.ports: List[Port] = []
        self.warning_port: Optional[Port] = None
        self._warning_seq = 1
        self.publisher = Publisher(self.realtime)
        #: The last round's and sensors' messages, port by port: what a held or paused robot
        #: repeats (:meth:`_heartbeat`).
        self._last_out: Dict[int, Tuple[Port, Bottle, str]] = {}
        self.running = False
        # When each state seq went out, as a ring indexed by seq (written by the loop,
        # read by command readers without a lock: one float store, no iteration).
        self.published_at = np.zeros(PUBLISHED_HISTORY)
        #: every port a state goes out on (set by :meth:`open`)
        self._state_ports: List[Port] = []
        self.latencies: Deque[float] = deque(maxlen=5000)
        self.overruns = 0
        self.max_step_s = 0.0
        self.started_at = 0.0
        self.steps = 0
        self.ft_ports: Dict[str, Port] = {}
        self.ft_offsets: Dict[str, analog.AnalogOffsets] = {}  # tare, set on <ft>/analog:o/rpc:i
        self.imu_port: Optional[Port] = None
        self.world_port: Optional[Port] = None
        self.whole_state_port: Optional[Port] = None
        #: The backend's joint indices in the order of ``[get] chains`` (the whole state's).
        self.whole_indices = [i for chain in self.chains.values() for i in chain.indices]
        self.whole_joints = [j for chain in self.chains.values() for j in chain.joints]

    # -- ports -----------------------------------------------------------------------

    def open(self, wait: float = math.inf) -> None:
        # Before /<robot>/rpc:i: a client that finds the HAL there looks for this port at once.
        self.whole_state_port = Port(nameclient=self.nameclient).open(
            protocol.whole_state_port_name(self.robot), wait=wait)
        self.ports.append(self.whole_state_port)
        robot_rpc = RpcServer(nameclient=self.nameclient,
                              handler=lambda request: robot_words.answer(request, self))
        robot_rpc.open(protocol.robot_rpc_name(self.robot), wait=wait)
        self.ports.append(robot_rpc)
        # Sent by a thread of its own, in order: the arbiter warns from the thread that
        # takes a module's commands, which must never wait on a module slow to read.
        self.warning_port = self._open(BufferedPort(nameclient=self.nameclient, strict=True),
                                       protocol.hal_warning_port_name(self.robot))
        for chain in self.chains.values():
            names = protocol.port_names(self.robot, chain.name)
            ports = self.chain_ports[chain.name]
            for key in ("state", "state_ext", "state_si"):
                ports[key] = self._open(Port(nameclient=self.nameclient), names[key])
            ports["command"] = self._open(
                Port(nameclient=self.nameclient, reader_wants_source=True,
                     reader=lambda bottle, source, chain=chain: self._on_command(chain, bottle,
                                                                                 source)),
                names["command"])
            ports["rpc"] = self._open(
                RpcServer(nameclient=self.nameclient, reader_wants_source=True,
                          handler=lambda bottle, source, chain=chain: self._chain_rpc(
                              chain, bottle, source)),
                names["rpc"])
        for sensor in self.backend.ft_sensors:
            name = protocol.ft_port_name(self.robot, sensor)
            self.ft_ports[sensor] = self._open(Port(nameclient=self.nameclient), name)
            self.ft_offsets[sensor] = analog.AnalogOffsets(6)
            self._open(RpcServer(nameclient=self.nameclient, handler=lambda request, sensor=sensor:
                                 analog.respond(request, self.ft_offsets[sensor],
                                                lambda: self.backend.ft(sensor),
                                                lambda text: log.info("%s rpc: %s", sensor, text))),
                       analog.rpc_name(name))
        self.imu_port = self._open(Port(nameclient=self.nameclient),
                                   protocol.imu_port_name(self.robot))
        self.battery_port = self._open(Port(nameclient=self.nameclient),
                                       protocol.battery_port_name(self.robot))
        self._open(RpcServer(nameclient=self.nameclient, handler=self._battery_rpc),
                   protocol.battery_rpc_name(self.robot))
        if getattr(self.backend, "plant", None) is not None:
            self.world_port = self._open(Port(nameclient=self.nameclient),
                                         protocol.world_port_name(self.robot))
        self._state_ports = [self.whole_state_port, *(
            ports[key] for ports in self.chain_ports.values()
            for key in ("state", "state_ext", "state_si"))]
        if self.clock is not None:
            self.clock.open()
        log.info("HAL for %s: %d chains (%s), %s backend, state every %g ms", self.robot,
                 len(self.chains), ", ".join(self.chains), type(self.backend).__name__,
                 self.config.period_ms)

    def _open(self, port: Port, name: str) -> Port:
        port.open(name)
        self.ports.append(port)
        return port

    def close(self) -> None:
        self.running = False
        self.gate.close()
        if self.clock is not None:
            self.clock.close()
        self.publisher.stop()
        # /<robot>/rpc:i after the chains (only the whole state goes later): a client that
        # finds chains without it takes us for a plain YARP robot (see walkman.hal.robot).
        for port in reversed(self.ports):
            port.close()
        self.backend.close()

    # -- incoming ----------------------------------------------------------------------

    def _on_command(self, chain: ChainBoard, bottle: Bottle, source: str = "") -> None:
        """A streaming command (``command:i``): refused with a log line when malformed."""
        if self.realtime:
            make_realtime_once(PATH_PRIORITY)
        try:
            command = controlboard.decode_stream(bottle, chain.axes())
            owner = owner_of(source) if source else "?"
            chain.command(command.what, command.joints, command.values, owner, command.seq)
            if self.members is not None:
                self.members.commanded(owner, chain.name, command.seq)
        except ControlBoardError as exc:
            burst = self._malformed[chain.name]
            if burst.record():
                log.warning("%s: refused command from %s (#%d of this burst): %s", chain.name,
                            source or "?", burst.count, exc)

    def _on_command_seq(self, seq: int) -> None:
        """Sense->move latency: a command names the state publication it answers."""
        now = time.perf_counter()
        if 0 <= self.state_stamp.count - seq < PUBLISHED_HISTORY:
            self.latencies.append(now - self.published_at[seq % PUBLISHED_HISTORY])

    def _arbitrate(self, owner: str, joints: List[int]) -> set:
        """The joints ``owner`` may command (see :mod:`walkman.hal.arbitration`)."""
        with self._arbiter_lock:
            decision = self.arbiter.filter(owner, joints, time.monotonic())
        for conflict in decision.conflicts:
            log.warning("%s", conflict.text())
            self._warn(conflict.text(), conflict.owner, conflict.holder, conflict.action)
        return set(decision.allowed)

    def _warn(self, text: str, owner: str, holder: str, action: str) -> None:
        """``/<robot>/warning:o``: ``seq text owner holder action`` (the owner's module
        repeats it to its pilot; ``wrong mode`` also makes it switch its joints back)."""
        if self.warning_port is not None:
            with self._arbiter_lock:
                self._warning_seq += 1
                seq = self._warning_seq
            self.warning_port.write(Bottle([seq, text, owner, holder, action]))

    def _chain_rpc(self, chain: ChainBoard, request: Bottle, source: str = "") -> Bottle:
        """``rpc:i``: YARP's control-board requests (:func:`controlboard.respond`)."""
        try:
            return controlboard.respond(chain, request, self.rpc_stamps[chain.name], time.time(),
                                        owner_of(source) if source else "?",
                                        lambda text: self._rpc_refused(chain.name, source, text))
        except Exception:  # our bug, not the peer's: say so, and answer as YARP fails
            log.exception("%s rpc from %s: %s failed", chain.name, source or "?",
                          request.to_text()[:120])
            return Bottle([Vocab("fail")])

    def _rpc_refused(self, chain: str, source: str, text: str) -> None:
        """A refused rpc request, logged once per burst per client."""
        burst = self._rpc_refusals.setdefault(f"{chain} {source}", Burst())
        if burst.record():
            log.info("%s rpc from %s (#%d of this burst): %s", chain, source or "?",
                     burst.count, text)

    # -- the robot-wide words (walkman.hal.robot_rpc.Operations) -----------------------

    def chain_joints(self) -> Dict[str, List[str]]:
        return {name: list(chain.joints) for name, chain in self.chains.items()}

    def halt(self, on: bool) -> None:
        for chain in self.chains.values():
            chain.halt(on)
        log.warning("HAL: %s by the pilot's stop-all", "every joint held" if on else
                    "released: commands apply again")

    def halted(self) -> bool:
        return any(chain.halted for chain in self.chains.values())

    def _plant(self, what: str):
        plant = getattr(self.backend, "plant", None)
        if plant is None:
            raise RobotWordError(f"this backend has no {what} (simulation only)")
        return plant

    def set_harness(self, mode: str) -> None:
        self._plant("harness")
        self._harness = mode  # the physics thread applies it before its next step

    def go_to_station(self, name: str) -> None:
        """The simulated robot goes to a task's station (between the DRC's tasks the real
        one walked or drove; here one session can do them all)."""
        held = self._plant("stations").grasped()
        if held:
            raise RobotWordError(f"a hand holds {', '.join(held)}: let go first (the part "
                                 f"would go with the robot)")
        self._station = name  # the physics thread moves the robot before its next step

    def push(self, impulse: List[float], seconds: Optional[float]) -> None:
        """A simulated push on the torso (N*s, world): two attribute writes the physics
        thread reads at its next step."""
        push = getattr(self.backend, "push", None)
        if push is None:
            raise RobotWordError("this backend cannot be pushed (simulation only)")
        push(impulse, *([] if seconds is None else [seconds]))

    # -- the loop ----------------------------------------------------------------------------

    def _apply_commands(self) -> None:
        harness, self._harness = self._harness, None
        if harness is not None:
            self.backend.plant.set_harness(harness)
        station, self._station = self._station, None
        if station is not None:
            self.backend.place(station)
            self.backend.plant.set_harness(self.backend.plant.harness_mode)
            for chain in self.chains.values():
                chain.resync()
            log.info("HAL: the robot is at station %s (simulation)", station)
        for chain in self.chains.values():
            chain.step(self.backend.dt)

    def _stamp_time(self) -> float:
        """The time in a stream's envelope: the simulated time on a clock, as Gazebo's
        devices stamp theirs, else the wall clock's, as YARP's wrapper stamps."""
        return self.backend.time if self.clock is not None else time.time()

    def _send(self, port: Port, bottle: Bottle, envelope: str = "") -> None:
        self.publisher.publish(port, bottle, envelope)
        if self.clock is not None:
            self._last_out[id(port)] = (port, bottle, envelope)

    def _heartbeat(self) -> None:
        """While paused or held: the last round and sensors again, as they were (same count,
        same time), so that no client takes the robot for a dead one."""
        for port, bottle, envelope in list(self._last_out.values()):
            if port.has_outputs:
                self.publisher.publish(port, bottle, envelope)
        self.publisher.flush()

    def _publish_state(self, every_port: bool = False) -> None:
        """Every chain's state, as YARP's wrapper streams it and in SI for the bridge;
        ``every_port``: also where nobody reads yet (the first, which a robot started paused
        repeats to the clients that connect meanwhile)."""
        backend = self.backend
        envelope = self.state_stamp.update(self._stamp_time()).envelope()
        seq = self.state_stamp.count
        self.published_at[seq % PUBLISHED_HISTORY] = time.perf_counter()
        if not every_port and not any(port.has_outputs for port in self._state_ports):
            return      # nobody reads a state: none is made (an idle HAL's every other tick)
        q, qdot, tau = backend.positions(), backend.velocities(), backend.torques()
        temperature = backend.temperatures()
        if self.whole_state_port is not None and \
                (every_port or self.whole_state_port.has_outputs):
            every = self.whole_indices
            self._send(self.whole_state_port, protocol.encode_whole_state(ChainState(
                seq, backend.time, q[every].tolist(), qdot[every].tolist(), tau[every].tolist(),
                temperature[every].tolist()), self.whole_joints))
        for chain in self.chains.values():
            idx, ports = chain.indices, self.chain_ports[chain.name]
            if every_port or ports["state_si"].has_outputs:
                state = ChainState(seq, backend.time, q[idx].tolist(), qdot[idx].tolist(),
                                   tau[idx].tolist(), temperature[idx].tolist())
                self._send(ports["state_si"], protocol.encode_state_si(state))
            q_deg = np.degrees(q[idx])
            if every_port or ports["state_ext"].has_outputs:
                data = JointData(tuple(q_deg.tolist()), tuple(np.degrees(qdot[idx]).tolist()),
                                 None, tuple(tau[idx].tolist()),
                                 tuple(chain.control_modes()),
                                 tuple(chain.interaction_modes()))
                self._send(ports["state_ext"], controlboard.encode_joint_data(data, len(idx)),
                           envelope)
            if every_port or ports["state"].has_outputs:
                self._send(ports["state"], Bottle(q_deg.tolist()), envelope)

    def _publish_sensors(self, every_port: bool = False) -> None:
        envelope = self.sensor_stamp.update(self._stamp_time()).envelope()
        for sensor, port in self.ft_ports.items():
            if every_port or port.has_outputs:
                wrench = self.ft_offsets[sensor].apply(self.backend.ft(sensor))
                self._send(port, protocol.encode_ft(wrench), envelope)
        if self.imu_port is not None and (every_port or self.imu_port.has_outputs):
            imu = self.backend.imu()
            self._send(self.imu_port, protocol.encode_inertial(
                imu.rpy, imu.acceleration, imu.gyro), envelope)

    def _drain_battery(self, dt: float) -> None:
        """The motors draw by their torques and velocities, the computers always."""
        self.battery.step(electric_power(self.backend.torques(), self.backend.velocities()), dt)

    def _publish_battery(self) -> None:
        """``batteryWrapper``'s stream once a second; a level crossed is a warning."""
        for text in self.battery.warnings():
            log.warning("HAL: %s", text)
            self._warn(text, "", "", "battery")
        if self.battery_port is not None and self.battery_port.has_outputs:
            envelope = self.battery_stamp.update(time.time()).envelope()
            self.publisher.publish(self.battery_port,
                                   battery_codec.encode_reading(self.battery.reading()), envelope)

    def _battery_rpc(self, request: Bottle) -> Bottle:
        """``[ibat] [btnf]`` -> ``[is] [btnf] "info"``, as ``batteryWrapper`` answers."""
        if len(request) >= 2 and request[0] == Vocab("ibat") and request[1] == Vocab("btnf"):
            reading = self.battery.reading()
            return Bottle([Vocab("is"), Vocab("btnf"),
                           f"simulated {battery_codec.CAPACITY_WH:g} Wh pack, "
                           f"{reading.charge:.1f} %, {reading.voltage:.1f} V"])
        return Bottle([Vocab("fail")])

    def _publish_world(self) -> None:
        if self.world_port is not None and self.world_port.has_outputs:
            plant = self.backend.plant
            self.publisher.publish(self.world_port,
                                   protocol.encode_world(self.backend.time, plant.d.qpos))

    def run(self, duration: Optional[float] = None) -> None:
        backend = self.backend
        if self.realtime and make_realtime(HAL_PRIORITY):
            log.info("physics loop runs with real-time priority (SCHED_FIFO %d)", HAL_PRIORITY)
        self.publisher.start()
        self.running = True
        state_every = max(1, round(self.config.period_ms / 1000.0 / backend.dt))
        burst = steps_per_wakeup(state_every, backend.dt)
        sensor_every = max(1, round(SENSOR_PERIOD_S / backend.dt))
        world_every = max(1, round(WORLD_PERIOD_S / backend.dt))
        battery_every = max(1, round(BATTERY_STEP_S / backend.dt))
        battery_out_every = max(1, round(BATTERY_PERIOD_S / backend.dt))
        self.started_at = time.perf_counter()
        deadline = self.started_at
        next_status = self.started_at + STATUS_PERIOD_S
        paced = self.realtime and self.rtf is not None
        step_wall = backend.dt / self.rtf if self.rtf else 0.0   # wall seconds per step
        if self.clock is not None:   # the first round and sensors, repeated while paused
            self._publish_state(every_port=True)
            self._publish_sensors(every_port=True)
            self.publisher.flush()
        next_beat = self.started_at
        still_running = lambda: self.running  # noqa: E731
        while self.running:
            if not self.gate.may_step():          # paused by /clock/rpc (or from the start)
                deadline = time.perf_counter()    # resumed later: no burst to catch up
                if deadline > next_beat:
                    self._heartbeat()
                    next_beat = deadline + HEARTBEAT_S
                if deadline > next_status:
                    self._log_status()
                    next_status = deadline + STATUS_PERIOD_S
                continue
            begin = time.perf_counter()
            self._apply_commands()
            backend.step()
            self.steps += 1
            self.gate.stepped()
            if self.steps % state_every == 0:
                self._publish_state()
            if self.steps % sensor_every == 0:
                self._publish_sensors()
            if self.steps % world_every == 0:
                self._publish_world()
            if self.steps % battery_every == 0:
                self._drain_battery(battery_every * backend.dt)
            if self.steps % battery_out_every == 0:
                self._publish_battery()
            self.publisher.flush()
            if self.members is not None and self.steps % state_every == 0:
                self.members.hold(backend.time, still_running, self._heartbeat)
            # After the hold: a follower's time, and stepSimulationAndWait's return, come
            # once the modules in lockstep have handled the round.
            if self.clock is not None and (self.steps % burst == 0 or self.gate.paused):
                self.clock.post(self.gate.taken)  # each wake-up's time; each counted step's
            for event in getattr(backend, "events", []):
                log.info("%s", event)
            if getattr(backend, "events", None):
                backend.events.clear()
            self.max_step_s = max(self.max_step_s, time.perf_counter() - begin)
            if duration is not None and backend.time >= duration:
                break
            if begin > next_status:
                self._log_status()
                next_status = begin + STATUS_PERIOD_S
            if paced and not self.gate.paused:    # counted steps run as fast as they can
                deadline += step_wall
                if self.steps % burst:
                    continue        # the period's next step, back to back
                delay = deadline + (burst - 1) * step_wall - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                elif delay < -MAX_LAG_S:
                    self.overruns += 1
                    deadline = time.perf_counter()  # fell behind: do not try to catch up

    def stats(self) -> Dict[str, float]:
        wall = max(time.perf_counter() - self.started_at, 1e-9)
        latencies = sorted(self.latencies)
        stats = {"sim_time": round(self.backend.time, 3),
                 "real_time_factor": round(self.backend.time / wall, 3),
                 "overruns": self.overruns, "max_step_ms": round(self.max_step_s * 1e3, 3),
                 "messages_sent": self.publisher.sent}
        if self.clock is not None and self.members is not None:
            stats["simulated_time"] = round(self.clock.server.now(), 6)
            stats["paused"] = self.gate.held
            stats["lockstep_members"] = len(self.members.members)
            stats["lockstep_held_s"] = round(self.members.held_s, 3)
            stats["lockstep_timeouts"] = self.members.dropped
        if latencies:
            stats["sense_to_move_median_ms"] = round(latencies[len(latencies) // 2] * 1e3, 3)
            stats["sense_to_move_p99_ms"] = round(latencies[int(len(latencies) * 0.99)] * 1e3, 3)
        return stats

    def _log_status(self) -> None:
        stats = self.stats()
        extra = self.backend.status()
        commands = sum(chain.commands for chain in self.chains.values())
        log.info("t=%.1fs real-time factor %.2f, %d commands, %d messages out, "
                 "max step %.2f ms, overruns %d %s", stats["sim_time"],
                 stats["real_time_factor"], commands, stats["messages_sent"],
                 stats["max_step_ms"], stats["overruns"],
                 {k: v for k, v in extra.items() if k not in ("time",)})


def make_backend(name: str, scene: bool, harness: str, thermal_speedup: float,
                 station: str = "valve") -> Backend:
    if name == "sim":
        from walkman.hal.sim import SimBackend

        return SimBackend(scene=scene, harness=harness, thermal_speedup=thermal_speedup,
                          station=station)
    if name == "ethercat":
        from walkman.hal.ethercat.master import EthercatBackend

        return EthercatBackend(scene=scene, harness=harness, thermal_speedup=thermal_speedup,
                               station=station)
    raise ValueError(f"unknown backend {name!r}: choose sim or ethercat")


def _rtf_argument(text: str) -> Optional[float]:
    try:
        return parse_rtf(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _seconds_argument(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not 0.01 <= value <= 3600:
        raise argparse.ArgumentTypeError(f"{text!r}: between 0.01 and 3600 s")
    return value


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="walkman-hal", description=__doc__.split("\n\n")[0])
    parser.add_argument("--backend", choices=["sim", "ethercat"], default="sim",
                        help="sim: MuJoCo with compliant servos; ethercat: emulated boards")
    parser.add_argument("--config", type=Path, help="chain grouping (models/hal_*.ini)")
    parser.add_argument("--scene", choices=["drc", "robot"], default="drc",
                        help="drc: with valve, car and door; robot: the robot alone")
    parser.add_argument("--harness", choices=["locked", "trolley", "off"], default="locked",
                        help="the scene's support harness: locked (hang still, default), "
                             "trolley (brake off: the robot walks, the harness keeps it up), off")
    parser.add_argument("--no-harness", action="store_const", const="off", dest="harness",
                        help="same as --harness off")
    parser.add_argument("--station", choices=sorted(STATIONS), default="valve",
                        help="where the robot starts in the drc scene (default: at the valve)")
    parser.add_argument("--thermal-speedup", type=float, default=1.0,
                        help="heat the motors faster than real time (demos, tests)")
    parser.add_argument("--battery", type=float, default=100.0, metavar="PERCENT",
                        help="the battery's charge at start (default 100)")
    parser.add_argument("--battery-speedup", type=float, default=1.0,
                        help="drain the battery faster than real time (demos, tests)")
    parser.add_argument("--duration", type=float, help="stop after this much simulated time")
    parser.add_argument("--clock", nargs="?", const=yarp_time.DEFAULT_SOURCE, metavar="NAME",
                        help="publish simulated time on the YARP port NAME (default /clock) "
                             "and serve NAME/rpc (ClockServer: pause, step, continue), as "
                             "gazebo_yarp_clock; programs started with YARP_CLOCK=NAME follow")
    parser.add_argument("--rtf", type=_rtf_argument, default=1.0, metavar="X|max",
                        help="keep simulated time at X times real time (default 1), or 'max': "
                             "as fast as the machine allows")
    parser.add_argument("--paused", action="store_true",
                        help="start paused, as gazebo -u (needs --clock): the physics waits "
                             "for NAME/rpc's continueSimulation or stepSimulation")
    parser.add_argument("--lockstep-timeout", type=_seconds_argument, default=DEFAULT_TIMEOUT,
                        metavar="S", help="a module in lockstep that has not handled its round "
                        f"after S wall seconds leaves the barrier (default {DEFAULT_TIMEOUT:g})")
    parser.add_argument("--verbose", action="store_true")
    options = parser.parse_args(argv)
    if options.paused and options.clock is None:
        parser.error("--paused needs --clock: without NAME/rpc nothing could continue it")
    if options.clock is not None and not is_valid_port_name(options.clock):
        parser.error(f"--clock {options.clock!r}: a YARP port name starts with '/', has no "
                     f"space and does not end with '/'")
    # The clock's source follows no clock but its own physics, even with YARP_CLOCK set for
    # the programs it serves (gazebo_yarp_clock does the same).
    yarp_time.use_system_clock()

    if options.rtf is not None:
        sys.setswitchinterval(SWITCH_INTERVAL)  # keep the physics thread on time
        make_process_realtime(HAL_BACKGROUND_PRIORITY)  # ... and its other threads off its lock
    logging.basicConfig(level=logging.DEBUG if options.verbose else logging.INFO,
                        format="[%(levelname)s] %(message)s", stream=sys.stderr)
    try:
        config = load_config(options.config)
    except (IniError, OSError, ValueError) as exc:   # the user's file; a bug shows its trace
        log.error("%s", exc)
        return 2
    try:
        battery = Battery(options.battery, options.battery_speedup)
    except ValueError as exc:
        parser.error(str(exc))
    backend = make_backend(options.backend, options.scene == "drc", options.harness,
                           options.thermal_speedup, options.station)
    server = HalServer(backend, config, battery=battery, clock=options.clock, rtf=options.rtf,
                       paused=options.paused, lockstep_timeout=options.lockstep_timeout)
    # Ctrl-C too, explicitly: a program started in the background of a script inherits SIGINT
    # ignored, and Python then never raises KeyboardInterrupt.
    for stop in (signal.SIGTERM, signal.SIGINT):
        signal.signal(stop, lambda *_: setattr(server, "running", False))
    try:
        server.open()
        server.run(options.duration)
    except KeyboardInterrupt:
        pass  # Ctrl-C ends the HAL; finally reports and closes
    finally:
        log.info("HAL stopping: %s", server.stats())
        server.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
