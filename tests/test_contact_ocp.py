"""The contact OCP's statement: what it accepts, what it rejects, what it transcribes."""

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.ocp import ContactProblem, ContactSolverOptions
from tfcontact.ocp.contact import perturbed_guess, solve_contact, transcribe
from tfcontact.scenes.particles import painleve_rod, point_mass
from tfcontact.timefreezing import time_freeze, with_speed_of_time
from tfcontact.verify import defect_segments, painleve_note


@pytest.fixture
def particle():
    return time_freeze(point_mass(2, mu=0.6, a_n=9.81, controlled=True))


def test_transcription_adds_speed_of_time_cost_state_and_clock_constraints(particle):
    u = particle.u
    problem = ContactProblem(system=particle, q0=[0, 1.5], v0=[0, 0], horizon=2.0,
                             n_intervals=4, running_cost=u[0] ** 2, u_lower=-10, u_upper=10,
                             speed_of_time=(1.0, 5.0))
    ocp, system = transcribe(problem)
    assert system.speed_of_time_index == 2 and system.cost_index is not None
    np.testing.assert_allclose(ocp.u_lower, [-10, -10, 1.0])
    np.testing.assert_allclose(ocp.u_upper, [10, 10, 5.0])
    # The clock is pinned to k T / N at every interval boundary.
    for k in range(1, 5):
        con = ocp.boundary_constraints(k, system.y)
        value = ca.Function("c", [system.y], [con.expression])(np.zeros(system.n_y))
        np.testing.assert_allclose(float(value), -k * 2.0 / 4)
        assert con.lower == con.upper == 0.0
    np.testing.assert_allclose(ocp.x0[system.q_index], [0, 1.5])
    assert ocp.x0[system.clock_index] == 0.0 and ocp.x_lower[system.clock_index] == 0.0


def test_bad_contact_problems_are_named(particle):
    base = dict(system=particle, q0=[0, 1], v0=[0, 0], horizon=1.0, n_intervals=4)
    with pytest.raises(InvalidInput, match="`horizon` must be a positive time"):
        ContactProblem(**{**base, "horizon": -1.0})
    with pytest.raises(InvalidInput, match="`n_intervals` must be a positive integer"):
        ContactProblem(**{**base, "n_intervals": 0})
    with pytest.raises(InvalidInput, match="`speed_of_time` must be"):
        ContactProblem(**{**base, "speed_of_time": (2.0, 1.0)})
    with pytest.raises(InvalidInput, match="`q0` has 3 entries, expected 2"):
        ContactProblem(**{**base, "q0": [0, 1, 2]})
    with pytest.raises(InvalidInput, match="already has a speed of time"):
        ContactProblem(**{**base, "system": with_speed_of_time(particle)})
    with pytest.raises(InvalidInput, match="`running_cost` must be a scalar"):
        ContactProblem(**{**base, "running_cost": particle.u})
    with pytest.raises(InvalidInput, match="`verify` must be a VerifyOptions, got 'auto'"):
        ContactSolverOptions(verify="auto")
    with pytest.raises(InvalidInput, match="`attempts` must be a positive integer"):
        ContactSolverOptions(attempts=0)
    with pytest.raises(InvalidInput, match="`attempts` must be a positive integer"):
        ContactSolverOptions(attempts=True)
    with pytest.raises(InvalidInput, match="`restart_noise` must be a positive number"):
        ContactSolverOptions(restart_noise=-1e-4)
    for seed in (-1, 1.5, True):
        with pytest.raises(InvalidInput, match="`first_seed` must be an integer >= 0"):
            solve_contact(ContactProblem(**base), first_seed=seed, verbose=False)
    # counts from numpy are counts too (one check for every layer, `positive_int`)
    assert ContactSolverOptions(attempts=np.int64(2)).attempts == 2
    assert ContactProblem(**{**base, "n_intervals": np.int64(4)}).n_intervals == 4


