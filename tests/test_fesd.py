"""FESD layer: tableaus, discretisation structure, switch detection, convergence order."""

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput, SolveFailed
from tfcontact.fesd import (
    Direct,
    Fesd,
    FesdGrid,
    GaussLegendre,
    HeavisideSystem,
    RadauIIA,
    Standard,
    StewartSystem,
    Tableau,
    discretize,
    simulate,
)
from tfcontact.fesd.tableau import collocation_tableau
from tfcontact.mpcc import Homotopy, Ipopt, L1Penalty, LinfPenalty, Scholtes

# Residual and IPOPT tolerance 1e-13: the switch time and x(T) are then exact to round-off.
TIGHT = {"homotopy": Homotopy(tolerance=1e-13), "nlp": Ipopt(tol=1e-13)}

# ---------------------------------------------------------------- tableaus


@pytest.mark.parametrize("stages", [1, 2, 3, 4])
@pytest.mark.parametrize("family", [RadauIIA, GaussLegendre])
def test_tableau_satisfies_the_order_conditions_of_its_stated_order(family, stages):
    tab = family(stages=stages).tableau()
    assert tab.order == family(stages=stages).order
    assert tab.order == (2 * stages - 1 if family is RadauIIA else 2 * stages)
    # Quadrature conditions B(p): sum_j b_j c_j^(k-1) = 1/k for k <= order, and not beyond.
    for k in range(1, tab.order + 1):
        assert tab.b @ tab.c ** (k - 1) == pytest.approx(1 / k, abs=1e-14)
    assert abs(tab.b @ tab.c**tab.order - 1 / (tab.order + 1)) > 1e-6
    # Stage conditions C(s): sum_j A_ij c_j^(k-1) = c_i^k / k for k <= s.
    for k in range(1, stages + 1):
        np.testing.assert_allclose(tab.A @ tab.c ** (k - 1), tab.c**k / k, atol=1e-14)
    assert tab.stiffly_accurate is (family is RadauIIA)


def test_radau_two_stages_matches_the_textbook_coefficients():
    # Hairer & Wanner II, Table IV.5.5: c = (1/3, 1), A = [[5/12, -1/12], [3/4, 1/4]].
    tab = RadauIIA(2).tableau()
    np.testing.assert_allclose(tab.c, [1 / 3, 1], atol=1e-15)
    np.testing.assert_allclose(tab.A, [[5 / 12, -1 / 12], [3 / 4, 1 / 4]], atol=1e-15)
    np.testing.assert_allclose(tab.b, [3 / 4, 1 / 4], atol=1e-15)
    gauss = GaussLegendre(2).tableau()
    np.testing.assert_allclose(gauss.c, [0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6], atol=1e-15)


def test_tableau_checks_its_consistency():
    with pytest.raises(InvalidInput, match="row sums of `A` must equal `c`"):
        Tableau(A=np.eye(2), b=[0.5, 0.5], c=[0.2, 1.0], order=1, name="bad")
    with pytest.raises(InvalidInput, match=r"weights `b` must sum to 1"):
        Tableau(A=[[1.0]], b=[0.9], c=[1.0], order=1, name="bad")
    with pytest.raises(InvalidInput, match=r"`points` must be distinct"):
        collocation_tableau([0.5, 0.5], order=1, name="bad")


@pytest.mark.parametrize("stages", [0, -1, 2.0, True])
def test_scheme_rejects_bad_stage_counts(stages):
    with pytest.raises(InvalidInput, match="`stages` must"):
        RadauIIA(stages=stages)


def test_unknown_scheme_is_rejected_with_the_fix():
    with pytest.raises(InvalidInput, match=r"unknown `scheme` 'radau'.*RadauIIA\(stages=s\)"):
        discretize(sign_system(), grid=FesdGrid(1, 2, 1.0), scheme="radau")


# ---------------------------------------------------------------- x' = 2 - sign(x)


def sign_system() -> StewartSystem:
    """x' = 2 - sign(x): region 1 (x > 0) x' = 1, region 2 (x < 0) x' = 3."""
    x = ca.SX.sym("x")
    return StewartSystem.from_sign_matrix(x, ca.SX(0, 1), ca.horzcat(1, 3), x,
                                          np.array([[1], [-1]]))


def sign_system_heaviside() -> HeavisideSystem:
    """The same system with alpha in H(x): x' = alpha * 1 + (1 - alpha) * 3."""
    x, alpha = ca.SX.sym("x"), ca.SX.sym("alpha")
    return HeavisideSystem(x=x, u=ca.SX(0, 1), alpha=alpha, rhs=3 - 2 * alpha, switching=x)


