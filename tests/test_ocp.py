"""OCP core: transcription structure, homotopies on an OCP with a switch, failures."""

import time

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput, SolveFailed
from tfcontact.fesd import GaussLegendre, HeavisideSystem, Standard, StewartSystem
from tfcontact.mpcc import Homotopy, L1Penalty, LinfPenalty, MpccStatus, Scholtes
from tfcontact.ocp import Constraint, OptimalControlProblem, Transcription, build, solve

TARGET = 1.5 * np.sqrt(2)
OPTIMAL_COST = 7 - 3 * np.sqrt(2)
OPTIMAL_U = [1, 2 * np.sqrt(2) - 1, 2 * np.sqrt(2) - 1, 2 * np.sqrt(2) - 1]


def controlled_sign_system() -> StewartSystem:
    """x' = 2 - sign(x) + u: x' = 1 + u for x > 0, 3 + u for x < 0."""
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    return StewartSystem.from_sign_matrix(x, u, ca.horzcat(1 + u, 3 + u), x,
                                          np.array([[1], [-1]]))


def min_energy_problem(n_intervals=4, target=TARGET, **kwargs) -> OptimalControlProblem:
    """min int_0^1 u^2 dt s.t. x(1) = target, x(0) = -1.

    In each region u is constant (H = u^2 + p (f + u), p constant): a before the switch at
    t_s = 1/(3 + a), b after, x(1) = (1 + b)(1 - t_s). Moving u before the switch also moves
    t_s, which shifts time between the phases; stationarity of the Lagrangian gives
    (a + 3)^2 = (b + 1)^2 + 8. With a = 1: t_s = 1/4, b = 2 sqrt 2 - 1, x(1) = 1.5 sqrt 2,
    cost 1/4 + 3/4 b^2 = 7 - 3 sqrt 2. With N = 4 intervals this optimum is on the control
    grid, so it is also the optimum of the discrete problem (exact integration).
    """
    sys = controlled_sign_system()
    return OptimalControlProblem(sys, [-1.0], 1.0, n_intervals, lagrange=sys.u[0] ** 2,
                                 terminal=Constraint(sys.x - target), **kwargs)


@pytest.mark.parametrize("relaxation", [Scholtes(), L1Penalty(), LinfPenalty()])
def test_each_relaxation_converges_to_the_closed_form_optimum(relaxation):
    result = solve(min_energy_problem(), relaxation=relaxation, verbose=False)
    assert result.status is MpccStatus.CONVERGED
    assert result.residual <= 1e-9
    assert result.cost == pytest.approx(OPTIMAL_COST, abs=1e-6)
    np.testing.assert_allclose(result.u.ravel(), OPTIMAL_U, atol=1e-5)
    np.testing.assert_allclose(result.switch_times, [0.25], atol=1e-8)
    assert result.x[-1, 0] == pytest.approx(TARGET, abs=1e-9)
    assert result.n_nlps == len(result.iterations) >= 1
    assert result.solve_time > 0 and result.build_time > 0


def test_switch_off_the_grid_lands_on_an_element_boundary():
    # N = 3: the switch of the optimum lies inside the first interval; FESD puts an
    # element boundary at x = 0 and keeps the terminal constraint.
    result = solve(min_energy_problem(n_intervals=3), verbose=False)
    assert result.success
    assert result.switch_times.size == 1
    k = int(np.argmin(np.abs(result.t - result.switch_times[0])))
    assert abs(result.x[k, 0]) <= 1e-8
    nominal = np.linspace(0, 1, 7)
    assert np.min(np.abs(nominal - result.switch_times[0])) > 1e-3
    assert result.x[-1, 0] == pytest.approx(TARGET, abs=1e-9)
    # consistency of the trajectory with the piecewise linear dynamics
    u_elem = np.repeat(result.u.ravel(), 2)
    slope = np.where(result.x[1:, 0] + result.x[:-1, 0] > 0, 1 + u_elem, 3 + u_elem)
    np.testing.assert_allclose(np.diff(result.x[:, 0]), slope * result.h, atol=1e-8)


