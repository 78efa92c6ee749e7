"""Contact OCPs with balls and particles (PROBLEMS.md TF-1, TF-2, TF-3), reduced for CI.

Fast tests check the ball-in-box time-freezing system against closed forms; the slow
ones solve reduced versions of the three OCPs end to end and require the independent
verification (`ContactResult.success`) to pass.
"""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.fesd import GaussLegendre, RadauIIA, simulate
from tfcontact.mpcc import Homotopy, Ipopt, LinfPenalty
from tfcontact.ocp.contact import ContactProblem, ContactSolverOptions, solve_contact
from tfcontact.plan_format import load_trajectory
from tfcontact.plan_format.adapters import trajectory_from_result
from tfcontact.scenes.ball_in_box import TF2_WALLS, WALLS, ball_in_box
from tfcontact.scenes.particle_ocps import (
    BALL_ROBOT,
    box_circle_options,
    box_circle_problem,
    particle_friction_problem,
    throwing_ball_problem,
)
from tfcontact.viz.plan import save_plan

# ---------------------------------------------------------------- the box, fast


def _active_region(tf, q, v) -> str:
    """The region whose indicator is smallest at (q, v, t = 0)."""
    g = ca.Function("g", [tf.y], [tf.pss.indicators])(np.r_[q, v, 0.0])
    return tf.region_names[int(np.argmin(np.asarray(g).ravel()))]


@pytest.mark.parametrize(("q", "region"), [
    ((0.0, 0.0), "interior"),
    ((0.0, -1.06), "bottom"),
    ((1.11, 0.0), "right"),
    ((0.0, 1.16), "top"),
    ((-1.21, 0.0), "left"),
    ((1.11, -1.06), "bottom_right"),
    ((1.11, 1.16), "right_top"),
    ((-1.21, 1.16), "top_left"),
    ((-1.21, -1.06), "left_bottom"),
])
def test_box_regions(q, region):
    assert _active_region(ball_in_box(), np.array(q), np.zeros(2)) == region


def test_box_modes_are_springs_along_the_wall_normals():
    k = 100.0
    tf = ball_in_box(stiffness=k)
    modes = tf.function()
    y = np.array([1.13, 0.2, 0.7, -0.4, 0.3])  # 3 cm inside the right wall
    u = np.array([5.0, -3.0])
    f = np.asarray(modes(y, u))
    names = list(tf.region_names)
    np.testing.assert_allclose(f[:, names.index("interior")], [0.7, -0.4, 5.0, -3.0, 1.0])
    # right wall, gap = 1.10 - x: x' = v_x, v_x' = -k (x - 1.10) (e = 1: no damping)
    np.testing.assert_allclose(f[:, names.index("right")], [0.7, 0, -k * 0.03, 0, 0],
                               atol=1e-12)
    np.testing.assert_allclose(f[:, names.index("bottom")], [0, -0.4, 0, -k * (0.2 + 1.05), 0],
                               atol=1e-12)
    corner = names.index("bottom_right")
    np.testing.assert_allclose(
        f[:, corner], f[:, names.index("right")] + f[:, names.index("bottom")])
    assert tf.cls.n_contacts == 4
    assert [c.name for c in tf.cls.contacts] == list(WALLS)


@pytest.mark.slow
def test_box_bounce_closed_form():
    """A ball flying at 1 m/s into the right wall (e = 1) comes back at -1 m/s after a
    frozen half period pi / sqrt(k) of numerical time (Radau IIA order 5: measured error
    5e-8; order 3 gives 2e-4 and 2.5e-5 with twice the steps, the slope 3)."""
    k = 100.0
    tf = ball_in_box(stiffness=k)
    tau_end = 0.6
    sim = simulate(tf.pss, np.array([1.0, 0.0, 1.0, 0.0, 0.0]), horizon=tau_end, n_steps=12,
                   u=np.zeros(2), scheme=RadauIIA(3), n_finite_elements=3)
    frozen = math.pi / math.sqrt(k)
    t_end = tau_end - frozen
    x_end = 1.10 - (t_end - 0.1)
    np.testing.assert_allclose(sim.x[-1], [x_end, 0.0, -1.0, 0.0, t_end], atol=1e-6)
    assert sim.x[:, 0].max() > 1.10 + 0.09  # it went 1 / sqrt(k) = 0.1 m into the wall


