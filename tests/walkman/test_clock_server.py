"""walkman/hal/clock_server.py: the ClockServer verbs over the physics thread's step gate."""

from __future__ import annotations

import threading

import pytest

from walkman.hal.clock_server import (EPOCH, ClockServer, SimulationTime, StepGate,
                                      parse_rtf)
from yarp_lite.bottle import Bottle, Vocab
from yarp_lite.bottle_text import parse


class Physics(threading.Thread):
    """The HAL's physics loop reduced to its gate: step while the gate lets it."""

    def __init__(self, gate: StepGate) -> None:
        super().__init__(daemon=True)
        self.gate, self.running = gate, True

    def run(self) -> None:
        while self.running:
            if self.gate.may_step():
                self.gate.stepped()

    def stop(self) -> None:
        self.running = False
        self.gate.close()
        if self.is_alive():
            self.join(5)


@pytest.fixture
def clock():
    gate = StepGate()
    server = ClockServer(gate, SimulationTime(0.001))
    physics = Physics(gate)
    yield server, physics
    physics.stop()


def ask(server: ClockServer, text: str) -> Bottle:
    return server.answer(parse(text))


def test_simulated_time_starts_above_zero_and_counts_steps_exactly(clock):
    server, _ = clock
    assert ask(server, "getSimulationTime") == [EPOCH] and EPOCH > 0
    assert ask(server, "getStepSize") == [0.001]
    server.gate.taken = 50
    assert ask(server, "getSimulationTime")[0] == EPOCH + 50 * 0.001


def test_paused_the_physics_takes_exactly_the_steps_asked_for(clock):
    server, physics = clock
    assert ask(server, "pauseSimulation") == [Vocab("done")]
    physics.start()
    assert server.gate.held or not server.gate.may_step()
    start = server.gate.taken
    assert ask(server, "stepSimulationAndWait 50") == Bottle()     # thrift's void reply
    assert server.gate.taken == start + 50
    assert ask(server, "stepSimulation") == [Vocab("done")]          # default: one step
    assert ask(server, "stepSimulationAndWait 1") == Bottle()
    assert server.gate.taken == start + 52
    assert ask(server, "getSimulationTime")[0] == pytest.approx(EPOCH + (start + 52) * 0.001,
                                                                abs=1e-12)
    assert ask(server, "continueSimulation") == [Vocab("done")]
    taken = server.gate.taken
    assert server.gate.wait_for(taken + 100)


def test_step_and_wait_while_running_waits_for_that_many_more_steps(clock):
    server, physics = clock
    physics.start()
    start = server.gate.taken
    assert ask(server, "stepSimulationAndWait 20") == Bottle()
    assert server.gate.taken >= start + 20


def test_resetting_the_time_starts_it_again_at_the_epoch(clock):
    server, _ = clock
    server.gate.taken = 1234
    assert ask(server, "resetSimulationTime") == [Vocab("done")]
    assert ask(server, "getSimulationTime") == [EPOCH]


def test_a_reset_its_owner_refuses_is_answered_with_why():
    server = ClockServer(StepGate(), SimulationTime(0.001),
                         on_reset=lambda: "2 modules step in lockstep")
    assert ask(server, "resetSimulationTime") == [
        Vocab("fail"), "resetSimulationTime: 2 modules step in lockstep"]


@pytest.mark.parametrize("request_text, named", [
    ("jumpAhead 10", "unknown ClockServer call 'jumpAhead 10'; known: pauseSimulation"),
    ("", "unknown ClockServer call ''"),
    ("42", "unknown ClockServer call '42'"),
    ("stepSimulationAndWait 1000000000", "the step count must be 1 to 60000 (60 s of 1 ms "
                                         "steps), got 1000000000"),
    ("stepSimulationAndWait -3", "the step count must be 1 to 60000"),
    ("stepSimulationAndWait 0", "the step count must be 1 to 60000"),
    ("stepSimulation 2.5", "the step count must be an integer, got 2.5"),
    ("stepSimulation ten", "the step count must be an integer, got 'ten'"),
    ("stepSimulation 1 2", "takes one step count, got '1 2'"),
    ("pauseSimulation now", "pauseSimulation: takes no arguments, got 'now'"),
])
def test_bad_calls_get_a_reply_that_names_the_fault_and_change_nothing(clock, request_text,
                                                                       named):
    server, _ = clock
    reply = ask(server, request_text)
    assert reply[0] == Vocab("fail") and named in reply[1], reply
    assert not server.gate.paused and server.gate.taken == 0


def test_a_closed_gate_releases_a_waiter_with_a_failure(clock):
    server, _ = clock
    server.gate.pause()
    replies = []
    waiter = threading.Thread(target=lambda: replies.append(ask(server, "stepSimulationAndWait 5")))
    waiter.start()
    server.gate.close()
    waiter.join(5)
    assert replies == [[Vocab("fail"), "stepSimulationAndWait: the simulation stopped before "
                                       "the steps were taken"]]


@pytest.mark.parametrize("text, value", [("1", 1.0), ("2.5", 2.5), ("max", None), ("MAX", None)])
def test_rtf_is_a_positive_factor_or_max(text, value):
    assert parse_rtf(text) == value


@pytest.mark.parametrize("text", ["0", "-1", "nan", "inf", "fast", ""])
def test_a_bad_rtf_is_refused_by_name(text):
    with pytest.raises(ValueError, match="--rtf takes a factor above 0 or 'max'"):
        parse_rtf(text)
