"""The ``ethercat`` backend: an emulated bus of 33 control boards and 5 sensor boards.

Theory of operation
-------------------
Every millisecond the master builds the process image -- 33 Tx slices of 12
bytes -- from the position references and PID gains, and sends it on the
bus.  Each board takes its slice, runs its firmware (a PID loop producing a
joint torque, see :mod:`walkman.hal.ethercat.firmware`), and answers its Rx
slice (16 bytes for a joint, 30 for a sensor board).  The master decodes the
answers and that is all the HAL knows: positions with the encoders'
resolution, spring torques, temperatures, fault words, and the round-trip
time it measured for each slave.

The mechanics under the boards are the same MuJoCo model as the ``sim``
backend, driven in torque mode by the boards' output, so modules see the
same robot on both backends, as the paper's HAL promises.
"""

from __future__ import annotations

import time
from typing import Dict, Optional

import numpy as np

from walkman.hal.backend import Imu
from walkman.hal.ethercat.firmware import ControlBoards, SensorBoard, pack_tx, unpack_rx
from walkman.hal.ethercat.packets import CLEAR_FAULTS, CONTROL_RX, CONTROL_TX, SENSOR_RX, Fault
from walkman.hal.sim import MujocoPlant, PlantBackend
from walkman.hal.thermal import ThermalModel
from walkman.model.description import Robot, walkman

#: Default PID gains written into every Tx packet: (P N*m/rad, D N*m*s/rad).
GAINS = {"default": (1500.0, 25.0), "hand": (200.0, 3.0), "leg": (2500.0, 40.0)}


def _gains(name: str) -> tuple:
    if name.endswith("_handj"):
        return GAINS["hand"]
    if any(part in name for part in ("Hip", "Knee", "Ank")):
        return GAINS["leg"]
    return GAINS["default"]