def test_verbose_prints_one_line_per_nlp(capsys):
    result = solve(min_energy_problem(), relaxation=LinfPenalty(), verbose=True)
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.rstrip().endswith("Solve_Succeeded")]
    assert len(lines) == result.n_nlps
    assert "sigma" in out and "residual" in out


def test_bounds_path_terminal_and_boundary_hook_are_imposed():
    sys = controlled_sign_system()
    prob = OptimalControlProblem(
        sys, [-1.0], 1.0, 4, lagrange=sys.u[0] ** 2,
        u_lower=-2.0, u_upper=2.5, x_upper=2.0,
        path=Constraint(sys.x + 0.1 * sys.u, upper=2.2, lower=-np.inf),
        terminal=Constraint(sys.x, lower=1.8, upper=1.8),
        boundary_constraints=lambda k, xk: Constraint(xk, -0.2, -0.2) if k == 1 else None,
    )
    built = build(prob, discretization=Transcription(scheme=GaussLegendre(2)))
    assert built.mpcc.n_w == built.mpcc.w0.size
    result = solve(built, relaxation=LinfPenalty(), verbose=False)
    assert result.success
    assert np.all(result.u <= 2.5 + 1e-9) and np.all(result.u >= -2 - 1e-9)
    assert result.x_intervals[1, 0] == pytest.approx(-0.2, abs=1e-9)
    assert result.x[-1, 0] == pytest.approx(1.8, abs=1e-9)
    assert np.all(result.x_stages <= 2.0 + 1e-9)
    assert result.t_intervals == pytest.approx([0, 0.25, 0.5, 0.75, 1.0])


def test_heaviside_and_standard_transcriptions_solve():
    x, u, a = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("alpha")
    sys = HeavisideSystem(x=x, u=u, alpha=a, rhs=3 - 2 * a + u, switching=x)
    prob = OptimalControlProblem(sys, [-1.0], 1.0, 4, lagrange=u**2,
                                 terminal=Constraint(x - TARGET))
    result = solve(prob, relaxation=LinfPenalty(), verbose=False)
    assert result.success
    assert result.cost == pytest.approx(OPTIMAL_COST, abs=1e-6)
    standard = solve(prob, relaxation=LinfPenalty(), verbose=False,
                     discretization=Transcription(method=Standard()))
    assert standard.success
    np.testing.assert_allclose(standard.h, 1 / 8)


def test_infeasible_problem_fails_with_ipopts_reason():
    # With |u| <= 1, x(1) <= 1.5 (x' = 4 until t = 1/4, then 2): x(1) = 10 is infeasible.
    prob = min_energy_problem(target=10.0, u_lower=-1.0, u_upper=1.0)
    result = solve(prob, verbose=False, throw=False, homotopy=Homotopy(max_nlps=3))
    assert not result.success
    assert result.status is MpccStatus.NLP_FAILED
    assert "Infeasible" in result.ipopt_status or "Restoration" in result.ipopt_status
    assert result.ipopt_status in result.message
    assert result.x.shape == (9, 1)  # the last iterate is there to inspect
    with pytest.raises(SolveFailed, match="NLP failed") as info:
        solve(prob, verbose=False, homotopy=Homotopy(max_nlps=3))
    assert info.value.result.status is MpccStatus.NLP_FAILED


