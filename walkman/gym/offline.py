"""GYM modules against the simulator in one process, on simulated time.

Theory of operation
-------------------
The same module classes that ``walkman-module`` runs, without YARP, the HAL
server or wall-clock time: an :class:`OfflineWorld` owns a simulator backend
and steps it 1 ms at a time; every module's ``run()`` is called each
``thread_period`` of *simulated* time (the module reads it through its
``now()``), and its ``move()`` goes through the same joint arbitration as the
HAL's.  Runs are deterministic and faster than real time, which makes this
the place to develop a task, and the benchmark's way to measure task times
in simulated seconds.  A switch does here what it does under the runner:
both drive the same :class:`~walkman.gym.transitions.Lifecycle` (hooks, status
words, the hold on stop), this file only runs the hooks in place and steps the
world while a module goes on to its safe pause.  It is not a substitute for
the process tests: those run the HAL and the modules as programs over YARP.
"""

from __future__ import annotations

from typing import Callable, Dict, List, Optional, Sequence, Type

import numpy as np

from walkman.control.kinematics import Kinematics
from walkman.gym.interfaces import RecordingInterfaces
from walkman.gym.lifecycle import State
from walkman.gym.thread import ControlThread
from walkman.gym.transitions import Lifecycle, Outcome
from walkman.hal.arbitration import JointArbiter
from walkman.hal.backend import Backend
from walkman.hal.robot import WholeBody, check_reference
from yarp_lite.bottle_text import parse


class SimulatedRobot(WholeBody):
    """The whole-body interface (:class:`walkman.hal.robot.WholeBody`), straight on a backend."""

    connected = True  # type: ignore[assignment]  # the simulator is always there

    def __init__(self, world: "OfflineWorld", owner: str) -> None:
        backend = world.backend
        self.world, self.owner = world, owner
        self.joint_names = backend.joint_names
        self.index = backend.index
        self.lower, self.upper = backend.lower, backend.upper
        self.warnings: List[str] = []

    def sense_position(self) -> np.ndarray:
        return self.world.backend.positions()

    def sense_velocity(self) -> np.ndarray:
        return self.world.backend.velocities()

    def sense_torque(self) -> np.ndarray:
        return self.world.backend.torques()

    def sense_temperature(self) -> np.ndarray:
        return self.world.backend.temperatures()

    def sense_ft(self, sensor: str) -> np.ndarray:
        return self.world.backend.ft(sensor)

    def sense_imu(self):
        imu = self.world.backend.imu()
        return imu.rpy, imu.acceleration, imu.gyro

    def move(self, q: Sequence[float], mode: str = "pos",
             joints: Optional[Sequence[str]] = None) -> bool:
        values = check_reference(q, self.joint_names, self.lower, self.upper)
        wanted = range(len(values)) if joints is None else [self.index[n] for n in joints]
        decision = self.world.arbiter.filter(self.owner, list(wanted), self.world.time)
        for conflict in decision.conflicts:
            if conflict.owner == self.owner:
                self.warnings.append(conflict.text())
        if decision.allowed:
            self.world.backend.set_references(decision.allowed, values[decision.allowed])
        return True

    def take_hal_warnings(self) -> List[str]:
        warnings, self.warnings = self.warnings, []
        return warnings


class OfflineModule:
    """One module in an :class:`OfflineWorld`: switch it, command it, read its status."""

    def __init__(self, world: "OfflineWorld", module_class: Type[ControlThread], name: str,
                 config: Optional[Dict] = None) -> None:
        self.world, self.name = world, name
        self.interfaces = RecordingInterfaces(f"/{name}", module_class)
        self.robot = SimulatedRobot(world, f"/{name}")
        self.thread = module_class(name, {"thread_period": 10, **(config or {})},
                                   self.interfaces, robot=self.robot,
                                   kinematics=world.kinematics)
        self.thread.clock = lambda: world.time
        self.lifecycle = Lifecycle(name, self.thread, self.interfaces,
                                   wait_until=world.wait_until, robot=lambda: self.robot)
        self.next_tick = 0.0

    @property
    def state(self) -> str:
        return self.interfaces.state

    @property
    def warnings(self) -> List[str]:
        return self.interfaces.warnings

    def switch(self, command: str) -> bool:
        """start/pause/resume/stop/quit as the runner applies them; False (told) if refused."""
        if self.lifecycle.switch(command) is not Outcome.DONE:
            return False
        self.next_tick = self.world.time
        return True

    def command(self, text: str) -> None:
        """A command line as ``yarp write`` sends it, e.g. ``turn 1.57``."""
        self.interfaces.commands.feed(parse(text))
        for problem in self.interfaces.commands.take_rejections():
            self.interfaces.warn(f"{self.name}: {problem}")

    def do(self, command: str, until: str, timeout: float = 30.0) -> float:
        """Send ``command`` and step until the status says ``until``; simulated seconds taken."""
        start = self.world.time
        self.command(command)
        self.world.step(0.02)
        self.world.run_until(lambda: self.state == until, timeout,
                             f"{self.name}: '{until}' after '{command}' (state {self.state}, "
                             f"warnings {self.warnings[-2:]})")
        return self.world.time - start

    def tick(self) -> None:
        state = self.lifecycle.state
        paused = state == State.PAUSED and self.thread.runs_while_paused()
        if (state == State.RUNNING or paused) and self.world.time + 1e-9 >= self.next_tick:
            self.next_tick += self.thread.thread_period
            if paused:
                self.thread.run_paused()
            else:
                self.thread.run()
        # In any state, as the runner's watchdog: a hold on stop may be refused too.
        for text in self.robot.take_hal_warnings():
            self.interfaces.warn(f"{self.name}: {text}")


class OfflineWorld:
    def __init__(self, backend: Optional[Backend] = None, policy: str = "refuse",
                 priorities: Optional[Dict[str, int]] = None) -> None:
        if backend is None:
            from walkman.hal.sim import SimBackend

            backend = SimBackend()
        self.backend = backend
        self.kinematics = Kinematics()
        self.arbiter = JointArbiter(backend.joint_names, policy, priorities)
        self.modules: List[OfflineModule] = []

    @property
    def time(self) -> float:
        return self.backend.time

    def add(self, module_class: Type[ControlThread], name: str,
            config: Optional[Dict] = None) -> OfflineModule:
        module = OfflineModule(self, module_class, name, config)
        self.modules.append(module)
        return module

    def step(self, seconds: float) -> None:
        end = self.time + seconds
        while self.time < end - 1e-9:
            for module in self.modules:
                module.tick()
            self.backend.step()

    def run_until(self, done: Callable[[], bool], timeout: float, what: str = "") -> float:
        """Step until ``done()``; returns the simulated seconds it took (TimeoutError if not)."""
        start = self.time
        if not self.wait_until(done, timeout):
            raise TimeoutError(f"{what or 'condition'} not reached in {timeout:g} simulated s")
        return self.time - start

    def wait_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """Step until ``done()`` or ``timeout`` simulated s: whether ``done()`` came true."""
        start = self.time
        while not done():
            if self.time - start > timeout:
                return False
            self.step(0.01)
        return True

    def prop(self, joint: str) -> float:
        """A scene joint's position (the valve, the steering wheel, the door...)."""
        return self.backend.plant.prop_position(joint)
