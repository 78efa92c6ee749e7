import numpy as np
import pytest

from tfcontact.fesd import RadauIIA
from tfcontact.fesd.tableau import as_tableau
from tfcontact.ocp.verify import (
    clock_checks,
    collocation_impulses,
    contact_impulses,
    friction_cone_violation,
)

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


def collocated(state_of_tau, h, stages=2):
    """Element starts and Radau IIA stage values of y(tau) = (x, z, v_x, v_z, clock) on
    elements of length h: exact for polynomials of degree <= s."""
    tab = as_tableau(RadauIIA(stages))
    starts = np.concatenate([[0.0], np.cumsum(h)[:-1]])
    x_start = np.array([state_of_tau(a) for a in starts])
    x_stages = np.array([[state_of_tau(a + c * dh) for c in tab.c]
                         for a, dh in zip(starts, h, strict=True)])
    return x_start, x_stages, tab


def collocation_impulses_of(x_start, x_stages, h, tab):
    return collocation_impulses(
        x_start, x_stages, h, tab.A, tab.b, np.zeros((len(h), 0)),
        (slice(0, 2), slice(2, 4), 4),
        mass_matrix=lambda q: MASS * np.eye(2),
        smooth_force=lambda q, v, u: np.array([0.0, -MASS * G]),
        contact_jacobian=lambda q: np.array([[0.0, 1.0], [1.0, 0.0]]),
    )


@pytest.mark.parametrize("speed_of_time", [1.0, 3.0])
def test_collocation_impulses_of_coulomb_sliding_are_exact(speed_of_time):
    """Sliding at mu g deceleration, the clock running at s: per element the normal impulse
    is m g s h and the tangential one -mu m g s h (the stage derivatives are exact)."""
    mu, v0, s = 0.3, 3.0, speed_of_time

    def state(tau):
        t = s * tau
        return np.array([v0 * t - 0.5 * mu * G * t**2, 0.0, v0 - mu * G * t, 0.0, t])

    h = np.array([0.01, 0.02, 0.015])
    x_start, x_stages, tab = collocated(state, h)
    impulses, fit = collocation_impulses_of(x_start, x_stages, h, tab)
    np.testing.assert_allclose(impulses[:, 0], MASS * G * s * h, rtol=1e-12)
    np.testing.assert_allclose(impulses[:, 1], -mu * MASS * G * s * h, rtol=1e-12)
    np.testing.assert_allclose(fit, 0.0, atol=1e-12)
    assert friction_cone_violation(impulses, [mu], [1]) < 1e-12
    assert friction_cone_violation(impulses, [0.5 * mu], [1]) == pytest.approx(
        0.5 * mu * MASS * G * s * h.max(), rel=1e-9)


def test_collocation_impulses_of_a_frozen_impact_have_no_smooth_part():
    """While frozen the clock stands still: the impulse is M times the velocity change."""
    def state(tau):  # v_z: -2 -> 0 and v_x: 1 -> 0.5 over tau in [0, 0.1], t = 0.3
        r = min(tau / 0.1, 1.0)
        return np.array([0.0, 0.0, 1.0 - 0.5 * r, -2.0 + 2.0 * r, 0.3])

    h = np.array([0.05, 0.05])
    x_start, x_stages, tab = collocated(state, h)
    impulses, _ = collocation_impulses_of(x_start, x_stages, h, tab)
    np.testing.assert_allclose(impulses.sum(axis=0), [MASS * 2.0, -MASS * 0.5], rtol=1e-12)
