"""walkman.gym.link_loss: a module's declared policy, and when it pauses or stops the module.

Pure: the link's state (as nodekit.link_watch says it), the lifecycle state and the
time go in, at most one verdict comes out.
"""

from __future__ import annotations

import math
from typing import List, Optional, Tuple

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nodekit.link_watch import DIRECT, DOWN, UNKNOWN, UP, LinkState
from walkman.gym.lifecycle import State, Switch
from walkman.gym.link_loss import LinkLoss, LinkLossDecider, LossAction, Verdict, link_loss_of
from walkman.gym.thread import GenericThread

UP_SINCE = LinkState(UP, 0.0)


def down(since: float) -> LinkState:
    return LinkState(DOWN, since, "the pilot's bridge silent for 1.6 s")


# -- the declaration --------------------------------------------------------------------------

def test_continue_is_the_default_of_every_module():
    assert GenericThread.link_loss == LinkLoss.CONTINUE
    assert link_loss_of(GenericThread) is LinkLoss.CONTINUE
    assert link_loss_of(object) is LinkLoss.CONTINUE     # a class that never heard of it
    assert str(LinkLoss.CONTINUE) == "continue"


def test_pause_and_stop_say_after_how_long():
    assert LinkLoss.pause(after=5) == LinkLoss(LossAction.PAUSE, 5.0)
    assert str(LinkLoss.pause(after=5)) == "pause after 5 s"
    assert str(LinkLoss.stop(after=2.5)) == "stop after 2.5 s"
    assert LinkLoss("stop", 1.0).action is LossAction.STOP     # a word works too
    with pytest.raises(AttributeError):
        LinkLoss.pause(after=5).after = 1.0                     # frozen


@pytest.mark.parametrize("after", [-1.0, math.inf, math.nan, "5", True, None])
def test_a_wrong_delay_is_refused_when_declared(after):
    with pytest.raises(ValueError, match="'after'"):
        LinkLoss(LossAction.PAUSE, after)


def test_a_wrong_declaration_is_refused_when_the_module_loads():
    with pytest.raises(ValueError, match="is not one of continue, pause, stop"):
        LinkLoss("hover", 1.0)

    class Confused(GenericThread):
        link_loss = "pause"
    with pytest.raises(TypeError, match=r"Confused.link_loss must be a LinkLoss"):
        link_loss_of(Confused)


# -- when it acts -----------------------------------------------------------------------------

class Module:
    """A lifecycle as the decider reads it: the state, and when it was entered."""

    def __init__(self, policy: LinkLoss, state: State, since: float = 0.0) -> None:
        self.decider = LinkLossDecider("m", policy)
        self.state, self.since = state, since

    def become(self, state: State, now: float) -> None:
        self.state, self.since = state, now

    def step(self, link: LinkState, now: float) -> Optional[Verdict]:
        verdict = self.decider.step(link, self.state, self.since, now)
        if verdict is not None and verdict.switch is not None:   # as the lifecycle would
            self.become({Switch.PAUSE: State.PAUSED, Switch.STOP: State.STOPPED}
                        [verdict.switch], now)
        return verdict


def test_continue_never_acts():
    module = Module(LinkLoss.CONTINUE, State.RUNNING)
    for now in range(0, 100, 5):
        assert module.step(down(0.0), float(now)) is None
    assert module.step(UP_SINCE, 200.0) is None


def test_pause_comes_after_the_delay_once_and_says_why():
    decider = LinkLossDecider("gaze_control", LinkLoss.pause(after=5.0))
    assert decider.step(UP_SINCE, State.RUNNING, 0.0, 9.0) is None
    assert decider.step(down(10.0), State.RUNNING, 0.0, 10.0) is None
    assert decider.step(down(10.0), State.RUNNING, 0.0, 14.9) is None
    verdict = decider.step(down(10.0), State.RUNNING, 0.0, 15.1)
    assert verdict == Verdict("gaze_control: paused: no link to the pilot for 5 s "
                              "(link-loss policy)", Switch.PAUSE)
    # Not again, whether the pause is still under way (its safe pause) or refused...
    assert decider.step(down(10.0), State.RUNNING, 0.0, 15.6) is None
    # ...or done.
    assert decider.step(down(10.0), State.PAUSED, 16.0, 16.0) is None
    assert decider.step(down(10.0), State.PAUSED, 16.0, 60.0) is None


def test_the_module_stays_paused_when_the_link_returns_and_says_so_once():
    module = Module(LinkLoss.pause(after=5.0), State.RUNNING)
    module.decider.name = "walking"
    assert module.step(down(1.0), 6.0).switch == Switch.PAUSE
    assert module.step(down(1.0), 6.5) is None
    back = module.step(LinkState(UP, 30.0), 30.0)
    assert back == Verdict("walking: the link to the pilot is back; the link-loss policy "
                           "paused the module 24 s ago and it stays paused until the pilot "
                           "resumes it")
    assert module.step(LinkState(UP, 30.0), 31.0) is None    # once
    # The pilot resumes it; the next outage pauses it again.
    module.become(State.RUNNING, 40.0)
    assert module.step(LinkState(UP, 30.0), 40.0) is None
    assert module.step(down(50.0), 55.0).switch == Switch.PAUSE


