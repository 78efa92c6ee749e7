import numpy as np
import pytest

from tfcontact.ocp.verify import clock_checks, contact_impulses, friction_cone_violation

G = 9.81
MASS = 2.0


def sliding_block(deceleration, n=11, horizon=0.2, v0=3.0):
    """A block on the ground (q = (x, z)) sliding with the given deceleration."""
    t = np.linspace(0.0, horizon, n)
    vx = v0 - deceleration * t
    q = np.column_stack([v0 * t - 0.5 * deceleration * t**2, np.zeros(n)])
    v = np.column_stack([vx, np.zeros(n)])
    return t, q, v, np.zeros((n, 0))


def impulses_of(t, q, v, u):
    return contact_impulses(
        t, q, v, u,
        mass_matrix=lambda q: MASS * np.eye(2),
        smooth_force=lambda q, v, u: np.array([0.0, -MASS * G]),
        contact_jacobian=lambda q: np.array([[0.0, 1.0], [1.0, 0.0]]),  # columns: normal, tangent
    )


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_coulomb_sliding_lies_on_the_cone_and_faster_braking_leaves_it(mu):
    impulses, residual = impulses_of(*sliding_block(mu * G))
    dt = 0.02
    np.testing.assert_allclose(impulses[:, 0], MASS * G * dt, rtol=1e-12)  # normal: weight
    np.testing.assert_allclose(impulses[:, 1], -mu * MASS * G * dt, rtol=1e-12)
    np.testing.assert_allclose(residual, 0.0, atol=1e-12)
    assert friction_cone_violation(impulses, [mu], [1]) < 1e-12
    too_much, _ = impulses_of(*sliding_block(2 * mu * G))
    np.testing.assert_allclose(
        friction_cone_violation(too_much, [mu], [1]), mu * MASS * G * dt, rtol=1e-9
    )


def test_an_impact_is_an_impulse_without_smooth_part():
    t = np.array([0.0, 0.3, 0.3])  # the impact happens at t = 0.3, the clock stands still
    q = np.zeros((3, 2))
    v = np.array([[1.0, -2.0], [1.0, -2.0], [0.5, 0.0]])
    impulses, _ = contact_impulses(
        t, q, v, np.zeros((3, 0)),
        mass_matrix=lambda q: MASS * np.eye(2),
        smooth_force=lambda q, v, u: np.zeros(2),
        contact_jacobian=lambda q: np.array([[0.0, 1.0], [1.0, 0.0]]),
    )
    np.testing.assert_allclose(impulses[1], [MASS * 2.0, -MASS * 0.5])
    assert friction_cone_violation(impulses, [0.25], [1]) == pytest.approx(0.0, abs=1e-12)
    assert friction_cone_violation(impulses, [0.2], [1]) == pytest.approx(0.2, abs=1e-12)


def test_clock_checks():
    assert clock_checks(np.array([0.0, 0.5, 0.5, 1.0]), 1.0, 1e-9) == (True, 0.0)
    monotone, error = clock_checks(np.array([0.0, 0.6, 0.5, 0.9]), 1.0, 1e-9)
    assert not monotone and error == pytest.approx(0.1)