def test_box_bad_input():
    with pytest.raises(InvalidInput, match="`walls` must be four positive"):
        ball_in_box((1.0, -1.0, 1.0, 1.0))
    with pytest.raises(InvalidInput, match="`stiffness` must be a finite number > 0"):
        ball_in_box(stiffness=0.0)
    with pytest.raises(InvalidInput, match="`restitution` must be in"):
        ball_in_box(restitution=0.0)
    with pytest.raises(InvalidInput, match="`omega` must be a non-zero"):
        box_circle_problem(0.0)


def test_contact_problem_guess_shape():
    problem = box_circle_problem(math.pi, n_intervals=4)
    assert problem.guess.shape == (5, 4)
    with pytest.raises(InvalidInput, match=r"`guess` must be a finite array .* shape \(5, 4\)"):
        ContactProblem(system=ball_in_box(), q0=[1, 0], v0=[0, 1], horizon=1.0,
                       n_intervals=4, guess=np.zeros((4, 4)))


def test_box_plan_and_bench_settings(load_script):
    """The plan script's settings are `box_circle_options()`, its flags replace one field
    each, and the bench's first variant is the seed's settings (the ratios' base)."""
    plan = load_script("plan_ball_in_box")
    assert plan.plan_options() == box_circle_options()
    options = plan.plan_options("scholtes", 1e-3)
    assert options.relaxation.name == "scholtes"
    assert options.homotopy == dataclasses.replace(box_circle_options().homotopy, sigma_0=1e-3)
    bench = load_script("bench_ball_in_box")
    assert list(bench.VARIANTS)[0] == "seed"
    seed = bench.VARIANTS["seed"]()
    assert seed.homotopy == Homotopy(sigma_0=0.1, tolerance=1e-7)
    assert seed.nlp == ContactSolverOptions().nlp
    assert bench.VARIANTS["chosen: mem50, kappa=0.05"]() == box_circle_options()
    problem = box_circle_problem(3 * math.pi, n_intervals=4)
    moved = bench.perturbed(problem, 1e-9, seed=1)
    np.testing.assert_array_equal(moved.guess[0], problem.guess[0])  # the start stays
    assert 0 < np.max(np.abs(moved.guess - problem.guess)) < 1e-8


# ---------------------------------------------------------------- reduced OCPs, slow


def _box_options() -> ContactSolverOptions:
    # scripts/plan_ball_in_box.py's settings: started on the reference, sigma_0 = 0.1,
    # Gauss-Legendre (Radau IIA's damping of the wall spring was exploited, see there)
    return ContactSolverOptions(scheme=GaussLegendre(2), n_finite_elements=3,
                                relaxation=LinfPenalty(),
                                homotopy=Homotopy(sigma_0=0.1, tolerance=1e-7))


@pytest.mark.slow
def test_box_slow_circle_touches_no_wall(tmp_path):
    """w = pi: exact tracking needs 9.9 N < 50 N, the optimum touches no wall."""
    problem = box_circle_problem(math.pi, n_intervals=8, periods=1.0)
    result = solve_contact(problem, _box_options(), verbose=False)
    assert result.success, result.message
    assert result.physical.impacts == ()
    assert result.verification.min_gap > 0.0
    # replayed with exact impacts on all four walls (measured deviation 3e-10)
    assert result.verification.method.startswith(
        "event-detecting reference (DOP853, exact impacts), 0 impacts")
    assert result.verification.end_state_deviation < 1e-6
    assert result.ocp.n_nlps == 1  # measured: 15 IPOPT iterations
    assert result.ocp.cost < 0.1
    # the plan's file: one robot contact (the ball) for four walls
    traj = trajectory_from_result(result, BALL_ROBOT, {"terrain": {"type": "none"}})
    assert traj.gap.shape == (traj.n_samples, 1)
    assert traj.extras["cls_gaps"].shape == (traj.n_samples, 4)
    np.testing.assert_allclose(traj.gap[:, 0], traj.extras["cls_gaps"].min(axis=1))
    save_plan(result, traj, tmp_path)
    loaded = load_trajectory(tmp_path / "trajectory.npz")
    assert loaded.solver["nlp_count"] == result.ocp.n_nlps
    assert loaded.verification["passed"] is True