class EthercatBackend(PlantBackend):
    def __init__(self, model: Optional[Robot] = None, scene: bool = True, harness: str = "locked",
                 thermal_speedup: float = 1.0, station: str = "valve") -> None:
        super().__init__(model or walkman())
        self._use_plant(MujocoPlant(self.model, scene=scene, harness=harness, station=station),
                        station)
        self.plant.set_servo(np.arange(len(self.joint_names)),
                             np.ones(len(self.joint_names), dtype=bool), self.idle)
        self.thermal = ThermalModel(len(self.joint_names), speedup=thermal_speedup)
        self.boards = ControlBoards([self.model.joint(n).lower for n in self.joint_names],
                                    [self.model.joint(n).upper for n in self.joint_names],
                                    [self.model.joint(n).effort for n in self.joint_names])
        self.gains = np.array([_gains(n) for n in self.joint_names])
        self.sensor_boards = [SensorBoard(name, lambda name=name: self.plant_ft(name))
                              for name in self.ft_sensors]
        self.sensor_boards.append(SensorBoard("imu", self._imu_sample))
        self.cycle = 0
        self.clear_faults = True
        # What the master last decoded from the bus.
        count = len(self.joint_names)
        self.measured = np.zeros(count)
        self.measured_reference = np.zeros(count)
        self.measured_torque = np.zeros(count)
        self.measured_temperature = np.zeros(count)
        self.faults = np.zeros(count, dtype=int)
        self.round_trip_us = np.zeros(count, dtype=int)
        self.sensor_values: Dict[str, tuple] = {}
        self.sensor_round_trip_us: Dict[str, int] = {}
        self._velocity = np.zeros(count)
        self.bytes_per_cycle = count * (CONTROL_TX.size + CONTROL_RX.size) + \
            len(self.sensor_boards) * SENSOR_RX.size
        self._velocity_ready = False
        self.step()  # first exchange, so every reading is valid from the start

    # -- the plant, as the boards' sensors see it ------------------------------------

    def plant_ft(self, name: str) -> list:
        return [*self.plant.sensor(f"{name}_force").tolist(),
                *self.plant.sensor(f"{name}_torque").tolist()]

    def _imu_sample(self) -> tuple:
        from walkman.hal.backend import quat_to_rpy

        rpy = quat_to_rpy(*self.plant.sensor("imu_orientation"))
        return (*rpy, *self.plant.sensor("imu_gyro"))

    # -- one bus cycle -------------------------------------------------------------------

    def build_tx_image(self) -> bytes:
        fault_word = CLEAR_FAULTS if self.clear_faults else 0
        self.clear_faults = False
        p_gain = np.where(self.idle, 0.0, self.gains[:, 0])
        d_gain = np.where(self.idle, 0.0, self.gains[:, 1])
        return pack_tx(self.reference, fault_word, p_gain, d_gain, self.cycle)

    def step(self) -> None:
        import mujoco

        plant = self.plant
        q = plant.d.qpos[plant.qpos_adr]
        qdot = plant.d.qvel[plant.dof_adr]
        temperature = self.thermal.temperature
        image = self.build_tx_image()
        started = time.perf_counter()
        # The frame travels the ring: every board reads its slice, runs, writes its answer.
        self.boards.receive(image, q)
        torques = self.boards.control(q, qdot, temperature)
        elapsed_us = (time.perf_counter() - started) * 1e6
        # A slave's round trip is the frame's time up to it, in ring order.
        count = len(self.joint_names)
        rtt = (elapsed_us * np.arange(1, count + 1) / count).astype(int)
        answers = self.boards.answer(q, temperature, rtt)
        plant.d.ctrl[plant.actuator] = torques
        mujoco.mj_step(plant.m, plant.d)
        self.time += self.dt
        self.cycle += 1
        self.thermal.step(torques, self.dt)
        self._decode(answers)

    def _decode(self, answers: bytes) -> None:
        previous = self.measured.copy()
        rx = unpack_rx(answers)
        self.measured[:] = rx["position"] / 1e6
        self.measured_reference[:] = rx["reference"] / 1e6
        self.measured_torque[:] = rx["torque"] / 100.0
        self.measured_temperature[:] = rx["temperature"] / 10.0
        self.faults[:] = rx["fault"]
        self.round_trip_us[:] = rx["rtt"]
        self._velocity = 0.8 * self._velocity + 0.2 * (self.measured - previous) / self.dt
        for board in self.sensor_boards:
            started = time.perf_counter()
            data = board.answer(0)
            board_rtt = int((time.perf_counter() - started) * 1e6)
            *raw, _fault, _rtt, _stamp = SENSOR_RX.unpack(data)
            self.sensor_values[board.name] = tuple(value / 1000.0 for value in raw)
            self.sensor_round_trip_us[board.name] = board_rtt

    # -- Backend ---------------------------------------------------------------------------

    def positions(self) -> np.ndarray:
        return self.measured.copy()

    def velocities(self) -> np.ndarray:
        return self._velocity.copy()

    def torques(self) -> np.ndarray:
        return self.measured_torque.copy()

    def temperatures(self) -> np.ndarray:
        return self.measured_temperature.copy()

    def ft(self, sensor: str) -> np.ndarray:
        return np.array(self.sensor_values[sensor])

    def imu(self) -> Imu:
        roll, pitch, yaw, wx, wy, wz = self.sensor_values["imu"]
        # The IMU board carries orientation and rates; report gravity as acceleration.
        gravity = 9.81
        acc = (-gravity * np.sin(pitch), gravity * np.sin(roll) * np.cos(pitch),
               gravity * np.cos(roll) * np.cos(pitch))
        return Imu((roll, pitch, yaw), tuple(float(a) for a in acc), (wx, wy, wz))

    def status(self) -> Dict[str, object]:
        faulty = {self.joint_names[i]: str(Fault(int(f))) for i, f in enumerate(self.faults)
                  if f and not f == Fault.TORQUE_SATURATED}
        return {"backend": "ethercat", "cycle": self.cycle,
                "bytes_per_cycle": self.bytes_per_cycle,
                "max_round_trip_us": int(self.round_trip_us.max()), "faults": faulty}