def test_a_short_outage_changes_nothing():
    module = Module(LinkLoss.pause(after=5.0), State.RUNNING)
    assert module.step(down(1.0), 5.9) is None
    assert module.step(LinkState(UP, 6.0), 6.0) is None     # nothing to say
    assert module.step(down(7.0), 11.9) is None             # a new outage
    assert module.step(down(7.0), 12.0).switch == Switch.PAUSE


@pytest.mark.parametrize("state", [State.CONSTRUCTOR, State.PAUSED, State.STOPPED,
                                   State.DESTRUCTOR])
def test_pause_leaves_a_module_that_is_not_running_alone(state):
    module = Module(LinkLoss.pause(after=1.0), state)
    assert module.step(down(0.0), 100.0) is None
    assert module.step(LinkState(UP, 101.0), 101.0) is None


def test_stop_acts_on_a_running_or_paused_module_and_says_it_stays_stopped():
    running = Module(LinkLoss.stop(after=3.0), State.RUNNING)
    verdict = running.step(down(0.0), 3.0)
    assert verdict == Verdict("m: stopped: no link to the pilot for 3 s (link-loss policy)",
                              Switch.STOP)
    assert running.step(down(0.0), 4.0) is None
    assert "stays stopped until the pilot starts it" in \
        running.step(LinkState(UP, 9.0), 9.0).warning

    paused = Module(LinkLoss.stop(after=3.0), State.PAUSED)
    assert paused.step(down(0.0), 3.0).switch == Switch.STOP


def test_a_module_started_during_the_outage_gets_its_full_delay():
    """Started from the robot itself while the link was down (the pilot cannot): the delay
    counts from the start, not from the cut long before."""
    module = Module(LinkLoss.pause(after=5.0), State.STOPPED)
    assert module.step(down(0.0), 60.0) is None
    module.become(State.RUNNING, 61.0)
    assert module.step(down(0.0), 65.9) is None
    verdict = module.step(down(0.0), 66.0)
    assert verdict.switch == Switch.PAUSE and "for 66 s" in verdict.warning
    # Resumed again from the robot during the same outage: paused again, after 5 s more.
    module.become(State.RUNNING, 70.0)
    assert module.step(down(0.0), 74.9) is None
    assert module.step(down(0.0), 75.0).switch == Switch.PAUSE


def test_a_refused_switch_is_not_proposed_again_in_the_same_outage():
    decider = LinkLossDecider("m", LinkLoss.pause(after=1.0))
    assert decider.step(down(0.0), State.RUNNING, 0.0, 1.0).switch == Switch.PAUSE
    for now in (1.5, 2.0, 30.0):                       # the lifecycle refused: still running
        assert decider.step(down(0.0), State.RUNNING, 0.0, now) is None


def test_back_after_someone_on_the_robot_changed_the_state_says_only_that():
    module = Module(LinkLoss.pause(after=1.0), State.RUNNING)
    assert module.step(down(0.0), 1.0).switch == Switch.PAUSE
    module.become(State.STOPPED, 2.0)
    assert module.step(LinkState(UP, 3.0), 3.0) == Verdict("m: the link to the pilot is back")


@pytest.mark.parametrize("link", [UNKNOWN, DIRECT, UP])
def test_no_bridge_or_a_live_link_never_acts(link):
    """The lab: no bridge ever spoke (unknown), or a program told there is none (direct)."""
    module = Module(LinkLoss.stop(after=0.0), State.RUNNING)
    for now in (0.0, 10.0, 1e6):
        assert module.step(LinkState(link, 0.0), now) is None


STATES = st.sampled_from(list(State))
LINKS = st.sampled_from([UP, DOWN, UNKNOWN])


@given(policy=st.sampled_from([LinkLoss.CONTINUE, LinkLoss.pause(after=2.0),
                               LinkLoss.stop(after=2.0)]),
       steps=st.lists(st.tuples(st.floats(0.0, 3.0), LINKS, STATES), max_size=60))
def test_every_switch_is_legal_and_due(policy, steps: List[Tuple[float, str, State]]):
    """Whatever the link and the lifecycle do: a switch only from a state the policy acts on,
    only while the link is down, never before the delay has passed since the cut and since
    the module entered its state."""
    decider = LinkLossDecider("m", policy)
    now, link, since, before = 0.0, LinkState(UNKNOWN, 0.0), 0.0, State.CONSTRUCTOR
    for gap, word, state in steps:
        now += gap
        if word != link.state:
            link = LinkState(word, now)
        if state != before:
            since, before = now, state
        verdict: Optional[Verdict] = decider.step(link, state, since, now)
        if verdict is None or verdict.switch is None:
            continue
        assert policy.action is not LossAction.CONTINUE and link.state == DOWN
        assert now - max(link.since, since) >= policy.after
        assert state == State.RUNNING or (state == State.PAUSED and
                                          verdict.switch == Switch.STOP)