@pytest.mark.slow
def test_box_fast_circle_bounces():
    """w = 3 pi: exact tracking needs 88.8 N > 50 N, the ball turns on the walls. Each
    bounce of the plan keeps its speed (e = 1) and the exact four-wall replay of its
    controls agrees (measured: 3 bounces, speed kept to 1e-10, 530 IPOPT iterations,
    end-state deviation 6e-9)."""
    problem = box_circle_problem(3 * math.pi, n_intervals=12, periods=1.0)
    result = solve_contact(problem, _box_options(), verbose=False)
    assert result.success, result.message
    complete = [imp for imp in result.physical.impacts if imp.complete]
    assert len(complete) >= 2
    for imp in complete:
        np.testing.assert_allclose(np.linalg.norm(imp.post[2:4]), np.linalg.norm(imp.pre[2:4]),
                                   rtol=1e-6)
    assert result.verification.method.startswith("event-detecting reference")
    assert result.verification.end_state_deviation < 1e-6
    assert result.verification.min_gap > -1e-8


@pytest.mark.slow
def test_throwing_ball_bounces_to_target():
    """TF-1 reduced (N = 10): Radau IIA with 4 stages resolves the elastic auxiliary
    spring; the plan is checked against the event-detecting simulation with exact
    Newton impacts (measured end-state deviation 7e-4)."""
    problem = throwing_ball_problem(n_intervals=10)
    options = ContactSolverOptions(scheme=RadauIIA(4), n_finite_elements=3,
                                   relaxation=LinfPenalty())
    result = solve_contact(problem, options, verbose=False)
    assert result.ocp.success, result.message
    assert len(result.physical.impacts) >= 1
    np.testing.assert_allclose(result.y[-1, result.system.q_index], [4.0, 0.5], atol=1e-6)
    assert result.verification.method.startswith("event-detecting reference")
    assert result.success, result.message


@pytest.mark.slow
def test_throwing_ball_with_two_stages_is_caught_by_the_verification():
    """With 2 stages the spring is under-resolved and the optimiser profits from the
    integration error (cost 60 against 246 with 4 stages): the check must catch it."""
    problem = throwing_ball_problem(n_intervals=10)
    options = ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=3,
                                   relaxation=LinfPenalty())
    result = solve_contact(problem, options, verbose=False)
    assert result.ocp.success, result.message
    assert result.status == "verification_failed"
    assert result.verification.end_state_deviation > 1.0  # measured 3.2
    # the local defects point at the interval where the plan is wrong (measured: 0.70 in
    # interval 7, 1e-11 in the others that do not start or end inside a bounce)
    defects = np.asarray(result.verification.local_defects)
    assert np.nanmax(defects) > 0.1
    assert np.nanmin(defects) < 1e-9
    assert "largest local defect" in result.verification.summary()


@pytest.mark.slow
def test_particle_friction_reaches_target():
    problem = particle_friction_problem(n_intervals=6)
    options = ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=3,
                                   relaxation=LinfPenalty(), attempts=3)
    result = solve_contact(problem, options, verbose=False)
    assert result.success, result.message
    assert len(result.attempts) == 1  # a plan that succeeds is not solved again
    tf = result.system
    end = np.concatenate([result.y[-1, tf.q_index], result.y[-1, tf.v_index]])
    np.testing.assert_allclose(end, [3.0, 0.0, 0.0, 0.0], atol=1e-6)
    assert len(result.physical.impacts) == 1
    # restarted at every interval from the plan's own state, the exact reference agrees
    # (measured: largest local defect 2e-10)
    defects = np.asarray(result.verification.local_defects)
    assert defects.shape == (6,) and np.all(np.isfinite(defects))
    assert defects.max() < 1e-7


