"""The friction cone and maximal dissipation of statically indeterminate contacts
(`impulse_freedom`, `coulomb_split`): closed forms for a planar box on two contacts whose
friction is not unique, and a two-contact time-freezing plan solved by the library."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from two_contact_box import pushed_box_problem, solved_plan

from tfcontact.fesd import RadauIIA
from tfcontact.fesd.tableau import as_tableau
from tfcontact.verify import (
    TimeFreezingPlan,
    check_time_freezing_plan,
    collocation_impulses,
    friction_cone_violation,
    maximal_dissipation_violation,
)
from tfcontact.verify.checks import coulomb_split, impulse_freedom

MU = 0.4
DEPTH = 0.1  # the contact spheres' centres below the centre of mass [m]
HALF_SPAN = 0.2  # half the distance between them [m]


def box_jacobian(q: np.ndarray) -> np.ndarray:
    """Columns (n_1, t_1, n_2, t_2) of a planar box q = (x, z, pitch) at pitch 0 with its
    contact points at (+-HALF_SPAN, -DEPTH - 0.1): friction at them turns the box."""
    return np.array([[0.0, 1.0, 0.0, 1.0],
                     [1.0, 0.0, 1.0, 0.0],
                     [-HALF_SPAN, -(DEPTH + 0.1), HALF_SPAN, -(DEPTH + 0.1)]])


def one_element(impulse: np.ndarray, slip: float):
    """One Radau IIA element whose stages carry the impulse (n_1, t_1, n_2, t_2): its
    freedom, and the slip of both contacts at its 4 samples."""
    tab = as_tableau(RadauIIA(2))
    x_stages = np.zeros((1, 2, 3))
    freedom = impulse_freedom(x_stages, np.array([1.0]), tab.b, slice(0, 3), box_jacobian)
    slips = np.full((1, 4, 2), slip)
    return impulse[None], freedom, slips


@pytest.mark.parametrize("slip", [0.0, 0.5])
def test_unequal_normal_impulses_share_the_friction_by_weight(slip):
    """Normal impulses 0.3 and 0.5 N s, friction 0.32 N s in all = mu times their sum (the
    box slides at the cone's edge): the minimum-norm split, 0.16 on each, puts the front
    contact 0.04 N s out of its cone; the admissible split 0.12 / 0.2 has none, and
    dissipates maximally where the box slips."""
    mu_total = MU * 0.8
    lam, freedom, slips = one_element(np.array([0.3, -0.16, 0.5, -0.16]), slip)
    assert freedom[0].shape == (4, 1)
    np.testing.assert_allclose(box_jacobian(None) @ freedom[0], 0.0, atol=1e-14)
    assert friction_cone_violation(lam, [MU, MU], [1, 1]) == pytest.approx(0.04)
    split = coulomb_split(lam, freedom, [MU, MU], [1, 1], slips)
    np.testing.assert_allclose(split[0], [0.3, -0.12, 0.5, -0.2], atol=1e-12)
    np.testing.assert_allclose(box_jacobian(None) @ split[0], box_jacobian(None) @ lam[0],
                               atol=1e-14)
    assert split[0, [1, 3]].sum() == pytest.approx(-mu_total)
    assert friction_cone_violation(split, [MU, MU], [1, 1]) < 1e-12
    worst, checked = maximal_dissipation_violation(split, slips, [MU, MU], [1, 1])
    assert worst < 1e-12 and checked == (2 if slip else 0)


def test_friction_beyond_the_cone_at_every_split_still_fails():
    """Friction 0.42 N s > mu (0.3 + 0.5) = 0.32: every split leaves at least one contact
    out of its cone; the best (equal excess) leaves (0.42 - 0.32) / 2 = 0.05 N s each."""
    lam, freedom, slips = one_element(np.array([0.3, -0.21, 0.5, -0.21]), 0.0)
    split = coulomb_split(lam, freedom, [MU, MU], [1, 1], slips)
    assert friction_cone_violation(split, [MU, MU], [1, 1]) == pytest.approx(0.05, rel=1e-9)


def test_a_single_contact_keeps_its_impulses():
    """One contact: nothing to choose (no freedom), the impulses are returned unchanged."""
    tab = as_tableau(RadauIIA(2))
    impulses, _ = collocation_impulses(
        np.zeros((1, 5)), np.zeros((1, 2, 5)), np.array([0.1]), tab.A, tab.b,
        np.zeros((1, 0)), (slice(0, 2), slice(2, 4), 4), mass_matrix=lambda q: np.eye(2),
        smooth_force=lambda q, v, u: np.array([0.0, -9.81]),
        contact_jacobian=lambda q: np.array([[0.0, 1.0], [1.0, 0.0]]))
    freedom = impulse_freedom(np.zeros((1, 2, 5)), np.array([0.1]), tab.b, slice(0, 2),
                              lambda q: np.array([[0.0, 1.0], [1.0, 0.0]]))
    assert freedom[0].shape == (2, 0)
    slips = np.zeros((1, 4, 1))
    assert np.array_equal(coulomb_split(impulses, freedom, [MU], [1], slips), impulses)


# ---------------------------------------------------------------------- a solved plan

def low_box_problem(tmp_path, mu):
    """A 2 kg box on two 0.1 m contact spheres whose centres lie 0.1 m below its centre of
    mass, pushed from rest towards x = 0.15 m in 0.6 s (4 control intervals, |u_x| <= 20
    N): the friction turns it forwards, so the back contact carries more weight and, when
    it slides, more friction."""
    return pushed_box_problem(tmp_path, mu, HALF_SPAN, DEPTH)


@pytest.fixture(scope="module")
def low_box(tmp_path_factory) -> TimeFreezingPlan:
    """`low_box_problem` solved (measured: 3 s)."""
    return solved_plan(low_box_problem(tmp_path_factory.mktemp("low_box"), MU))


def test_a_box_pushed_on_contacts_below_its_centre_of_mass_passes_the_cone(low_box):
    """The minimum-norm split shared the friction evenly and gave false violations (cone
    5.1e-2 N s, dissipation 3.9e-2 N s over the tolerance 7.7e-3 N s); some admissible
    split obeys Coulomb's law (measured: cone 3e-17, dissipation 8e-8, replay 2.8e-7)."""
    verification = check_time_freezing_plan(low_box)
    assert verification.passed, verification.summary()
    assert verification.friction_cone_violation < 1e-9
    assert verification.dissipation_violation < 1e-6
    assert verification.end_state_deviation < 1e-6


def test_the_same_plan_checked_with_half_the_friction_fails_the_cone(low_box, tmp_path):
    """The plan's friction checked against mu / 2: it exceeds mu / 2 times the normal
    impulse at every split (the box slides at the edge of the mu cone), so the cone check
    fails by about mu / 4 times the element's normal impulses."""
    from tfcontact.ocp.contact import transcribe

    _, system = transcribe(low_box_problem(tmp_path, MU / 2))
    tampered = replace(low_box, system=system)
    verification = check_time_freezing_plan(tampered)
    assert not verification.passed
    note = next(n for n in verification.notes if n.startswith("friction-cone tolerance"))
    largest_normal = float(note.split("impulse ")[1].split(" N s")[0])
    assert verification.friction_cone_violation > 0.2 * MU / 4 * largest_normal
