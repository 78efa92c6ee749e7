import dataclasses

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput, SolveFailed
from tfcontact.mpcc import (
    Homotopy,
    Ipopt,
    L1Penalty,
    LinfPenalty,
    Mpcc,
    MpccSolver,
    MpccStatus,
    Scholtes,
    solve,
)


def corner_mpcc(target=(1.0, 0.8), extra_g=None):
    """min (x - a)^2 + (y - b)^2 s.t. 0 <= x perp y >= 0: the solution is (a, 0) when a > b."""
    w = ca.SX.sym("w", 2)
    a, b = target
    g = ca.SX(0, 1) if extra_g is None else extra_g(w)
    n_g = g.numel()
    return Mpcc(
        w=w, f=(w[0] - a) ** 2 + (w[1] - b) ** 2, g=g,
        lbg=np.zeros(n_g), ubg=np.zeros(n_g),
        lbw=np.zeros(2), ubw=np.full(2, np.inf), w0=np.array([0.5, 0.5]),
        G=w[0], H=w[1], blocks={"x": np.array([0]), "y": np.array([1])},
    )


@pytest.mark.parametrize("relaxation", [Scholtes(), L1Penalty(), LinfPenalty()])
def test_each_relaxation_reaches_the_mpcc_solution(relaxation):
    result = solve(corner_mpcc(), relaxation=relaxation, homotopy=Homotopy(tolerance=1e-9))
    assert result.status is MpccStatus.CONVERGED
    assert result.residual <= 1e-9
    np.testing.assert_allclose(result.value("x"), [1.0], atol=1e-6)
    np.testing.assert_allclose(result.value("y"), [0.0], atol=1e-6)
    np.testing.assert_allclose(result.objective, 0.8**2, atol=1e-6)
    assert 1 <= result.n_nlps <= Homotopy().n_max
    assert len(result.history) == result.n_nlps
    # each NLP's time splits into function evaluations and IPOPT's own work
    for step in result.history:
        assert 0.0 < step.evaluation_seconds < step.seconds
    assert result.evaluation_time == pytest.approx(
        sum(s.evaluation_seconds for s in result.history))


def test_spral_reaches_the_same_mpcc_solution_as_mumps():
    """IPOPT's other linear solver in the wheel: the same solution, IPOPT told which."""
    results = {name: solve(corner_mpcc(), homotopy=Homotopy(tolerance=1e-9),
                           nlp=Ipopt(linear_solver=name)) for name in ("mumps", "spral")}
    assert all(r.status is MpccStatus.CONVERGED for r in results.values())
    np.testing.assert_allclose(results["spral"].value("x"), results["mumps"].value("x"),
                               atol=1e-7)
    assert Ipopt(linear_solver="spral").casadi_options()["ipopt"]["linear_solver"] == "spral"
    assert "linear_solver" not in Ipopt().casadi_options()["ipopt"]  # IPOPT's default


def test_scholtes_needs_sigma_below_tolerance():
    # Scholtes keeps the products at sigma while both factors want to be positive,
    # so it stops only once sigma <= tolerance: ceil(log(1e-6)/log(0.1)) + 1 NLPs.
    result = solve(corner_mpcc(target=(1.0, 1.0)), homotopy=Homotopy(tolerance=1e-6))
    assert result.success
    assert result.n_nlps >= 6


def test_parameters_and_repeated_solves_reuse_one_build():
    w = ca.SX.sym("w", 2)
    p = ca.SX.sym("p")
    mpcc = Mpcc(w=w, f=(w[0] - p) ** 2 + (w[1] + p) ** 2, g=ca.SX(0, 1), lbg=[], ubg=[],
                lbw=np.zeros(2), ubw=np.full(2, np.inf), w0=np.ones(2), G=w[0], H=w[1], p=p)
    solver = MpccSolver(mpcc, relaxation=LinfPenalty())
    for target in (2.0, -3.0):
        result = solver.solve(p=[target])
        assert result.success
        # x = max(p, 0), y = max(-p, 0): the projection of (p, -p) on the complementarity set
        np.testing.assert_allclose(result.w, [max(target, 0), max(-target, 0)], atol=1e-6)