def test_a_restart_perturbs_the_guess_but_not_the_start_state(particle):
    """The restart's guess: seeded Gaussian noise on the boundary states after x0 and on
    the controls, clipped to the bounds (the clock's lower bound 0 keeps it >= 0)."""
    u = particle.u
    problem = ContactProblem(system=particle, q0=[0, 1.5], v0=[0, 0], horizon=2.0,
                             n_intervals=40, running_cost=u[0] ** 2, u_lower=-10, u_upper=10,
                             speed_of_time=(1.0, 5.0))
    ocp, system = transcribe(problem)
    one = perturbed_guess(ocp, 1e-3, seed=1)
    assert one.x_guess.shape == (41, ocp.x0.size) and one.u_guess.shape == (40, 3)
    np.testing.assert_array_equal(one.x_guess[0], ocp.x0)
    step = one.x_guess[1:, system.q_index] - ocp.x0[system.q_index]
    assert 0.5e-3 < step.std() < 2e-3 and np.abs(step).max() < 1e-2
    assert np.all(one.x_guess[:, system.clock_index] >= 0.0)
    assert np.all(one.u_guess[:, 2] >= 1.0)  # speed of time >= s_min
    np.testing.assert_array_equal(perturbed_guess(ocp, 1e-3, seed=1).x_guess, one.x_guess)
    assert not np.array_equal(perturbed_guess(ocp, 1e-3, seed=2).x_guess, one.x_guess)


def test_local_defect_segments_run_past_boundaries_without_a_physical_state():
    """Two finite elements per interval; True marks a frozen element (clock at rest)."""
    running = np.zeros(6, dtype=bool)
    assert defect_segments(np.array([0.0, 1.0, 2.0, 3.0]), running) == [(0, 1), (1, 2), (2, 3)]
    # an impact across boundary 1 (frozen on both sides): no physical state there
    impact = running.copy()
    impact[[1, 2]] = True
    assert defect_segments(np.array([0.0, 1.0, 2.0, 3.0]), impact) == [(0, 2), (2, 3)]
    # frozen only before boundary 1: the impact ends on it, the state there is physical
    assert defect_segments(np.array([0.0, 1.0, 2.0, 3.0]), np.eye(6, dtype=bool)[1]) == [
        (0, 1), (1, 2), (2, 3)]
    # an interval the clock does not move in adds nothing, inside or at the end
    assert defect_segments(np.array([0.0, 1.0, 1.0, 2.0]), running) == [(0, 1), (1, 3)]
    assert defect_segments(np.array([0.0, 1.0, 2.0, 2.0]), running) == [(0, 1), (1, 3)]


def test_painleve_note_names_the_ill_posed_closed_samples():
    """The verification's note counts the closed samples inside the Painleve band (rod,
    mu = 2: theta = 1 rad is inside, 0.2 rad is not); open samples and well-posed
    contacts give no note."""
    rod = painleve_rod(mu=2.0)
    q = np.array([[0.0, 0.5 * np.sin(a), a] for a in (0.2, 1.0, 1.0, 1.1)])
    closed = np.array([[True], [True], [False], [True]])
    note = painleve_note(rod, q, closed)
    assert note is not None and "contact 'end' at 2 of 3 closed samples" in note
    margin_at_1 = (1 + 3 * np.cos(1.0) ** 2 - 6 * np.sin(1.0) * np.cos(1.0)) / 2
    margin_at_11 = (1 + 3 * np.cos(1.1) ** 2 - 6 * np.sin(1.1) * np.cos(1.1)) / 2
    assert f"down to {min(margin_at_1, margin_at_11):.3g}" in note
    assert painleve_note(rod, q[:1], closed[:1]) is None
    assert painleve_note(rod, q, np.zeros_like(closed)) is None
    assert painleve_note(painleve_rod(mu=0.5), q, closed) is None