def test_discretization_has_the_stated_structure():
    s, n_fe, N = 2, 3, 4
    disc = discretize(sign_system(), grid=FesdGrid(N, n_fe, 2.0), scheme=RadauIIA(s))
    E = N * n_fe
    mpcc = disc.mpcc
    assert disc.layout.x.shape == (E + 1, 1)
    assert disc.layout.x_stages.shape == (E, s, 1)
    assert disc.layout.z["theta"].shape == (E, s, 2)
    assert mpcc.blocks["h"].size == E
    # stage-mode cross complementarity: s * n_f pairs per element
    assert mpcc.n_comp == E * s * 2
    np.testing.assert_allclose(mpcc.lbw[mpcc.blocks["h"]], 0.0)
    np.testing.assert_allclose(mpcc.ubw[mpcc.blocks["h"]], 2 * 2.0 / E)
    assert np.all(mpcc.lbw[mpcc.blocks["theta"]] == 0)
    assert mpcc.p.numel() == 1  # x0
    # Radau's end point is its last stage: no separate boundary variables
    assert "lambda_end" not in mpcc.blocks
    gauss = discretize(sign_system(), grid=FesdGrid(N, n_fe, 2.0), scheme=GaussLegendre(s))
    assert gauss.mpcc.blocks["lambda_end"].size == E * 2
    standard = discretize(sign_system(), grid=FesdGrid(N, n_fe, 2.0), method=Standard())
    assert "h" not in standard.mpcc.blocks
    assert standard.mpcc.n_comp == E * s * 2
    element = discretize(sign_system(), grid=FesdGrid(N, n_fe, 2.0),
                         method=Fesd(cross_complementarity="element"))
    assert element.mpcc.n_comp == E * 2


@pytest.mark.parametrize("system", [sign_system, sign_system_heaviside],
                         ids=["stewart", "heaviside"])
@pytest.mark.parametrize("scheme", [RadauIIA(1), RadauIIA(2), GaussLegendre(2)],
                         ids=["radau1", "radau2", "gauss2"])
@pytest.mark.parametrize("n_steps", [2, 5])
def test_fesd_detects_the_switch_exactly(system, scheme, n_steps):
    # x(0) = -1: x' = 3 until x = 0 at t = 1/3, then x' = 1, so x(T) = T - 1/3.
    # With T = 1 and 2 or 5 steps of 2 elements, 1/3 is on no nominal grid point.
    T = 1.0
    result = simulate(system(), [-1.0], horizon=T, n_steps=n_steps, scheme=scheme, **TIGHT)
    assert result.success
    assert result.switch_times.size == 1
    assert abs(result.switch_times[0] - 1 / 3) <= 1e-9
    assert abs(result.x[-1, 0] - (T - 1 / 3)) <= 1e-12
    assert result.t[-1] == pytest.approx(T, abs=1e-14)
    # the boundary at the switch carries x = 0
    k = int(np.argmin(np.abs(result.t - 1 / 3)))
    assert abs(result.x[k, 0]) <= 1e-12


def test_standard_discretization_misses_the_switch():
    T = 1.0
    result = simulate(sign_system(), [-1.0], horizon=T, n_steps=2, method=Standard())
    assert result.success
    np.testing.assert_allclose(result.h, T / 4)
    assert abs(result.x[-1, 0] - (T - 1 / 3)) > 1e-2


def test_simulation_with_controls_and_bad_inputs():
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    sys = StewartSystem.from_sign_matrix(x, u, ca.horzcat(u - 1, u + 1), x,
                                         np.array([[1], [-1]]))
    with pytest.raises(InvalidInput, match="pass `u`"):
        simulate(sys, [-1.0], horizon=1.0, n_steps=2)
    with pytest.raises(InvalidInput, match=r"`u` must have shape \(1,\) or \(n_steps, n_u\)"):
        simulate(sys, [-1.0], horizon=1.0, n_steps=2, u=np.ones((3, 1)))
    with pytest.raises(InvalidInput, match=r"`x0` has 2 entries, expected n_x = 1"):
        simulate(sys, [-1.0, 0.0], horizon=1.0, n_steps=2, u=2.0)
    with pytest.raises(InvalidInput, match=r"`n_steps` must be a positive integer, got 0"):
        simulate(sys, [-1.0], horizon=1.0, n_steps=0, u=2.0)
    with pytest.raises(InvalidInput, match=r"`n_finite_elements` must be a positive integer"):
        simulate(sys, [-1.0], horizon=1.0, n_steps=2, u=2.0, n_finite_elements=-2)
    with pytest.raises(InvalidInput, match=r"`horizon` must be a positive number"):
        simulate(sys, [-1.0], horizon=-1.0, n_steps=2, u=2.0)
    # u = 2: x' = 3 for x < 0, then 1: the same switch at t = 1/3; u per step works too.
    result = simulate(sys, [-1.0], horizon=1.0, n_steps=3, u=[[2.0], [2.0], [2.0]], **TIGHT)
    assert abs(result.switch_times[0] - 1 / 3) <= 1e-9
    assert abs(result.x[-1, 0] - 2 / 3) <= 1e-12


