"""Task success beside physical verification: goals measured on the plan's motion."""

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.fesd import RadauIIA
from tfcontact.mpcc import Ipopt, LinfPenalty
from tfcontact.ocp import ContactProblem, ContactSolverOptions
from tfcontact.ocp.contact import solve_contact
from tfcontact.ocp.goals import (
    Clearance,
    EndPosition,
    Flight,
    LiftOffs,
    Motion,
    Moves,
    Progress,
    TaskReport,
    check_goals,
)
from tfcontact.scenes.particles import point_mass
from tfcontact.timefreezing import time_freeze


def _hop() -> Motion:
    """x from 0 to 0.66, one excursion of the foot to 0.3 m, a second one to 0.02 m."""
    t = np.linspace(0.0, 1.0, 11)
    x = np.linspace(0.0, 0.66, 11)
    gap = np.array([0, 0, 0.1, 0.3, 0.1, 0, 0, 0.02, 0.01, 0, 0])
    return Motion(t=t, q=np.column_stack([x, 0.5 + gap]), gaps=gap[:, None],
                  names=("x", "z"))


def test_each_goal_measures_the_motion():
    motion = _hop()
    report = check_goals([EndPosition("x", 0.7, 0.05), Progress("x", 0.5),
                          Clearance(0, 0.25), LiftOffs(0, 1, 0.05), Moves()], motion)
    assert report.passed and report.status == "done"
    values = {c.name: c.value for c in report.checks}
    assert values["end x"] == pytest.approx(0.04)
    assert values["progress x"] == pytest.approx(0.66)
    assert values["clearance contact 0"] == pytest.approx(0.3)
    assert values["lift-offs contact 0"] == 1  # the 2 cm excursion is below 5 cm
    assert check_goals([LiftOffs(0, 2, 0.015)], motion).checks[0].value == 2
    # a foot that starts in the air, or rises twice without touching down, lifts off once
    swing = Motion(t=np.arange(6.0), q=np.zeros((6, 1)),
                   gaps=np.array([[0.2], [0.0], [0.3], [0.1], [0.3], [0.0]]), names=("x",))
    assert check_goals([LiftOffs(0, 1, 0.05)], swing).checks[0].value == 1
    with pytest.raises(InvalidInput, match="`touch` .* must lie below `height`"):
        LiftOffs(0, 1, 0.05, touch=0.1)
    missed = check_goals([EndPosition("x", 1.3, 0.05), Progress("x", -0.1),
                          LiftOffs(0, 2, 0.05)], motion)
    assert not missed.passed and missed.status == "goal_missed"
    assert [c.passed for c in missed.checks] == [False, False, False]
    assert "goal missed" in missed.summary() and "GOAL MISSED" in missed.summary()


def test_flight_needs_every_contact_up_at_once_for_the_duration():
    """Two feet: front up over [0.2, 0.5] s, hind over [0.3, 0.7] s: together 0.2 s
    (samples 0.3 to 0.5), although each alone is up longer; feet lifted in turn (no
    overlap) fly 0 s."""
    t = np.linspace(0.0, 1.0, 11)
    front = np.array([0, 0, .05, .1, .1, .05, 0, 0, 0, 0, 0])
    hind = np.array([0, 0, 0, .05, .1, .1, .1, .05, 0, 0, 0])
    jump = Motion(t=t, q=np.zeros((11, 1)), gaps=np.column_stack([front, hind]),
                  names=("x",))
    check = check_goals([Flight((0, 1), 0.19)], jump).checks[0]
    assert check.value == pytest.approx(0.2) and check.passed
    assert not check_goals([Flight((0, 1), 0.25)], jump).passed
    assert check_goals([Flight((0,), 0.3)], jump).checks[0].value == pytest.approx(0.3)
    # 6 cm of clearance needed: the overlap shrinks to the samples 0.4 s (front .1, hind
    # .1) alone, a stretch of zero length
    assert check_goals([Flight((0, 1), 0.1, height=0.06)], jump).checks[0].value == 0.0
    walk = Motion(t=t, q=np.zeros((11, 1)), gaps=np.column_stack([front, front[::-1]]),
                  names=("x",))
    assert check_goals([Flight((0, 1), 0.1)], walk).checks[0].value == 0.0
    with pytest.raises(InvalidInput, match="a Flight goal needs at least one contact"):
        Flight((), 0.1)
    with pytest.raises(InvalidInput, match="`duration` must be a positive number"):
        Flight((0,), 0.0)


def test_no_motion_wins_over_a_missed_goal():
    still = Motion(t=np.linspace(0, 1, 5), q=np.zeros((5, 2)), gaps=np.zeros((5, 1)),
                   names=("x", "z"))
    report = check_goals([EndPosition("x", 1.0, 0.1), Moves(1e-3)], still)
    assert report.status == "no_motion" and not report.passed
    assert TaskReport(()).passed and not TaskReport(()).stated
    assert "no goals stated" in TaskReport(()).summary()


