"""The end-state check of an open-loop replay that stopped before T, or whose kicked
replays stop before T (`departure_check`), on the closed form of an unstable system: the
linearised inverted pendulum q'' = lambda^2 q, whose equilibrium q = v = 0 is the plan. A
replay started with a velocity error e runs away as q = e sinh(lambda t) / lambda,
v = e cosh(lambda t); a replay from (q0, v0) is at q0 cosh + v0 / lambda sinh,
q0 lambda sinh + v0 cosh."""

from types import SimpleNamespace

import numpy as np
import pytest

from tfcontact.errors import SolveFailed
from tfcontact.verify import SENSITIVITY_KICK, ReplayedPlan, StoppedReplay, end_state_check

RATE = 12.0  # lambda [1/s]
TOLERANCE = 0.05
N = 10
CLOCKS = np.linspace(0.0, 1.0, N + 1)
PLAN = ReplayedPlan(cls=SimpleNamespace(n_q=1), x0=np.zeros(2), clocks=CLOCKS,
                    states=np.zeros((N + 1, 2)), controls=np.zeros((N, 0)), horizon=1.0)


def pendulum(x0: np.ndarray, t: float) -> np.ndarray:
    """The closed-form state at t from x0 = (q0, v0)."""
    q0, v0 = x0
    c, s = np.cosh(RATE * t), np.sinh(RATE * t)
    return np.array([q0 * c + v0 / RATE * s, q0 * RATE * s + v0 * c])


def stopped_at(stop_time: float, velocity_error: float, replay_to=None) -> StoppedReplay:
    """A replay that adds a velocity error to its start (as a plan's local errors would
    add up), from the plan's start and stopped at `stop_time`; from another start
    `replay_to` (default: the same replay)."""
    error = np.array([0.0, velocity_error])
    reached = CLOCKS[CLOCKS < stop_time]
    states = np.array([pendulum(PLAN.x0 + error, t) for t in reached])
    return StoppedReplay(stop_time, np.max(np.abs(states), axis=1), states,
                         replay_to or (lambda x0, k: pendulum(x0 + error, CLOCKS[k])))


def check(stopped: StoppedReplay, defects: tuple[float, ...]) -> tuple[bool, float, list]:
    notes: list[str] = []
    passed, _, amplification = end_state_check(PLAN, TOLERANCE, np.inf, defects, None, notes,
                                               stopped=stopped)
    return passed, amplification, notes


def test_a_replay_that_left_the_plan_before_it_stopped_is_judged_where_it_left():
    """Velocity error 1e-5: 1e-5 cosh(12 t) first exceeds 0.05 at the boundary t = 0.8
    (0.074; 0.022 at 0.7). A velocity kick there moves the replay by cosh(9.6) = 7382
    times the kick, and 7382 x the eight intervals' defects (8e-5) = 0.59 reaches 0.074:
    the departure is the dynamics', the plan passes on its local defects."""
    passed, amplification, notes = check(stopped_at(0.85, 1e-5), (1e-5,) * N)
    assert passed
    assert amplification == pytest.approx(np.cosh(RATE * 0.8), rel=1e-9)
    assert "after leaving the plan: 7.38e-02 from it at t = 0.8 s (boundary 8)" in notes[0]
    assert "the end-state check passes on the local defects" in notes[0]


def test_a_replay_that_stopped_while_it_still_followed_the_plan_fails():
    """Stopped at 0.75 s, the last boundary it passed (0.7 s) is 0.022 from the plan, inside
    the tolerance: nothing says the plan's own motion is simulable, so it fails."""
    passed, amplification, notes = check(stopped_at(0.75, 1e-5), (1e-5,) * N)
    assert not passed and np.isnan(amplification)
    assert "within 2.22e-02 of the plan at each of the 8 control-interval boundaries" in notes[0]


def test_a_departure_larger_than_the_amplified_defects_fails():
    """The same departure with local defects of 1e-9 per interval: 7382 x 8e-9 = 5.9e-5
    does not reach 0.074, so the departure is not the plan's local errors amplified."""
    passed, amplification, notes = check(stopped_at(0.85, 1e-5), (1e-9,) * N)
    assert not passed and amplification == pytest.approx(np.cosh(RATE * 0.8), rel=1e-9)
    assert "does not account for the deviation" in notes[0]


