"""A two-axis control board in memory: the control-board protocol without a robot.

Shipped in the package (as python-can ships its virtual bus) so that the
protocol's unit tests, its fuzz target and anyone writing a client can drive
:func:`walkman.hal.controlboard.respond` without a simulator or a HAL process.
Its values are fixed and easy to recognise in a reply (encoders 10 and 20
degrees, temperatures 30 and 31 C, torques 1 and -1 Nm, limits +-90 degrees);
commands are only recorded, in :attr:`VirtualBoard.commands`.
"""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

from walkman.hal.controlboard import ControlBoardDevice


class VirtualBoard(ControlBoardDevice):
    """Joints ``j0`` and ``j1``, in position mode until told otherwise."""

    def __init__(self) -> None:
        self.modes = ["pos", "pos"]
        #: every command received: (what, joints, values, owner)
        self.commands: List[Tuple[str, List[int], List[float], str]] = []

    def axes(self) -> int:
        return 2

    def vector(self, name: str) -> List[float]:
        return {"encoders": [10.0, 20.0], "temperatures": [30.0, 31.0]}.get(name, [0.0, 0.0])

    def axis_name(self, axis: int) -> str:
        return f"j{axis}"

    def limits(self, axis: int) -> Tuple[float, float]:
        return (-90.0, 90.0)

    def torques(self) -> List[float]:
        return [1.0, -1.0]

    def control_modes(self) -> List[str]:
        return list(self.modes)

    def set_control_modes(self, joints: Sequence[int], modes: Sequence[str],
                          owner: str = "") -> None:
        for joint, mode in zip(joints, modes):
            self.modes[joint] = mode

    def pid(self, pid_type: str, axis: int) -> List[float]:
        return [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]

    def motion_done(self, joints: Sequence[int]) -> bool:
        return True

    def command(self, what: str, joints: Sequence[int], values: Sequence[float],
                owner: str = "", seq: Optional[int] = None) -> None:
        self.commands.append((what, list(joints), list(values), owner))
