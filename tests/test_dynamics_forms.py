"""The Heaviside right-hand side of `Inelastic` written with one M(q) solve (`OneSolve`,
the default) is the per-mode sum modes @ weights (`PerModeSolves`) regrouped: the same
function of (y, u, alpha) for planar, 3-D and no friction, several contacts at once. The
inverse-dynamics form (`InverseDynamics`: accelerations as auxiliary variables with
M(q) a = sum_k theta_k F_k) is that function where its equations hold, and simulates and
plans as the explicit form does."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest
from two_contact_box import box_urdf, pushed_box_problem

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.fesd import HeavisideSystem, Physical, simulate
from tfcontact.timefreezing import Inelastic, from_robot, time_freeze
from tfcontact.timefreezing.inelastic import InverseDynamics, OneSolve, PerModeSolves


def _box_cls(folder, base: str, mu: tuple[float, float]):
    from tfcontact.robot import ContactSpec, load_robot

    path = folder / "box.urdf"
    path.write_text(box_urdf(0.3, 0.2))
    robot = load_robot(str(path), base=base, contacts=(ContactSpec("front", 0.05),
                                                       ContactSpec("back", 0.05)))
    return from_robot(robot, mu=list(mu), a_n=50.0, eps_t=1e-3, actuated=["root_joint"])


def _points(tf, rng: np.random.Generator, count: int) -> list[np.ndarray]:
    """Random (y, u, alpha) with alpha in [0, 1] and velocities of order 1 m/s (so the
    3-D slip modes, which divide by ||v_t||_eps, are exercised away from the ball)."""
    pss = tf.pss
    return [np.concatenate([rng.uniform(-0.5, 0.5, pss.n_x), rng.uniform(-5, 5, pss.n_u),
                            rng.uniform(0, 1, pss.alpha.numel())]) for _ in range(count)]


@pytest.mark.parametrize(("base", "mu"), [("floating", (0.7, 0.4)), ("planar", (0.5, 0.0)),
                                          ("floating", (0.0, 0.6))])
def test_one_solve_rhs_is_the_sum_of_the_modes(tmp_path, base, mu):
    cls = _box_cls(tmp_path, base, mu)
    tf = time_freeze(cls, method=Inelastic(dynamics=OneSolve()))
    assert tf.parameter("dynamics") == "one_solve"
    assert time_freeze(cls, method=Inelastic()).parameter("dynamics") == "per_mode_solves"
    old = time_freeze(cls, method=Inelastic(dynamics=PerModeSolves())).pss
    pss = tf.pss
    z = ca.vertcat(pss.x, pss.u, pss.alpha)
    new = ca.Function("new", [z], [pss.rhs, ca.mtimes(tf.modes, tf.weights)])
    per_mode = ca.Function("old", [ca.vertcat(old.x, old.u, old.alpha)], [old.rhs])
    n_modes = 1 + sum(2 if m else 1 for m in mu)
    assert tf.modes.shape[1] == n_modes
    for point in _points(tf, np.random.default_rng(7), 5):
        one, summed = (np.asarray(value).ravel() for value in new(point))
        written = np.asarray(per_mode(point)).ravel()
        scale = np.max(np.abs(summed))
        assert scale > 1.0  # the auxiliary pushes act (a_n = 50), not a trivial zero
        np.testing.assert_allclose(one, summed, rtol=0, atol=1e-12 * scale)
        np.testing.assert_array_equal(written, summed)  # PerModeSolves is the sum as written


def test_the_stewart_form_is_unchanged_by_the_strategy(tmp_path):
    from tfcontact.robot import ContactSpec, load_robot

    path = tmp_path / "box.urdf"
    path.write_text(box_urdf(0.3, 0.2))
    robot = load_robot(str(path), base="planar", contacts=(ContactSpec("front", 0.05),))
    cls = from_robot(robot, mu=0.5, actuated=["root_joint"])
    a = time_freeze(cls, method=Inelastic(form="stewart", dynamics=OneSolve()))
    b = time_freeze(cls, method=Inelastic(form="stewart", dynamics=PerModeSolves()))
    assert a.pss.n_regions == b.pss.n_regions == 8
    assert str(a.modes) == str(b.modes)


def test_dynamics_must_be_a_strategy():
    with pytest.raises(InvalidInput, match="HeavisideDynamics"):
        Inelastic(dynamics="one_solve")  # type: ignore[arg-type]


def _solved_auxiliary(pss) -> ca.Function:
    """a(y, u, alpha) solving the auxiliary equations (affine in a: one Newton step)."""
    e = pss.auxiliary_equations
    a = -ca.solve(ca.jacobian(e, pss.auxiliary),
                  ca.substitute(e, pss.auxiliary, ca.SX.zeros(pss.n_auxiliary)))
    return ca.Function("a", [ca.vertcat(pss.x, pss.u, pss.alpha)], [a])


@pytest.mark.parametrize(("base", "mu"), [("floating", (0.7, 0.4)), ("planar", (0.5, 0.0))])
def test_inverse_dynamics_rhs_is_the_sum_of_the_modes_where_its_equations_hold(
        tmp_path, base, mu):
    cls = _box_cls(tmp_path, base, mu)
    tf = time_freeze(cls, method=Inelastic(dynamics=InverseDynamics()))
    pss = tf.pss
    assert tf.parameter("dynamics") == "inverse_dynamics"
    assert pss.n_auxiliary == cls.n_q  # one acceleration per velocity
    # no M^-1 anywhere: the rhs is the accelerations themselves, the equations M a - F
    assert not ca.depends_on(pss.rhs[cls.n_q:2 * cls.n_q], ca.vertcat(pss.x, pss.u))
    z = ca.vertcat(pss.x, pss.u, pss.alpha)
    solve = _solved_auxiliary(pss)
    f = ca.Function("f", [z, pss.auxiliary], [pss.rhs, pss.auxiliary_equations,
                                               ca.mtimes(tf.modes, tf.weights)])
    for point in _points(tf, np.random.default_rng(3), 5):
        a = np.asarray(solve(point)).ravel()
        rhs, residual, summed = (np.asarray(v).ravel() for v in f(point, a))
        scale = np.max(np.abs(summed))
        assert scale > 1.0
        assert np.max(np.abs(residual)) < 1e-12 * scale
        np.testing.assert_allclose(rhs, summed, rtol=0, atol=1e-12 * scale)
        # and only there: another a breaks both the equations and the equality
        rhs, residual, _ = (np.asarray(v).ravel() for v in f(point, a + 0.1))
        assert np.max(np.abs(residual)) > 1e-3 and np.max(np.abs(rhs - summed)) > 1e-3


def test_inverse_dynamics_needs_the_heaviside_form(tmp_path):
    cls = _box_cls(tmp_path, "planar", (0.5, 0.0))
    with pytest.raises(IncompatibleOptions, match="auxiliary variables"):
        time_freeze(cls, method=Inelastic(form="stewart", dynamics=InverseDynamics()))


def test_auxiliary_variables_need_one_equation_each():
    x, a = ca.SX.sym("x"), ca.SX.sym("a", 2)
    alpha = ca.SX.sym("alpha")
    with pytest.raises(InvalidInput, match="one equation per auxiliary variable"):
        HeavisideSystem(x=x, u=ca.SX(0, 1), alpha=alpha, rhs=a[0], switching=x,
                        auxiliary=a, auxiliary_equations=a[0] - x)


def test_inverse_dynamics_simulation_matches_the_explicit_form(tmp_path):
    """The two-contact box resting on the ground at 0.5 m/s slides to a stop at
    v^2 / (2 mu g) (mu = 0.5): the same FESD simulation with either form, and the
    accelerations of the inverse-dynamics form solve its equations at every stage point."""
    cls = _box_cls(tmp_path, "planar", (0.5, 0.5))
    results = {}
    for dynamics in (OneSolve(), InverseDynamics()):
        tf = time_freeze(cls, method=Inelastic(dynamics=dynamics))
        y0 = tf.initial_state([0.0, 0.25, 0.0], [0.5, 0.0, 0.0])
        results[dynamics.name] = (tf, simulate(tf, y0, horizon=Physical(0.2), n_steps=4,
                                               u=np.zeros(3)))
    (_, one), (tf, inverse) = results["one_solve"], results["inverse_dynamics"]
    assert one.success and inverse.success
    stop = 0.5**2 / (2 * 0.5 * 9.81)
    assert abs(one.x[-1, 0] - stop) < 1e-4
    np.testing.assert_allclose(inverse.x[-1], one.x[-1], rtol=0, atol=1e-7)
    a = inverse.algebraic["auxiliary"]
    assert a.shape == (*inverse.x_stages.shape[:2], 3)
    pss = tf.pss
    e = ca.Function("e", [pss.x, pss.u, pss.alpha, pss.auxiliary], [pss.auxiliary_equations])
    steps = np.repeat(np.arange(len(inverse.u)), len(a) // len(inverse.u))
    worst = max(float(np.max(np.abs(np.asarray(e(inverse.x_stages[k, j], inverse.u[steps[k]],
                                                   inverse.algebraic["alpha"][k, j],
                                                   a[k, j])))))
                for k in range(a.shape[0]) for j in range(a.shape[1]))
    assert worst < 1e-6  # [N]: M a = sum_k theta_k F_k holds at the solution


@pytest.fixture(scope="module")
def box_in_both_forms(tmp_path_factory):
    """The pushed two-contact box (tests/two_contact_box.py) planned with the explicit
    and with the inverse-dynamics form: (explicit, implicit) `ContactResult`s."""
    from tfcontact.ocp import ContactSolverOptions, solve_contact

    problem = pushed_box_problem(tmp_path_factory.mktemp("box"), 0.5, 0.3, 0.2)
    tf = problem.system
    inverse = time_freeze(tf.cls, method=Inelastic(dynamics=InverseDynamics()))
    # the running cost reads q only: the new system's clock symbol does not enter it
    return tuple(solve_contact(p, ContactSolverOptions(), verbose=False)
                 for p in (problem, replace(problem, system=inverse)))


def test_inverse_dynamics_plans_the_box_as_the_explicit_form_does(box_in_both_forms):
    """Either form plans the pushed box: converged, verified, the box pushed to its goal;
    the inverse-dynamics form carries its accelerations as algebraic variables."""
    assert all(r.success and r.ocp.success and r.verification.passed
               for r in box_in_both_forms)
    assert "auxiliary" in box_in_both_forms[1].ocp.algebraic


@pytest.mark.xfail(strict=False, reason=(
    "round-off decides which local solution of the relaxed MPCC each form reaches: the "
    "same to 1e-6 where first measured; on a Zen 3 machine (2026-11-29) cost 0.093994 "
    "(explicit) against 0.094014 (inverse), end x 30 um apart, both verified; solved "
    "from the explicit plan's nodes the inverse form went to a third, 0.090012"))
def test_inverse_dynamics_plan_matches_the_explicit_form(box_in_both_forms):
    """Both forms the same plan: the same cost and end state to the solver's tolerance."""
    explicit, implicit = box_in_both_forms
    assert implicit.ocp.cost == pytest.approx(explicit.ocp.cost, rel=1e-6)
    np.testing.assert_allclose(implicit.y[-1], explicit.y[-1], rtol=0, atol=1e-6)
