"""The preview gate: a task's dangerous command is worked out on this PC before it leaves.

Theory of operation
-------------------
Every command a widget sends goes through :class:`PreviewGate`.  For a task
module (a :class:`~walkman.modules.task.TaskModule`) the gate keeps its shadow
(:class:`walkman.gym.preview.Shadow`, the module's own class and IK) and the
robot's last measured posture (``/joint_states``, from the bridge).  A
dangerous command is previewed in the state the module reports: if the shadow
refuses it, or its motion passes where the IK cannot reach, it is not sent and
the widget says why; otherwise the preview's posture is shown as a ghost in
the 3-D view while the gateway counts down, and hidden when the countdown
ends (sent or cancelled); a second click while it counts down is the pilot's
cancel and goes out unpreviewed.  Every command sent is then given to the
shadow at the posture of its sending, so the shadow's notes follow the module's.
For other modules the gate only passes commands on; before the first joint
state it works from the robot's home posture, where it stands when it starts.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING, Callable, Dict, Optional, Sequence

import numpy as np

if TYPE_CHECKING:       # at run time imported by _shadow, inside its guard
    from walkman.gym.preview import Shadow

log = logging.getLogger("pilot.preview")

Send = Callable[[], str]
#: s a countdown is believed without news: the gateway says how much is left every 0.5 s;
#: a countdown whose end this PC never heard (the link dropped it) is over after this long
#: silence, and the next dangerous click is previewed again, not taken for a cancel
COUNTDOWN_SILENCE = 3.0


class PreviewGate:
    def __init__(self, state_of: Callable[[str], Optional[str]],
                 show: Callable[[str, np.ndarray], None], say: Callable[[str], None],
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.state_of, self.show, self.say, self.clock = state_of, show, say, clock
        self.posture: Optional[np.ndarray] = None
        self._shadows: Dict[str, Optional[Shadow]] = {}   # None: no preview for that module
        self._order: Optional[Dict[str, int]] = None
        self.last_ms: Optional[float] = None
        #: modules whose timed command counts down -> until when that is believed
        self._counting: Dict[str, float] = {}

    def on_joints(self, names: Sequence[str], position: Sequence[float]) -> None:
        from walkman.model.description import walkman

        if self._order is None:
            self._order = {name: index for index, name in enumerate(walkman().joint_names)}
        # Not this robot's whole posture (another model, or a JointState with efforts and no
        # positions, which ROS allows): ignored; the assignment below would raise and cut the
        # event's dispatch short (the status widget's torques would never show).
        if len(names) != len(self._order) or len(position) != len(names) or \
                set(names) != set(self._order):
            return
        posture = np.zeros(len(self._order))
        posture[[self._order[name] for name in names]] = position
        self.posture = posture

    def _shadow(self, module: str) -> Optional[Shadow]:
        if module not in self._shadows:
            self._shadows[module] = None
            try:
                from walkman.gym.preview import Shadow
                from walkman.gym.runner import load_module_class
                from walkman.modules.task import TaskModule

                cls = load_module_class(module)
                if isinstance(cls, type) and issubclass(cls, TaskModule):
                    self._shadows[module] = Shadow(cls, module)
            except Exception:  # noqa: BLE001 -- a module this PC cannot load has no preview
                log.warning("pilot: no preview for %s: its class does not load here", module,
                            exc_info=True)
        return self._shadows[module]

    def command(self, module: str, name: str, numbers: Sequence[float], dangerous: bool,
                send: Send) -> str:
        """Preview (dangerous commands), then ``send()``; '' or why it was not sent."""
        shadow = self._shadow(module)
        state = self.state_of(module)
        if shadow is None or state is None:
            return send()
        # Before the first joint state the robot stands as it started, in its home posture:
        # the shadow follows from there rather than miss the pose it needs later.
        posture = self.posture if self.posture is not None else shadow.home
        text = " ".join([name, *(repr(float(v)) for v in numbers)])
        if dangerous and self.counting(module):
            return send()                  # a second click while it counts down: a cancel
        try:
            if dangerous:
                preview = shadow.preview(text, state, posture)
                self.last_ms = preview.seconds * 1e3
                if preview.refused:
                    self.say(f"preview of {module} {name}: refused ({self.last_ms:.0f} ms)")
                    return f"not sent: this PC's preview says {preview.refusal}"
                if preview.known and preview.moves:
                    self.show(module, preview.posture)
                    self.say(f"preview of {module} {name}: the ghost shows where it goes "
                             f"({self.last_ms:.0f} ms)")
                elif preview.known:
                    self.say(f"preview of {module} {name}: accepted on this PC, no arm "
                             f"motion to show ({self.last_ms:.0f} ms)")
                else:
                    self.say(f"no preview of {module} {name}: {preview.refusal}")
        except Exception:  # noqa: BLE001 -- a preview's bug must not stop the pilot's command
            log.exception("pilot: the preview of %s %s failed; sent without one", module, text)
        problem = send()
        if not problem:
            # Nor may it kill the PI: an exception in a Qt slot aborts the process.
            try:
                shadow.follow(text, state, posture)
            except Exception:  # noqa: BLE001
                log.exception("pilot: the shadow of %s could not follow %s", module, text)
            if dangerous:
                self._counting[module] = self.clock() + COUNTDOWN_SILENCE
        return problem

    def counting(self, module: str) -> bool:
        """The module's timed command from this PC counts down (as far as we know)."""
        return self._counting.get(module, -float("inf")) > self.clock()

    def countdown_left(self, module: str, remaining: float) -> None:
        """The gateway says the countdown goes on: believed until it should have ended."""
        if module in self._counting:
            self._counting[module] = self.clock() + remaining + COUNTDOWN_SILENCE

    def countdown_over(self, module: str) -> None:
        """The gateway sent or cancelled the module's timed command."""
        self._counting.pop(module, None)