def test_a_departure_needs_every_local_defect_and_a_measured_amplification():
    """A restart that stopped (an inf defect, here after the departure) fails the plan,
    and so does a kicked replay that stops before the departure's boundary."""
    defects = (1e-5,) * (N - 1) + (np.inf,)
    passed, _, _ = check(stopped_at(0.85, 1e-5), defects)
    assert not passed

    def kicked_replay_stops(x0, k):
        raise SolveFailed("kicked multi-contact replay stopped: max_events")

    passed, amplification, notes = check(stopped_at(0.85, 1e-5, kicked_replay_stops),
                                         (1e-5,) * N)
    assert not passed and np.isnan(amplification)
    assert "the amplification is not measured" in notes[0]


def test_the_kick_is_the_fraction_of_the_tolerance_the_check_promises():
    """The kicked replays start from the plan's start with every velocity moved by
    SENSITIVITY_KICK x the tolerance, both signs, and run to the departure's boundary."""
    starts = []

    def recording(x0, k):
        starts.append((x0.copy(), k))
        return pendulum(x0, CLOCKS[k])  # the kicked replay's error left out: not measured

    check(stopped_at(0.85, 1e-5, recording), (1e-5,) * N)
    kick = SENSITIVITY_KICK * TOLERANCE
    assert [k for _, k in starts] == [8, 8]
    np.testing.assert_array_equal([x for x, _ in starts], [[0.0, kick], [0.0, -kick]])


def test_a_replay_that_stopped_before_its_first_sample_passed_no_boundary():
    """A replay with no sample at all (stopped at its start) passed no boundary, also when
    the plan's clock starts a round-off before 0: the check fails instead of raising."""
    from tfcontact.verify import stopped_replay

    plan = ReplayedPlan(cls=PLAN.cls, x0=PLAN.x0, clocks=CLOCKS - 1e-28, states=PLAN.states,
                        controls=PLAN.controls, horizon=1.0)
    stopped = stopped_replay(SimpleNamespace(t=np.zeros(0)), plan, lambda x0, k: x0)
    assert stopped.states.shape == (0, 2) and stopped.deviations.size == 0
    passed, amplification, notes = check(stopped, (1e-5,) * N)
    assert not passed and np.isnan(amplification)
    assert "at each of the 0 control-interval boundaries" in notes[0]


def test_a_replay_that_ran_to_t_is_judged_where_it_left_when_its_kicked_replays_stop():
    """The replay with velocity error 1e-5 runs to T = 1 s, 1e-5 cosh(12) = 0.81 from the
    plan; the kicked replays to T stop (a chatter the unkicked one escaped), so the
    amplification to T is not measured. Given the replay at the boundaries before T
    (`parted`), the plan is judged at t = 0.8 s, where it left: as for a replay that
    stopped, 7382 x 8e-5 reaches 0.074 and it passes; with defects of 1e-9 it fails;
    without `parted` it fails as before, the amplification not measured."""
    error = np.array([0.0, 1e-5])
    end = pendulum(PLAN.x0 + error, 1.0)

    def kicked_to_t_stops(x0):
        raise SolveFailed("kicked multi-contact replay stopped: max_events")

    def judged(defects, parted):
        notes: list[str] = []
        passed, _, amplification = end_state_check(
            PLAN, TOLERANCE, float(np.max(np.abs(end))), defects, end, notes,
            kicked_to_t_stops, parted=parted)
        return passed, amplification, notes

    passed, amplification, notes = judged((1e-5,) * N, stopped_at(1.0, 1e-5))
    assert passed and amplification == pytest.approx(np.cosh(RATE * 0.8), rel=1e-9)
    assert len(notes) == 1 and notes[0].startswith("open-loop replay 8.14e-01 from the plan")
    assert ("kicked start velocities stopped before T, so the plan is judged where the "
            "open-loop replay left it: 7.38e-02 from it at t = 0.8 s (boundary 8)") in notes[0]
    assert "passes on the local defects" in notes[0]
    passed, amplification, notes = judged((1e-9,) * N, stopped_at(1.0, 1e-5))
    assert not passed and "does not account for the deviation" in notes[0]
    passed, amplification, notes = judged((1e-5,) * N, None)
    assert not passed and np.isnan(amplification)
    assert "the amplification is not measured and the end-state check fails" in notes[0]