def test_intermediate_tol_solves_only_the_stepping_stones_loosely():
    homotopy = Homotopy(tolerance=1e-6)
    tight = solve(corner_mpcc(), homotopy=homotopy)
    loose = solve(corner_mpcc(), homotopy=homotopy, nlp=Ipopt(intermediate_tol=1e-2))
    assert loose.status is MpccStatus.CONVERGED
    np.testing.assert_allclose(loose.w, tight.w, atol=1e-6)
    # sigma = 1, 0.1, ..., 1e-5 are stepping stones; sigma = 1e-6 meets the tolerance
    assert [step.intermediate for step in loose.history] == [True] * 6 + [False]
    assert loose.history[-1].sigma == pytest.approx(1e-6)
    # a loosely solved stepping stone is off the relaxed NLP's solution by more than `tol`
    assert abs(loose.history[0].objective - tight.history[0].objective) > 1e-9


def test_intermediate_tol_with_a_quasi_newton_hessian():
    # no exact Hessian to share with the stepping stones' IPOPT instance
    nlp = Ipopt(intermediate_tol=1e-2, options={"hessian_approximation": "limited-memory"})
    result = solve(corner_mpcc(), homotopy=Homotopy(tolerance=1e-6), nlp=nlp)
    assert result.status is MpccStatus.CONVERGED
    np.testing.assert_allclose(result.w, [1.0, 0.0], atol=1e-5)


def test_a_stepping_stone_that_meets_the_tolerance_is_solved_again_to_tol():
    # y wants to be negative, so y = 0 already at sigma = 1: the first (loose) NLP meets
    # the homotopy's tolerance, and the same sigma is solved again to IPOPT's `tol`.
    result = solve(corner_mpcc(target=(1.0, -0.5)), homotopy=Homotopy(tolerance=1e-2),
                   nlp=Ipopt(intermediate_tol=1e-2))
    assert result.status is MpccStatus.CONVERGED
    assert [(s.sigma, s.intermediate) for s in result.history] == [(1.0, True), (1.0, False)]
    assert result.history[-1].residual < result.history[0].residual
    np.testing.assert_allclose(result.w, [1.0, 0.0], atol=1e-8)


def test_the_homotopy_solves_each_nlp_with_the_blas_threads_it_is_given(monkeypatch):
    """`Ipopt.blas_threads`: IPOPT's path depends on CasADi's OpenBLAS thread count, which
    the environment sets (OMP_NUM_THREADS=1 sent biped-walk-short's discovery to a plan
    short of its goal); each NLP runs with the count given, whatever the process had, and
    the count is restored after; None leaves the process's own."""
    from contextlib import contextmanager

    import tfcontact.mpcc.solver as solver_module
    from tfcontact.native import blas_threads, casadi_openblas

    lib = casadi_openblas()
    if lib is None:
        pytest.skip("CasADi has no bundled OpenBLAS here")
    seen = []
    real = solver_module.blas_threads

    @contextmanager
    def recording(n):
        with real(n):
            seen.append(int(lib.openblas_get_num_threads()))
            yield

    monkeypatch.setattr(solver_module, "blas_threads", recording)
    homotopy = Homotopy(tolerance=1e-6)
    with blas_threads(1):  # as OMP_NUM_THREADS=1 leaves it
        fixed = solve(corner_mpcc(), homotopy=homotopy)
        assert seen == [2] * fixed.n_nlps  # the default
        assert lib.openblas_get_num_threads() == 1
        seen.clear()
        solve(corner_mpcc(), homotopy=homotopy, nlp=Ipopt(blas_threads=None))
        assert set(seen) == {1}
    seen.clear()
    with blas_threads(2):
        solve(corner_mpcc(), homotopy=homotopy, nlp=Ipopt(blas_threads=1))
        assert set(seen) == {1} and lib.openblas_get_num_threads() == 2
    with pytest.raises(InvalidInput, match="`blas_threads` must be a positive integer"):
        Ipopt(blas_threads=0)


def test_warm_start_push_starts_later_nlps_from_the_last_multipliers():
    homotopy = Homotopy(tolerance=1e-6)
    cold = solve(corner_mpcc(), homotopy=homotopy)
    warm = solve(corner_mpcc(), homotopy=homotopy, nlp=Ipopt(warm_start_push=1e-9))
    assert warm.status is MpccStatus.CONVERGED
    np.testing.assert_allclose(warm.w, cold.w, atol=1e-5)
    assert [s.warm_started for s in warm.history] == [False] + [True] * (warm.n_nlps - 1)
    assert not any(s.warm_started for s in cold.history)
    # IPOPT got the multipliers: the last NLPs start next to their solutions (measured:
    # 3 iterations each instead of 6)
    assert sum(warm.iterations[-3:]) < sum(cold.iterations[-3:])
    options = Ipopt(warm_start_push=1e-9).casadi_options(warm=True)["ipopt"]
    assert options["warm_start_init_point"] == "yes"
    assert options["warm_start_bound_push"] == options["warm_start_mult_bound_push"] == 1e-9
    assert "warm_start_init_point" not in Ipopt(warm_start_push=1e-9).casadi_options()["ipopt"]