def test_bad_problem_data_is_rejected():
    sys = controlled_sign_system()
    with pytest.raises(InvalidInput, match=r"`x0` has 2 entries, expected n_x = 1"):
        OptimalControlProblem(sys, [0.0, 1.0], 1.0, 4)
    with pytest.raises(InvalidInput, match=r"`n_intervals` must be a positive integer, got 0"):
        OptimalControlProblem(sys, [0.0], 1.0, 0)
    with pytest.raises(InvalidInput, match=r"`horizon` must be a positive number"):
        OptimalControlProblem(sys, [0.0], 0.0, 4)
    with pytest.raises(InvalidInput, match=r"`u_lower` has 2 entries, expected 1"):
        OptimalControlProblem(sys, [0.0], 1.0, 4, u_lower=[0, 1])
    with pytest.raises(InvalidInput, match=r"`u_lower\[0\]` = 1.0 exceeds `u_upper\[0\]`"):
        OptimalControlProblem(sys, [0.0], 1.0, 4, u_lower=1.0, u_upper=0.0)
    with pytest.raises(InvalidInput, match=r"`mayer` depends on symbols \['u'\]"):
        OptimalControlProblem(sys, [0.0], 1.0, 4, mayer=sys.u[0])
    with pytest.raises(InvalidInput, match=r"`x_guess` must have shape \(1,\) or \(N \+ 1"):
        OptimalControlProblem(sys, [0.0], 1.0, 4, x_guess=np.zeros((3, 1)))
    with pytest.raises(InvalidInput, match=r"`n_finite_elements` must be a positive integer"):
        Transcription(n_finite_elements=0)
    with pytest.raises(InvalidInput, match=r"unknown `scheme`"):
        build(min_energy_problem(), discretization=Transcription(scheme="gauss"))


def test_constraint_bounds_default_to_equality_or_one_sided():
    x = ca.SX.sym("x", 2)
    eq = Constraint(x)
    np.testing.assert_array_equal(eq.lower, [0, 0])
    np.testing.assert_array_equal(eq.upper, [0, 0])
    low = Constraint(x, lower=1.0)
    np.testing.assert_array_equal(low.upper, [np.inf, np.inf])
    up = Constraint(x, upper=[1.0, 2.0])
    np.testing.assert_array_equal(up.lower, [-np.inf, -np.inf])
    with pytest.raises(InvalidInput, match=r"`lower\[1\]` = 3.0 exceeds `upper\[1\]` = 2.0"):
        Constraint(x, lower=[0.0, 3.0], upper=[1.0, 2.0])
    with pytest.raises(InvalidInput, match=r"`upper` has 3 entries, expected 2"):
        Constraint(x, upper=[1.0, 2.0, 3.0])


def test_a_constraints_rows_keep_their_bounds():
    x = ca.SX.sym("x", 3)
    both = Constraint(2 * x, lower=[0.0, -1.0, -2.0], upper=[1.0, 2.0, 3.0])
    kept = both.rows([2, 0])
    value = ca.Function("kept", [x], [kept.expression])([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(np.asarray(value).ravel(), [6.0, 2.0])
    np.testing.assert_array_equal(kept.lower, [-2.0, 0.0])
    np.testing.assert_array_equal(kept.upper, [3.0, 1.0])
    assert both.rows([]) is None
    with pytest.raises(InvalidInput, match=r"row indices \[3\] outside the constraint's 3"):
        both.rows([3])


def test_trajectory_guess_is_interpolated_with_consistent_algebraic_variables():
    prob = min_energy_problem(x_guess=np.array([[-1.0], [0.5], [1.0], [2.0], [3.0]]),
                              u_guess=[1.0, 2.0, 2.0, 2.0])
    built = build(prob)
    w0, lay = built.mpcc.w0, built.discretization.layout
    np.testing.assert_allclose(w0[lay.x[::2]].ravel(), [-1.0, 0.5, 1.0, 2.0, 3.0])
    # theta is mode 1 (x > 0) where the guess is positive, mode 2 where negative
    theta = w0[lay.z["theta"]]
    xs = w0[lay.x_stages][..., 0]
    off = xs != 0  # one stage point sits on the switching surface: either mode
    np.testing.assert_allclose(theta[..., 0][off], (xs[off] > 0).astype(float))
    result = solve(built, relaxation=LinfPenalty(), verbose=False)
    assert result.cost == pytest.approx(OPTIMAL_COST, abs=1e-6)


@pytest.mark.slow
def test_build_time_scales_linearly_in_the_horizon():
    times = {}
    for n in (20, 80):
        start = time.perf_counter()
        built = build(min_energy_problem(n_intervals=n),
                      discretization=Transcription(n_finite_elements=3))
        times[n] = time.perf_counter() - start
        assert built.mpcc.n_comp == n * 3 * 2 * 2
    assert times[80] < 8 * times[20] + 0.05
