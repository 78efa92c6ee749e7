"""The repeated-block derivatives (tfcontact.mpcc.derivatives) against CasADi's own."""

import dataclasses

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.fesd import (
    Fesd,
    FesdGrid,
    GaussLegendre,
    HeavisideSystem,
    RadauIIA,
    Standard,
    discretize,
)
from tfcontact.mpcc import Homotopy, Ipopt, MpccSolver
from tfcontact.mpcc.derivatives import repeated_block_derivatives
from tfcontact.mpcc.problem import RepeatedBlock


def nonlinear_system() -> HeavisideSystem:
    """Two states, a control and one switch, nonlinear everywhere (nonzero Hessians)."""
    x, u, alpha = ca.SX.sym("x", 2), ca.SX.sym("u"), ca.SX.sym("alpha")
    rhs = ca.vertcat(x[1] * ca.cos(x[0]),
                     alpha * (u * x[0] ** 2 - ca.sin(x[1])) + (1 - alpha) * ca.exp(-x[0] * u))
    return HeavisideSystem(x=x, u=u, alpha=alpha, rhs=rhs, switching=x[0] - 0.3 * x[1] ** 2)


def casadi_derivatives(x, p, f, g):
    solver = ca.nlpsol("reference", "ipopt", {"x": x, "p": p, "f": f, "g": g},
                       {"print_time": False})
    return solver.get_function("nlp_jac_g"), solver.get_function("nlp_hess_l")


@pytest.mark.parametrize("scheme, method, controls", [
    (RadauIIA(2), Fesd(), "variables"),
    (GaussLegendre(2), Fesd(), "parameters"),  # element end states of their own; u in p
    (RadauIIA(3), Standard(), "variables"),  # fixed steps: an argument free of w
])
def test_repeated_block_derivatives_equal_casadis_own(scheme, method, controls):
    disc = discretize(nonlinear_system(), grid=FesdGrid(3, 2, 1.0), scheme=scheme,
                      method=method, controls=controls)
    m = disc.mpcc
    assert len(m.repeated) == 1 and m.repeated[0].rows.shape[0] == 6
    f = m.f + ca.sumsqr(ca.sin(m.w))  # an objective with a Hessian of its own
    ours = repeated_block_derivatives(m.w, m.p, f, m.g, m.repeated, threads=2)
    jac_g, hess_lag = casadi_derivatives(m.w, m.p, f, m.g)
    rng = np.random.default_rng(3)
    for _ in range(3):
        w, p = rng.normal(size=m.n_w), rng.normal(size=m.p.numel())
        lam_f, lam_g = rng.normal(), rng.normal(size=m.n_g)
        g_ref, J_ref = jac_g(w, p)
        g_ours, J_ours = ours["jac_g"](w, p)
        H_ref = hess_lag(w, p, lam_f, lam_g)
        H_ours = ours["hess_lag"](w, p, lam_f, lam_g)
        assert J_ours.sparsity() == J_ref.sparsity()
        assert H_ours.sparsity() == H_ref.sparsity()
        np.testing.assert_array_equal(g_ours.full(), g_ref.full())
        for ref, value in ((J_ref, J_ours), (H_ref, H_ours)):
            scale = np.max(np.abs(ref.full()))
            assert scale > 0.1
            np.testing.assert_allclose(value.full(), ref.full(), rtol=0, atol=1e-13 * scale)


def test_the_solver_reaches_the_same_solution_with_and_without_repeated_blocks():
    disc = discretize(nonlinear_system(), grid=FesdGrid(2, 2, 1.0), controls="parameters")
    m = disc.mpcc
    p = np.concatenate([[0.4, -0.2], [0.5, -0.3]])
    schedule = Homotopy(sigma_0=1e-2, tolerance=1e-8)
    solvers = [MpccSolver(m, nlp=Ipopt(tol=1e-12, element_derivatives=True, threads=2)),
               MpccSolver(m, nlp=Ipopt(tol=1e-12))]  # off by default: CasADi's own
    kinds = [s.nlp_function("nlp_hess_l").class_name() for s in solvers]
    assert kinds == ["MXFunction", "SXFunction"]
    results = [solver.solve(p, homotopy=schedule, verbose=False) for solver in solvers]
    assert all(r.success for r in results)
    np.testing.assert_allclose(results[0].w, results[1].w, atol=1e-8)