def test_warm_start_push_with_intermediate_tol():
    # four IPOPT instances: (stepping stone or not) x (warm started or not)
    result = solve(corner_mpcc(), homotopy=Homotopy(tolerance=1e-6),
                   nlp=Ipopt(intermediate_tol=1e-2, warm_start_push=1e-9))
    assert result.status is MpccStatus.CONVERGED
    assert [(s.intermediate, s.warm_started) for s in result.history] == \
        [(True, False)] + [(True, True)] * 5 + [(False, True)]
    np.testing.assert_allclose(result.w, [1.0, 0.0], atol=1e-5)


def test_infeasible_problem_is_reported_not_marked_successful():
    mpcc = corner_mpcc(extra_g=lambda w: w[0] + w[1] + 1.0)  # x + y = -1 with x, y >= 0
    result = solve(mpcc, throw=False, homotopy=Homotopy(max_nlps=2))
    assert not result.success
    assert result.status is MpccStatus.NLP_FAILED
    assert "Infeasible" in result.ipopt_status or "Restoration" in result.ipopt_status
    with pytest.raises(SolveFailed, match="NLP failed") as info:
        solve(mpcc, homotopy=Homotopy(max_nlps=2))
    assert info.value.result is not None


def test_bad_input_is_named():
    with pytest.raises(InvalidInput, match="`kappa` must lie in"):
        Homotopy(kappa=1.5)
    with pytest.raises(InvalidInput, match="`sigma_0` must be positive"):
        Homotopy(sigma_0=0.0)
    with pytest.raises(InvalidInput, match="`max_refinements` must be a non-negative integer"):
        Homotopy(max_refinements=-1)
    with pytest.raises(InvalidInput, match="`intermediate_tol` must be a finite number >= `tol`"):
        Ipopt(tol=1e-8, intermediate_tol=1e-9)
    with pytest.raises(InvalidInput, match="`intermediate_tol`"):
        Ipopt(intermediate_tol=float("nan"))
    for bad in (0.0, 0.5, True, float("nan"), "1e-9"):
        with pytest.raises(InvalidInput, match="`warm_start_push` must be a number in"):
            Ipopt(warm_start_push=bad)
    with pytest.raises(InvalidInput, match="`warm_start_bound_push` is set by"):
        Ipopt(warm_start_push=1e-9, options={"warm_start_bound_push": 1e-3})
    with pytest.raises(InvalidInput, match="no `warm_start_push`"):
        Ipopt().casadi_options(warm=True)
    with pytest.raises(InvalidInput, match=r"`linear_solver` must be one of 'mumps', "
                                           r"'spral' .*got 'ma57'"):
        Ipopt(linear_solver="ma57")
    with pytest.raises(InvalidInput, match="give `linear_solver` as a field of Ipopt"):
        Ipopt(options={"linear_solver": "spral"})
    w = ca.SX.sym("w", 2)
    with pytest.raises(InvalidInput, match="`lbw` has 1 entries, expected 2"):
        Mpcc(w=w, f=w[0], g=ca.SX(0, 1), lbg=[], ubg=[], lbw=[0], ubw=[1, 1], w0=[0, 0],
             G=w[0], H=w[1])
    with pytest.raises(InvalidInput, match="`G` and `H` must have equal length"):
        Mpcc(w=w, f=w[0], g=ca.SX(0, 1), lbg=[], ubg=[], lbw=[0, 0], ubw=[1, 1], w0=[0, 0],
             G=w, H=w[1])
    with pytest.raises(InvalidInput, match="`relaxation` must be a Relaxation"):
        MpccSolver(corner_mpcc(), relaxation="scholtes")
    with pytest.raises(InvalidInput, match="pass `p`|`p` has"):
        MpccSolver(corner_mpcc()).solve(p=[1.0])