def test_bad_goals_are_named():
    with pytest.raises(InvalidInput, match="`tolerance` must be a positive number"):
        EndPosition("x", 1.0, 0.0)
    with pytest.raises(InvalidInput, match="`distance` of a Progress goal must not be 0"):
        Progress("x", 0.0)
    with pytest.raises(InvalidInput, match="`count` must be a positive integer"):
        LiftOffs(0, 0, 0.05)
    with pytest.raises(InvalidInput, match="`height` must be a positive number"):
        Clearance(0, float("nan"))
    particle = time_freeze(point_mass(2, mu=0.6, a_n=9.81, controlled=True))
    base = dict(system=particle, q0=[0, 0], v0=[0, 0], horizon=1.0, n_intervals=4)
    with pytest.raises(InvalidInput, match="coordinate `y`; the system's coordinates are"):
        ContactProblem(**base, goals=(EndPosition("y", 1.0, 0.1),))
    with pytest.raises(InvalidInput, match="names contact 3; the system has 1"):
        ContactProblem(**base, goals=(Clearance(3, 0.1),))
    with pytest.raises(InvalidInput, match="`goals` must hold Goal objects"):
        ContactProblem(**base, goals=("reach x = 1",))
    with pytest.raises(InvalidInput, match=r"`control_guess` must be a finite array of shape"):
        ContactProblem(**base, control_guess=np.zeros((3, 2)))


def _sliding_particle(costs=lambda tf: {}, **kwargs) -> ContactProblem:
    """A particle at rest on the ground (mu 0.6), pushed by u_x in [-10, 10] N for 1 s;
    `costs(system)` gives the cost keywords in the system's symbols."""
    tf = time_freeze(point_mass(2, mu=0.6, a_n=9.81, controlled=True))
    return ContactProblem(system=tf, q0=[0.0, 0.0], v0=[0.0, 0.0], horizon=1.0,
                          n_intervals=4, u_lower=[-10.0, 0.0], u_upper=[10.0, 0.0],
                          **costs(tf), **kwargs)


def _options(**nlp) -> ContactSolverOptions:
    return ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=2,
                                relaxation=LinfPenalty(), nlp=Ipopt(**nlp))


def test_a_physical_plan_that_does_nothing_is_not_a_success():
    """Before: a problem whose cost is cheapest at rest returned a do-nothing plan marked
    "converged, verification PASSED". It is still physical, but its goals say no."""
    problem = _sliding_particle(lambda tf: {"running_cost": ca.sumsqr(tf.u)},
                                goals=(EndPosition("q_x", 1.0, 0.05), Moves(1e-3)))
    result = solve_contact(problem, _options(), verbose=False)
    assert result.ocp.success and result.verification.passed
    assert not result.success and result.status == "no_motion"
    assert result.task.checks[1].value < 1e-3
    assert "task: no motion" in result.summary()


def test_a_plan_short_of_its_goal_is_goal_missed():
    """The same particle, pulled to x = 1 by a weak terminal cost against a heavy control
    cost: it slides, but stops short (measured about 0.1 m)."""
    def costs(tf):
        x = tf.y[tf.q_index][0]
        return {"running_cost": ca.sumsqr(tf.u), "terminal_cost": 50 * (x - 1) ** 2}

    problem = _sliding_particle(costs, goals=(EndPosition("q_x", 1.0, 0.05), Progress("q_x", 0.01)))
    result = solve_contact(problem, _options(), verbose=False)
    assert result.ocp.success and result.verification.passed
    assert result.status == "goal_missed" and not result.success
    end, progress = result.task.checks
    assert not end.passed and progress.passed
    assert 0.05 < end.value < 1.0


def test_a_control_guess_reaches_the_solver():
    """With IPOPT stopped after one iteration per NLP the plan's controls still follow
    the guess (sign and size; measured -8.6, -2.8, 3.6, 6.2 from -10, -6, 5, 8), while
    from the default guess (zero) they stay near zero."""
    guess = np.column_stack([[-12.0, -6.0, 5.0, 8.0], np.zeros(4)])
    guessed = solve_contact(_sliding_particle(control_guess=guess), _options(max_iter=1),
                            verbose=False)
    default = solve_contact(_sliding_particle(), _options(max_iter=1), verbose=False)
    assert np.array_equal(np.sign(guessed.u[:, 0]), np.sign(guess[:, 0]))
    assert np.all(np.abs(guessed.u[:, 0]) > 2.0)
    assert np.all(np.abs(default.u[:, 0]) < 0.5)
    flat = _sliding_particle(control_guess=[3.0, 0.0])
    assert flat.control_guess.shape == (4, 2)


def test_end_height_needs_the_contact_resting_at_the_height():
    """The lowest point z_low = z - 0.02 of a foot under the second coordinate: ending at
    z = 0.07 with gap 0 rests on a 5 cm top; at 0.05 it is on the ground below (2 cm off);
    with gap 3 mm at T it is not resting."""
    from tfcontact.ocp.goals import EndHeight

    def lowest(q):
        return q[1] - 0.02

    goal = EndHeight(0, 0.05, 0.01, lowest)
    t = np.linspace(0.0, 1.0, 3)

    def motion(z_end, gap_end):
        return Motion(t=t, q=np.array([[0.0, 0.3], [0.5, 0.4], [1.0, z_end]]),
                      gaps=np.array([[0.0], [0.1], [gap_end]]), names=("x", "z"))

    on_top = goal.check(motion(0.07, 0.0))
    assert on_top.passed and on_top.value == pytest.approx(0.0, abs=1e-15)
    below = goal.check(motion(0.05, 0.0))
    assert not below.passed and below.value == pytest.approx(0.02)
    assert not goal.check(motion(0.07, 0.003)).passed
    assert check_goals([goal], motion(0.05, 0.0)).status == "goal_missed"
    with pytest.raises(InvalidInput, match="`lowest` must be a function"):
        EndHeight(0, 0.05, 0.01, 0.3)
    with pytest.raises(InvalidInput, match="Clearance names contact 1"):
        EndHeight(1, 0.05, 0.01, lowest).validate(("x", "z"), 1)