def test_the_failed_attempt_nearest_success_is_returned():
    """A failed plan's result is its best solve, not its last: a physical plan that misses
    its task before a converged one that fails its checks, before a failed homotopy;
    among equals the smallest end-state deviation (NaN last), then the earliest."""
    from tfcontact.ocp.contact import Attempt, nearest_success

    def attempt(status: str, deviation: float) -> Attempt:
        return Attempt(None, status, 10, 1.0, 0.1, deviation)

    assert nearest_success([attempt("nlp_failed", 0.1), attempt("verification_failed", 3.0),
                            attempt("not_converged", 0.01)]) == 1
    assert nearest_success([attempt("verification_failed", 0.5),
                            attempt("goal_missed", 9.0)]) == 1
    assert nearest_success([attempt("verification_failed", np.nan),
                            attempt("verification_failed", 2.0),
                            attempt("verification_failed", 0.9)]) == 2
    assert nearest_success([attempt("nlp_failed", 0.2), attempt("nlp_failed", 0.2)]) == 0
    assert nearest_success([attempt("no_motion", 1.0), attempt("converged", 1e-6)]) == 1
    with pytest.raises(InvalidInput, match="no solve to choose from"):
        nearest_success([])


def test_a_periodicity_repeats_the_named_states_at_the_interval_boundaries(particle):
    """`Periodicity`: the boundary hook adds y_i(t_k) - y_i(t_k - P) for the named states
    (q or v indices mapped into the time-freezing state) from boundary first + P on, the
    start state itself where the period begins at 0; bad periods are refused."""
    from tfcontact.ocp import Periodicity

    def hook_rows(periodicity):
        problem = ContactProblem(system=particle, q0=[0.0, 1.0], v0=[0.5, 0.0],
                                 horizon=1.0, n_intervals=5, periodicity=periodicity)
        ocp, tf = transcribe(problem)
        rng = np.random.default_rng(0)
        ys = [rng.standard_normal(tf.n_y) for _ in range(6)]
        ys[0] = ocp.x0
        symbols = [ca.SX.sym(f"y{k}", tf.n_y) for k in range(1, 6)]
        rows = []
        for k, y in enumerate(symbols, start=1):
            con = ocp.boundary_constraints(k, y)
            value = ca.Function("c", symbols, [con.expression])(*ys[1:])
            rows.append(np.asarray(value).ravel())
        return tf, ys, rows

    tf, ys, rows = hook_rows(Periodicity(states=(1, 2), period=2, first=1))
    z, v_x = np.arange(tf.n_y)[tf.q_index][1], np.arange(tf.n_y)[tf.v_index][0]
    assert [r.size for r in rows] == [1, 1, 3, 3, 3]  # the clock row, then 2 repeated
    for k in (3, 4, 5):
        np.testing.assert_allclose(rows[k - 1][1:], [ys[k][z] - ys[k - 2][z],
                                                     ys[k][v_x] - ys[k - 2][v_x]])
    tf, ys, rows = hook_rows(Periodicity(states=(0,), period=5))
    x = np.arange(tf.n_y)[tf.q_index][0]
    assert rows[4][1] == pytest.approx(ys[5][x] - 0.0)  # x(T) - x(0), the start's
    for bad, message in (
            (Periodicity(states=(4,), period=2), r"must index x = \(q, v\) of 4 entries"),
            (Periodicity(states=(0,), period=3, first=3), "passes the last boundary N = 5")):
        with pytest.raises(InvalidInput, match=message):
            ContactProblem(system=particle, q0=[0.0, 1.0], v0=[0.0, 0.0], horizon=1.0,
                           n_intervals=5, periodicity=bad)
    with pytest.raises(InvalidInput, match="needs `stagewise_clock`"):
        ContactProblem(system=particle, q0=[0.0, 1.0], v0=[0.0, 0.0], horizon=1.0,
                       n_intervals=5, stagewise_clock=False,
                       periodicity=Periodicity(states=(0,), period=2))
    with pytest.raises(InvalidInput, match="must be distinct state indices"):
        Periodicity(states=(1, 1), period=2)
    with pytest.raises(InvalidInput, match="`Periodicity.period` must be a positive"):
        Periodicity(states=(1,), period=0)