class _ShortStepsOnly(MpccSolver):
    """A solver whose NLPs 'fail' (IPOPT's status replaced, the iterate spoilt) when sigma
    drops by more than 20x below the last solved NLP's: a warm start that only carries
    short steps. It records each NLP's sigma, starting point and returned iterate."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.last_solved = 1.0  # sigma_0: the first NLP solves
        self.calls: list[tuple[float, np.ndarray, np.ndarray]] = []

    def _solve_nlp(self, x, lam_g, p, sigma, intermediate):
        start = x.copy()
        x, lam_g, step, violation = super()._solve_nlp(x, lam_g, p, sigma, intermediate)
        if self.last_solved / sigma > 20:
            x = x + 0.3
            step = dataclasses.replace(step, ipopt_status="Restoration_Failed")
        else:
            self.last_solved = sigma
        self.calls.append((sigma, start, x.copy()))
        return x, lam_g, step, violation


def test_refinement_cuts_a_failed_step_and_warm_starts_from_the_last_solved_nlp():
    homotopy = Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4, max_refinements=3)
    solver = _ShortStepsOnly(corner_mpcc())
    result = solver.solve(homotopy=homotopy)
    assert result.status is MpccStatus.CONVERGED
    np.testing.assert_allclose(result.w, [1.0, 0.0], atol=1e-5)
    sigmas = [s.sigma for s in result.history]
    # 1; 1e-2 fails, 1e-1 (midpoint) and 1e-2; 1e-4 fails, 1e-3 and 1e-4; 1e-6 fails,
    # 1e-5 and 1e-6: three refinements, none counted against `max_nlps`
    np.testing.assert_allclose(sigmas, [1, 1e-2, 1e-1, 1e-2, 1e-4, 1e-3, 1e-4, 1e-6, 1e-5,
                                        1e-6], rtol=1e-12)
    assert [s.refined for s in result.history] == [False] + [False, True, False] * 3
    assert [s.ipopt_status == "Restoration_Failed" for s in result.history] == (
        [False] + [True, False, False] * 3)
    # the refined NLP starts where the last solved one ended, not at the spoilt iterate
    np.testing.assert_array_equal(solver.calls[2][1], solver.calls[0][2])
    np.testing.assert_array_equal(solver.calls[3][1], solver.calls[2][2])


def test_without_refinement_a_failed_step_is_followed_from_its_iterate():
    solver = _ShortStepsOnly(corner_mpcc())
    result = solver.solve(homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4))
    assert result.status is MpccStatus.NLP_FAILED
    assert [s.sigma for s in result.history] == pytest.approx([1, 1e-2, 1e-4, 1e-6])
    # the plain schedule goes on from the failed NLP's (spoilt) iterate
    np.testing.assert_array_equal(solver.calls[2][1], solver.calls[1][2])
    # once the refinements are used up, the schedule goes on as without them
    solver = _ShortStepsOnly(corner_mpcc())
    result = solver.solve(homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4,
                                            max_refinements=1))
    assert result.status is MpccStatus.NLP_FAILED
    # 1; 1e-2 fails, 1e-1 (the one refinement) and 1e-2 solve; 1e-4 fails and the plain
    # schedule goes on from its iterate to 1e-6, which fails too
    assert [s.sigma for s in result.history] == pytest.approx([1, 1e-2, 1e-1, 1e-2, 1e-4,
                                                               1e-6])
    assert [s.refined for s in result.history] == [False, False, True, False, False, False]
    np.testing.assert_array_equal(solver.calls[5][1], solver.calls[4][2])


def test_a_homotopy_stops_at_a_failure_when_its_last_solved_nlp_is_acceptable():
    """`accept_residual`: the first failed NLP ends the homotopy when the last solved NLP's
    residual is within it (that iterate reported); a tighter bound goes on as before."""
    plain = _ShortStepsOnly(corner_mpcc()).solve(
        homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4))
    first = plain.history[0].residual  # sigma 1 solved, 1e-2 failed
    assert first > 1e-6
    solver = _ShortStepsOnly(corner_mpcc())
    result = solver.solve(homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4,
                                            accept_residual=2 * first))
    assert result.status is MpccStatus.NLP_FAILED
    assert [s.sigma for s in result.history] == pytest.approx([1, 1e-2])
    np.testing.assert_array_equal(result.w, solver.calls[0][2][: result.w.size])
    assert result.residual == pytest.approx(first)
    tighter = _ShortStepsOnly(corner_mpcc()).solve(
        homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4, accept_residual=first / 2))
    assert [s.sigma for s in tighter.history] == pytest.approx([1, 1e-2, 1e-4, 1e-6])
    # refinements come first: 1e-2 fails, the refined 1e-1 and 1e-2 solve; 1e-4 fails and
    # the last solved NLP (1e-2) is within the bound
    refined = _ShortStepsOnly(corner_mpcc()).solve(
        homotopy=Homotopy(kappa=0.01, tolerance=1e-6, max_nlps=4, max_refinements=1,
                          accept_residual=2 * first))
    assert [s.sigma for s in refined.history] == pytest.approx([1, 1e-2, 1e-1, 1e-2, 1e-4])
    with pytest.raises(InvalidInput, match="`accept_residual` must be None or a number > 0"):
        Homotopy(accept_residual=0.0)


def test_a_homotopy_stops_at_the_first_solved_nlp_within_stop_residual():
    """`stop_residual`: the first solved NLP whose residual is within it ends the homotopy,
    a stepping stone solved to `intermediate_tol` too; the result is that iterate,
    not_converged (its residual above `tolerance`). On the corner MPCC the Scholtes
    relaxation's solution at sigma has x y = sigma, so the NLP where the homotopy stops
    is known."""
    homotopy = Homotopy(kappa=0.1, tolerance=1e-8)
    full = solve(corner_mpcc(), homotopy=homotopy, nlp=Ipopt(intermediate_tol=1e-2))
    assert full.status is MpccStatus.CONVERGED and full.n_nlps > 4
    stopped = solve(corner_mpcc(), homotopy=dataclasses.replace(homotopy, stop_residual=2e-3),
                    nlp=Ipopt(intermediate_tol=1e-2), throw=False)
    assert stopped.status is MpccStatus.NOT_CONVERGED
    assert [s.sigma for s in stopped.history] == pytest.approx([1, 1e-1, 1e-2, 1e-3])
    assert stopped.history[-1].intermediate  # a stepping stone, not solved again tightly
    assert 1e-8 < stopped.residual <= 2e-3
    assert stopped.residual == pytest.approx(stopped.history[-1].residual)
    # the iterate is the loosely solved relaxed NLP at sigma 1e-3: x near 1, x y <= sigma
    x, y = stopped.value("x")[0], stopped.value("y")[0]
    assert x == pytest.approx(1.0, abs=1e-2) and 0 < x * y <= 1e-3 * (1 + 1e-6)
    assert stopped.residual == pytest.approx(x * y)
    # a bound the schedule's last NLP meets anyway changes nothing: converged as before
    same = solve(corner_mpcc(), homotopy=dataclasses.replace(homotopy, stop_residual=1e-8),
                 nlp=Ipopt(intermediate_tol=1e-2))
    assert same.status is MpccStatus.CONVERGED and same.n_nlps == full.n_nlps
    with pytest.raises(InvalidInput, match="`stop_residual` must be None or a number > 0"):
        Homotopy(stop_residual=-1.0)


def test_a_verbose_homotopy_says_where_a_long_nlp_is(monkeypatch, capsys):
    """A verbose solve prints a line inside an NLP when `PROGRESS_SECONDS` have passed
    since its last one (here 0: at every iteration after the first), naming the NLP; a
    quiet solve of the same solver afterwards prints nothing."""
    from tfcontact.mpcc import solver as mpcc_solver

    monkeypatch.setattr(mpcc_solver, "PROGRESS_SECONDS", 0.0)
    solver = MpccSolver(corner_mpcc())
    result = solver.solve(homotopy=Homotopy(tolerance=1e-9), verbose=True)
    out = capsys.readouterr().out
    first = result.history[0].iterations
    assert first >= 2
    assert "      NLP 1: iteration 1, " in out and f"      NLP 1: iteration {first}, " in out
    assert "NLP 1: iteration 0," not in out
    assert "      NLP 2: iteration 1, " in out
    solver.solve(homotopy=Homotopy(tolerance=1e-9))
    assert capsys.readouterr().out == ""


def test_progress_lines_count_from_the_last_line():
    """A line on the clock (a minute since the last) restarts the count of iterations:
    no second line a few iterations later at the next multiple of `every`."""
    from tfcontact.mpcc.solver import IterationProgress

    progress = IterationProgress(every=10, seconds=60.0)
    assert [i for i in range(1, 25) if progress.due(i)] == [10, 20]
    progress = IterationProgress(every=10, seconds=60.0)
    lines = [i for i in range(1, 4) if progress.due(i)]
    progress.last -= 61.0  # a minute passes during iteration 4
    lines += [i for i in range(4, 25) if progress.due(i)]
    assert lines == [4, 14, 24]
