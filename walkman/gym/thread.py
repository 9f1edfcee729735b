"""What a module developer inherits: :class:`GenericThread` and :class:`ControlThread`.

The paper's ``generic_thread``: override ``custom_init`` (required) and
``run``; optionally ``custom_pause``, ``custom_resume``, ``custom_release``,
``ready_to_pause`` (``pause`` and ``stop`` wait for it: walking lands its
foot), ``run_paused`` (a paused module that must keep the robot safe) and
``held_posture`` (what the robot holds once the module stops).
Everything else -- ports, the pilot interfaces, the lifecycle, the loop
timing, reconnections -- is the runner's job (:mod:`walkman.gym.runner`).

A minimal module::

    class Module(ControlThread):
        statuses = ["idle", "moving"]

        def custom_init(self):
            self.goal = self.robot.sense_position()
            return True

        def run(self):
            command = self.command_interface.get_command()   # pilot's command, or None
            q = self.robot.sense_position()                  # sense
            ...                                               # compute
            self.robot.move(q)                               # move
            self.status_interface.set_status("idle")
"""

from __future__ import annotations

import logging
import time
from typing import Any, Callable, Dict, FrozenSet, List, Mapping, Optional, Sequence, Tuple

from walkman.gym.interfaces import PilotCommand, PilotInterfaces
from walkman.gym.link_loss import LinkLoss
from walkman.gym.validity import DEFAULT_VALIDITY

log = logging.getLogger("walkman.gym")


class _CommandView:
    def __init__(self, interfaces: PilotInterfaces) -> None:
        self._interfaces = interfaces

    def get_command(self) -> Optional[PilotCommand]:
        """The oldest command not yet handled, or None (never blocks)."""
        command = self._interfaces.commands.get()
        if command is not None:  # a pilot's command: rare, worth a line in the log
            log.info("%s: command %s%s (seq %s)", self._interfaces.prefix.lstrip("/"),
                     command.name, "".join(f" {a}" for a in command.args), command.seq)
        return command


class _StatusView:
    def __init__(self, interfaces: PilotInterfaces, on_change) -> None:
        self._interfaces = interfaces
        self._on_change = on_change

    def set_status(self, state: str, *data: Any) -> None:
        if self._interfaces.set_status(state, data):
            self._on_change()

    @property
    def status(self) -> str:
        return self._interfaces.state


class _WarningView:
    def __init__(self, interfaces: PilotInterfaces) -> None:
        self._interfaces = interfaces

    def warn(self, text: str) -> None:
        log.warning("%s", text)
        self._interfaces.warn(text)


class GenericThread:
    """Base of every module; see the module docstring for the contract."""

    #: The module's states, in order: sent as 'a', 'b', ... (dictionary compression).
    statuses: List[str] = []
    #: command -> (fewest numbers, most numbers, usage): what a pilot's tool offers.
    arguments: Mapping[str, Tuple[int, int, str]] = {}
    #: Commands a pilot's tool sends with a countdown (the paper's QtTimedButton).
    dangerous: FrozenSet[str] = frozenset()
    #: Seconds a pilot's switch or command may wait before it starts, unless the pilot sets
    #: another; older, it is refused as expired (:mod:`walkman.gym.validity`).
    command_validity: float = DEFAULT_VALIDITY
    #: What the module does when the link to the pilot dies (:mod:`walkman.gym.link_loss`):
    #: ``LinkLoss.CONTINUE`` (as at the DRC), ``LinkLoss.pause(after=5.0)`` or
    #: ``LinkLoss.stop(after=...)``.  Say in the class why the module's choice is right.
    link_loss: LinkLoss = LinkLoss.CONTINUE
    #: How a pilot reads a status's numbers, per state (``"*"``: every other state): a
    #: format over them with names and units, e.g. ``"neck yaw {0:.2f} rad"``.  Without
    #: one, or for numbers that do not fit it, they are shown as they came.
    status_format: Mapping[str, str] = {}

    @classmethod
    def describe_status(cls, state: str, values: Sequence[float]) -> str:
        """A status's numbers as the pilot reads them (the PI shows this beside the state)."""
        template = cls.status_format.get(state, cls.status_format.get("*"))
        if template is not None and values:
            try:
                return template.format(*values)
            except (IndexError, ValueError):
                pass    # not the shape the module declared: the numbers as they are
        return " ".join(f"{value:g}" for value in values)

    def __init__(self, name: str, config: Dict[str, Any], interfaces: PilotInterfaces,
                 on_status_change=lambda: None) -> None:
        self.name = name
        self.config = config
        #: Where modules read time: under the runner the robot's time once it is connected
        #: (:class:`walkman.hal.clock.RobotClock`), simulated time offline.
        self.clock: Callable[[], float] = time.monotonic
        self.thread_period = float(config.get("thread_period", 10)) / 1000.0
        self.command_interface = _CommandView(interfaces)
        self.status_interface = _StatusView(interfaces, on_status_change)
        self.warning_interface = _WarningView(interfaces)

    def now(self) -> float:
        """Seconds on the module's clock (use it, not time.monotonic, for trajectories)."""
        return self.clock()

    # -- to override ----------------------------------------------------------------------

    def custom_init(self) -> bool:
        raise NotImplementedError(f"{type(self).__name__} must implement custom_init()")

    def run(self) -> None:
        """One control step, called every ``thread_period`` while running."""

    #: Set while the pilot asked to pause and the module has not paused yet.
    pause_requested: bool = False

    def ready_to_pause(self) -> bool:
        """False while the module must go on to reach a safe pause (walking: feet down).

        The runner keeps calling ``run()`` (with ``pause_requested`` set) until
        this is True, then calls ``custom_pause``.
        """
        return True

    def run_paused(self) -> None:
        """Called every ``thread_period`` while paused, if a module overrides it.

        Paused, a module is silent so that another may use the robot (the paper's
        door sequence).  A module whose robot would not stay safe without it -- walking:
        nothing else keeps a free-standing robot balanced -- overrides this to go on
        commanding *only* the joints that keep it safe (the legs); the HAL frees the
        others (the waist) for the next module once they have been silent."""

    @classmethod
    def runs_while_paused(cls) -> bool:
        return cls.run_paused is not GenericThread.run_paused

    def custom_pause(self) -> bool:
        return True

    def custom_resume(self) -> bool:
        return True

    def custom_release(self) -> None:
        """Undo custom_init (called on stop and quit)."""


class ControlThread(GenericThread):
    """A GenericThread with the robot: ``self.robot`` (whole-body) and ``self.kinematics``."""

    needs_robot = True

    def __init__(self, name: str, config: Dict[str, Any], interfaces: PilotInterfaces,
                 on_status_change=lambda: None, robot=None, kinematics=None) -> None:
        super().__init__(name, config, interfaces, on_status_change)
        self.robot = robot
        self.kinematics = kinematics

    def held_posture(self):
        """What the robot holds when the module stops or fails: None (the default) holds
        the posture the joints read; a module whose command differs from that on purpose
        (walking makes up for the legs' springs) returns its command for its joints."""
        return None

    def move(self, q) -> bool:
        return self.robot.move(q)