def test_a_block_with_wrong_rows_is_refused():
    m = discretize(nonlinear_system(), grid=FesdGrid(2, 2, 1.0)).mpcc
    block = m.repeated[0]
    shifted = dataclasses.replace(block, rows=block.rows + 1)
    with pytest.raises(InvalidInput, match="does not give its rows of g"):
        MpccSolver(dataclasses.replace(m, repeated=(shifted,)),
                   nlp=Ipopt(element_derivatives=True))
    with pytest.raises(InvalidInput, match="`rows` must be nonnegative indices of shape"):
        RepeatedBlock(function=block.function, arguments=block.arguments, rows=block.rows[:, :-1])
    with pytest.raises(InvalidInput, match="`arguments` has 2 entries"):
        RepeatedBlock(function=block.function, arguments=block.arguments[:2], rows=block.rows)
    with pytest.raises(InvalidInput, match="beyond g's"):
        dataclasses.replace(m, repeated=(dataclasses.replace(block, rows=block.rows + m.n_g),))
    with pytest.raises(InvalidInput, match="share rows of g"):
        repeated_block_derivatives(m.w, m.p, m.f, m.g, (block, block))
    with pytest.raises(InvalidInput, match="`threads` must be a positive integer"):
        Ipopt(threads=0)


def test_arguments_that_are_not_plain_variables_fall_back_to_casadis_derivatives():
    m = discretize(nonlinear_system(), grid=FesdGrid(2, 2, 1.0)).mpcc
    block = m.repeated[0]
    scaled = dataclasses.replace(block, arguments=(2 * block.arguments[0],) + block.arguments[1:])
    assert repeated_block_derivatives(m.w, m.p, m.f, m.g, (scaled,)) == {}
    assert set(repeated_block_derivatives(m.w, m.p, m.f, m.g, m.repeated)) == {"jac_g", "hess_lag"}


def test_an_opti_problems_repeated_rows_give_casadis_derivatives_and_solution():
    """`RepeatedRows` (the exact re-solves' shooting steps): a pendulum's RK4 steps recorded
    as repeated rows of an Opti problem, with a row of their own between them; the
    scattered Jacobian and Hessian equal CasADi's, and IPOPT reaches the same solution."""
    from tfcontact.ocp.nodes import RepeatedRows

    x, u, x_next = ca.SX.sym("x", 2), ca.SX.sym("u"), ca.SX.sym("x_next", 2)

    def rhs(s):
        return ca.vertcat(s[1], -9.81 * ca.sin(s[0]) + u * ca.cos(s[0]))

    h = 0.05
    k1 = rhs(x)
    k2 = rhs(x + h / 2 * k1)
    k3 = rhs(x + h / 2 * k2)
    k4 = rhs(x + h * k3)
    step = ca.Function("step", [x, u, x_next], [x_next - x - h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])

    def build(recorded: bool):
        opti = ca.Opti()
        rows = RepeatedRows(opti)
        states = [opti.variable(2) for _ in range(9)]
        controls = opti.variable(8)
        target = opti.parameter()
        opti.subject_to(states[0] == [0.1, 0.0])
        for k in range(8):
            if recorded:
                rows.zero(step, states[k], controls[k], states[k + 1])
            else:
                opti.subject_to(step(states[k], controls[k], states[k + 1]) == 0)
            opti.subject_to(ca.sin(states[k + 1][0]) * controls[k] <= 3.0)  # not repeated
        opti.subject_to(opti.bounded(-4, controls, 4))
        opti.minimize(ca.sumsqr(controls) + 100 * (states[-1][0] - target) ** 2)
        opti.set_value(target, 0.6)
        return opti, rows

    opti, rows = build(True)
    derivatives = rows.derivative_options(threads=2)
    assert set(derivatives) == {"jac_g", "hess_lag"}
    assert RepeatedRows(ca.Opti()).derivative_options() == {}
    nlp_x, nlp_p = ca.SX.sym("x", opti.nx), ca.SX.sym("p", opti.np)
    f, g = ca.Function("nlp", [opti.x, opti.p], [opti.f, opti.g]).expand()(nlp_x, nlp_p)
    jac_g, hess_lag = casadi_derivatives(nlp_x, nlp_p, f, g)
    rng = np.random.default_rng(5)
    for _ in range(3):
        w, p = rng.normal(size=opti.nx), rng.normal(size=opti.np)
        lam_f, lam_g = rng.normal(), rng.normal(size=opti.ng)
        J_ref, J_ours = jac_g(w, p)[1], derivatives["jac_g"](w, p)[1]
        H_ref = hess_lag(w, p, lam_f, lam_g)
        H_ours = derivatives["hess_lag"](w, p, lam_f, lam_g)
        for ref, value in ((J_ref, J_ours), (H_ref, H_ours)):
            scale = np.max(np.abs(ref.full()))
            assert scale > 0.1
            np.testing.assert_allclose(value.full(), ref.full(), rtol=0, atol=1e-13 * scale)

    solutions = []
    for recorded in (True, False):
        opti, rows = build(recorded)
        opti.solver("ipopt", {"print_time": False, "expand": True, **rows.derivative_options()},
                    {"print_level": 0, "sb": "yes", "tol": 1e-12})
        solution = opti.solve()
        kind = solution.opti.debug.casadi_solver.get_function("nlp_hess_l").class_name()
        assert kind == ("MXFunction" if recorded else "SXFunction")
        solutions.append(solution.value(opti.x))
    np.testing.assert_allclose(solutions[0], solutions[1], atol=1e-8)