@pytest.mark.slow
def test_unreachable_target_fails_with_reason():
    """x = 30 m in 2 s with |u| <= 10 N is out of reach: a failed status with the reason."""
    problem = particle_friction_problem((30.0, 0.0, 0.0, 0.0), n_intervals=4)
    options = ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=3,
                                   relaxation=LinfPenalty(), nlp=Ipopt(tol=1e-8, max_iter=200),
                                   attempts=2)
    result = solve_contact(problem, options, verbose=False)
    assert not result.success
    assert result.status == "nlp_failed"
    assert "IPOPT did not solve" in result.message
    # the failed plan was solved again from a perturbed guess, and failed again
    assert [(a.seed, a.status) for a in result.attempts] == [(None, "nlp_failed"),
                                                              (1, "nlp_failed")]
    assert result.attempts[result.chosen].iterations == result.ocp.total_iterations
    assert result.timings["solve"] == pytest.approx(
        sum(a.solve_time for a in result.attempts))
    assert "attempt 2: nlp_failed" in result.summary()
    assert result.ocp.ipopt_status in ("Infeasible_Problem_Detected",
                                       "Maximum_Iterations_Exceeded",
                                       "Restoration_Failed")
    # a pipeline's second run of a whole plan solves its discovery from seed 1 on
    # (`first_seed`): the same perturbed guess as the second attempt above
    again = solve_contact(problem, dataclasses.replace(options, attempts=1), first_seed=1,
                          verbose=False)
    assert [(a.seed, a.status) for a in again.attempts] == [(1, "nlp_failed")]
    assert again.ocp.total_iterations == result.attempts[1].iterations


def test_walls_constant():
    assert TF2_WALLS == (1.05, 1.10, 1.15, 1.20)


@pytest.mark.slow
def test_warm_start_from_a_previous_plan():
    """TF-3 reduced: started from its own converged plan the solve takes a few iterations
    and returns the same plan (measured: 30 against 594 iterations); started from it with
    another scheme (3 stages) it converges to a verified plan nearby (measured: 81
    iterations); a plan with another N is refused."""
    problem = particle_friction_problem(n_intervals=6)
    options = ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=3,
                                   relaxation=LinfPenalty())
    cold = solve_contact(problem, options, verbose=False)
    assert cold.success, cold.message
    low = Homotopy(sigma_0=1e-3)
    again = solve_contact(problem, dataclasses.replace(options, homotopy=low),
                          initial_guess=cold, verbose=False)
    assert again.success, again.message
    assert again.ocp.total_iterations < cold.ocp.total_iterations / 5
    np.testing.assert_allclose(again.y, cold.y, atol=1e-6)
    finer = solve_contact(problem, dataclasses.replace(options, scheme=RadauIIA(3), homotopy=low),
                          initial_guess=cold, verbose=False)
    assert finer.success, finer.message
    assert finer.ocp.total_iterations < cold.ocp.total_iterations / 2
    # a system whose NLP has other variables per stage (the inverse-dynamics form's
    # accelerations) starts from the plan's boundary states, not its whole iterate
    from tfcontact.timefreezing import Inelastic, time_freeze
    from tfcontact.timefreezing.inelastic import InverseDynamics

    inverse = time_freeze(problem.system.cls, method=Inelastic(dynamics=InverseDynamics()))
    other = solve_contact(dataclasses.replace(problem, system=inverse),
                          dataclasses.replace(options, homotopy=low), initial_guess=cold,
                          verbose=False)
    assert other.success, other.message
    with pytest.raises(InvalidInput, match="same system with N = 4 control intervals"):
        solve_contact(particle_friction_problem(n_intervals=4), options, initial_guess=cold,
                      verbose=False)
    with pytest.raises(InvalidInput, match="`initial_guess` must be a ContactResult"):
        solve_contact(problem, options, initial_guess=cold.ocp, verbose=False)