@pytest.mark.parametrize("relaxation", [Scholtes(), L1Penalty(), LinfPenalty()])
def test_every_relaxation_simulates_the_switch(relaxation):
    result = simulate(sign_system(), [-1.0], horizon=1.0, n_steps=3, relaxation=relaxation)
    assert result.success
    assert result.residual <= 1e-9
    assert abs(result.switch_times[0] - 1 / 3) <= 1e-9


def test_direct_step_equilibration_gives_equal_steps_away_from_the_switch():
    result = simulate(sign_system(), [-1.0], horizon=1.0, n_steps=3, n_finite_elements=3,
                      method=Fesd(step_equilibration=Direct()), relaxation=LinfPenalty())
    assert result.success
    assert abs(result.switch_times[0] - 1 / 3) <= 1e-9
    h = result.h.reshape(3, 3)
    # steps 1 and 3 hold no switch: their elements are equal
    np.testing.assert_allclose(h[0], 1 / 9, atol=1e-8)
    np.testing.assert_allclose(h[2], 1 / 9, atol=1e-8)


def test_a_failed_step_is_reported_or_raised():
    # One NLP with sigma = 1 cannot reach the residual tolerance: the step fails.
    with pytest.raises(SolveFailed, match="step 1 of 2 failed"):
        simulate(sign_system(), [-1.0], horizon=1.0, n_steps=2,
                 homotopy=Homotopy(max_nlps=1), retry=False)
    result = simulate(sign_system(), [-1.0], horizon=1.0, n_steps=2,
                      homotopy=Homotopy(max_nlps=1), retry=False, throw=False)
    assert not result.success
    assert result.t.size == 1 and result.n_steps == 1


def test_a_failed_step_is_retried_with_a_gentler_schedule():
    # The same failing schedule; the retry (kappa -> sqrt(kappa), NLPs until the
    # tolerance) finishes each step, and the switch is still found.
    result = simulate(sign_system(), [-1.0], horizon=1.0, n_steps=2,
                      homotopy=Homotopy(max_nlps=1))
    assert result.success
    assert result.n_retries == 2
    assert result.residual <= 1e-9
    assert abs(result.switch_times[0] - 1 / 3) <= 1e-9


# ---------------------------------------------------------------- convergence order


def circle_system() -> StewartSystem:
    """[FESD] section 4.4: x' = A1 x for |x|^2 < 1, A2 x for |x|^2 > 1, w = 2 pi."""
    x = ca.SX.sym("x", 2)
    w = 2 * np.pi
    a1 = ca.DM([[1, w], [-w, 1]])
    a2 = ca.DM([[1, -w], [w, 1]])
    return StewartSystem.from_sign_matrix(x, ca.SX(0, 1), ca.horzcat(a1 @ x, a2 @ x),
                                          ca.sumsqr(x) - 1, np.array([[-1], [1]]))


CIRCLE_X0 = np.array([np.exp(-1), 0.0])
CIRCLE_T = np.pi / 2


def circle_reference(t: float) -> np.ndarray:
    """Closed form: in polar coordinates r' = r in both regions, phi' = -w inside, +w outside.

    From r(0) = 1/e, phi(0) = 0: r = e^(t - 1), so the switch is at t_s = 1 with
    phi(1) = -2 pi, x(1) = (1, 0); afterwards x(t) = e^(t - 1) (cos w(t - 1), sin w(t - 1)).
    """
    w = 2 * np.pi
    if t <= 1:
        return np.exp(t - 1) * np.array([np.cos(w * t), -np.sin(w * t)])
    return np.exp(t - 1) * np.array([np.cos(w * (t - 1)), np.sin(w * (t - 1))])


def global_errors(stages, n_steps_list, method, family=RadauIIA):
    errors, steps = [], []
    for n in n_steps_list:
        result = simulate(circle_system(), CIRCLE_X0, horizon=CIRCLE_T, n_steps=n,
                          scheme=family(stages), n_finite_elements=2, method=method,
                          relaxation=L1Penalty(), homotopy=Homotopy(tolerance=1e-12),
                          nlp=Ipopt(tol=1e-12))
        errors.append(np.linalg.norm(result.x[-1] - circle_reference(CIRCLE_T)))
        steps.append(CIRCLE_T / (2 * n))
    return np.array(steps), np.array(errors)


def fitted_order(steps, errors) -> float:
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def test_circle_reference_solves_the_ode():
    w = 2 * np.pi
    a1 = np.array([[1, w], [-w, 1]])
    a2 = np.array([[1, -w], [w, 1]])
    np.testing.assert_allclose(circle_reference(0.0), CIRCLE_X0, atol=1e-15)
    for t, a in ((0.4, a1), (1.3, a2)):
        fd = (circle_reference(t + 1e-6) - circle_reference(t - 1e-6)) / 2e-6
        np.testing.assert_allclose(fd, a @ circle_reference(t), rtol=1e-8)
    np.testing.assert_allclose(circle_reference(1 - 1e-12), circle_reference(1 + 1e-12),
                               atol=1e-10)


@pytest.mark.parametrize(("family", "stages", "n_steps"), [
    (RadauIIA, 2, (10, 20, 40, 100)),
    (RadauIIA, 3, (5, 10, 20, 50)),
    (GaussLegendre, 2, (10, 20, 40, 100)),
])
def test_fesd_recovers_the_smooth_order_across_the_switch(family, stages, n_steps):
    # [FESD] Table 1: Radau IIA 2s - 1, Gauss-Legendre 2s (measured 3.04, 4.85, 4.00).
    steps, errors = global_errors(stages, n_steps, Fesd(), family)
    assert steps[0] / steps[-1] >= 10
    assert abs(fitted_order(steps, errors) - family(stages).order) <= 0.3


@pytest.mark.slow
def test_fesd_implicit_euler_is_first_order():
    # Radau IIA s = 1 damps the rotation by O(w^2 h): asymptotic only for h < 5e-3.
    steps, errors = global_errors(1, (160, 500, 1600), Fesd())
    assert abs(fitted_order(steps, errors) - 1) <= 0.3


def test_standard_discretization_is_first_order_across_the_switch():
    # Its error jumps with where the switch falls in an element; over a decade of h it
    # decreases at most linearly (measured: slope ~0.6).
    steps, errors = global_errors(3, (20, 60, 200), Standard())
    assert fitted_order(steps, errors) < 1.5
    _, fesd_errors = global_errors(3, (100,), Fesd())
    assert fesd_errors[0] < 1e-3 * errors[-1]


def test_bad_grid_and_method_options_are_rejected():
    with pytest.raises(InvalidInput, match=r"`n_intervals` must be a positive integer, got 0"):
        FesdGrid(0, 2, 1.0)
    with pytest.raises(InvalidInput, match=r"`n_finite_elements` must be a positive integer"):
        FesdGrid(2, -1, 1.0)
    with pytest.raises(InvalidInput, match=r"`horizon` must be a positive number \[s\], got nan"):
        FesdGrid(2, 2, float("nan"))
    with pytest.raises(InvalidInput, match=r"`gamma_h` must lie in \(0, 1\], got 1.5"):
        Fesd(gamma_h=1.5)
    with pytest.raises(InvalidInput, match=r"`cross_complementarity` must be 'stage' or"):
        Fesd(cross_complementarity="all")
    with pytest.raises(InvalidInput, match=r"`step_equilibration` must be HeuristicMean\(\)"):
        Fesd(step_equilibration="mean")
    with pytest.raises(InvalidInput, match=r"`method` must be Fesd\(...\) or Standard\(\)"):
        discretize(sign_system(), grid=FesdGrid(1, 2, 1.0), method="fesd")
    with pytest.raises(InvalidInput, match=r"`system` must be a StewartSystem or Heaviside"):
        discretize("x' = 1", grid=FesdGrid(1, 2, 1.0))
    with pytest.raises(InvalidInput, match=r"`controls` must be 'variables' or 'parameters'"):
        discretize(sign_system(), grid=FesdGrid(1, 2, 1.0), controls="fixed")
    disc = discretize(sign_system(), grid=FesdGrid(1, 2, 1.0))
    with pytest.raises(InvalidInput, match=r"`x0` has 2 entries, expected n_x = 1"):
        disc.parameters([1.0, 2.0])
