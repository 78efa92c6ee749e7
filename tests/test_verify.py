import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.fesd import RadauIIA
from tfcontact.fesd.tableau import as_tableau
from tfcontact.mpcc import L1Penalty, Scholtes
from tfcontact.verify import (
    SLIP_THRESHOLD,
    AutoReplay,
    ExactReplay,
    FesdReplay,
    Verification,
    VerifyOptions,
    check_time_freezing_plan,
    clock_checks,
    collocation_impulses,
    contact_impulses,
    friction_cone_violation,
    maximal_dissipation_violation,
    methods,
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


def slip_samples(state_of_tau, h, tab):
    """v_x (the tangential velocity of the ground contact) at each element's start, Radau
    stages and end, shape (E, s + 2, 1)."""
    starts = np.concatenate([[0.0], np.cumsum(h)[:-1]])
    return np.array([[state_of_tau(a + c * dh)[2] for c in (0.0, *tab.c, 1.0)]
                     for a, dh in zip(starts, h, strict=True)])[:, :, None]


def sliding_state(deceleration, v0=3.0, s=1.0):
    def state(tau):
        t = s * tau
        return np.array([v0 * t - 0.5 * deceleration * t**2, 0.0, v0 - deceleration * t, 0.0, t])
    return state


@pytest.mark.parametrize("speed_of_time", [1.0, 3.0])
def test_coulomb_sliding_dissipates_maximally_and_reversed_friction_does_not(speed_of_time):
    """Sliding at mu g deceleration the friction is -mu Lambda_n along the slip: no violation
    on any of the 3 elements. Friction pushing along the slip stays inside the cone but
    misses Coulomb's law by ||mu Lambda_n + mu Lambda_n|| = 2 mu m g s h."""
    mu, s = 0.3, speed_of_time
    state = sliding_state(mu * G, s=s)
    h = np.array([0.01, 0.02, 0.015])
    x_start, x_stages, tab = collocated(state, h)
    impulses, _ = collocation_impulses_of(x_start, x_stages, h, tab)
    slip = slip_samples(state, h, tab)
    worst, checked = maximal_dissipation_violation(impulses, slip, [mu], [1])
    assert worst < 1e-12 and checked == 3
    along = impulses * [1.0, -1.0]
    assert friction_cone_violation(along, [mu], [1]) < 1e-12
    worst, checked = maximal_dissipation_violation(along, slip, [mu], [1])
    assert worst == pytest.approx(2 * mu * MASS * G * s * h.max(), rel=1e-9) and checked == 3


def test_friction_below_the_cone_edge_while_slipping_is_a_violation():
    """Braking at half of mu g is inside the cone (the cone check passes) but dissipates
    too little: the violation is mu Lambda_n - |Lambda_t| = 0.5 mu m g h."""
    mu = 0.4
    state = sliding_state(0.5 * mu * G)
    h = np.array([0.01, 0.02])
    x_start, x_stages, tab = collocated(state, h)
    impulses, _ = collocation_impulses_of(x_start, x_stages, h, tab)
    assert friction_cone_violation(impulses, [mu], [1]) < 1e-12
    worst, checked = maximal_dissipation_violation(impulses, slip_samples(state, h, tab),
                                                   [mu], [1])
    assert worst == pytest.approx(0.5 * mu * MASS * G * h.max(), rel=1e-9) and checked == 2


def test_an_element_whose_slip_reverses_is_not_checked():
    """v_x = v_1 - mu g t through zero in the middle of the second element: the first element
    (forward slip, friction backwards) is right; the second reverses and is skipped; in the
    third the block slips backwards with the friction still backwards: 2 mu m g h_3."""
    mu = 0.3
    h = np.array([0.01, 0.02, 0.015])
    state = sliding_state(mu * G, v0=0.02 * mu * G)  # v_x = 0 at t = 0.02
    x_start, x_stages, tab = collocated(state, h)
    impulses, _ = collocation_impulses_of(x_start, x_stages, h, tab)
    slip = slip_samples(state, h, tab)
    assert np.all(np.abs(slip[[0, 2]]) > SLIP_THRESHOLD)
    worst, checked = maximal_dissipation_violation(impulses, slip, [mu], [1])
    assert checked == 2
    assert worst == pytest.approx(2 * mu * MASS * G * h[2], rel=1e-9)


def test_a_sticking_element_is_not_checked():
    """No friction under a normal impulse of 1 N s is Coulomb only while the contact sticks:
    a slip below the threshold leaves it unchecked, a real slip makes it a violation mu."""
    mu = 0.5
    impulses = np.array([[1.0, 0.0]])
    sticking = np.array([[[1e-4], [-2e-4], [5e-4], [1e-4]]])
    assert maximal_dissipation_violation(impulses, sticking, [mu], [1]) == (0.0, 0)
    slipping = np.full((1, 4, 1), 0.5)
    assert maximal_dissipation_violation(impulses, slipping, [mu], [1]) == (
        pytest.approx(mu), 1)


def test_three_dimensional_slip_is_opposed_along_its_mean_direction():
    """Contact 1 is frictionless (no tangent columns), contact 2 has two tangents: its slip
    turns from 0.1 to 0.3 rad (mean direction 0.2 rad). Friction -mu Lambda_n d is right,
    the same friction turned by 90 degrees misses by sqrt(2) mu Lambda_n, and a slip turning
    by more than 90 degrees within the element is not checked."""
    mu, normal = 0.5, 2.0

    def slip_at(angles):
        return np.column_stack([np.cos(angles), np.sin(angles)])[None]

    turning = slip_at(np.array([0.1, 0.15, 0.25, 0.3]))
    d = np.array([np.cos(0.2), np.sin(0.2)])
    right = np.array([[3.0, normal, *(-mu * normal * d)]])  # (n_1, n_2, t_2a, t_2b)
    worst, checked = maximal_dissipation_violation(right, turning, [0.0, mu], [0, 2])
    assert worst < 1e-12 and checked == 1
    turned = np.array([[3.0, normal, *(mu * normal * np.array([d[1], -d[0]]))]])
    worst, _ = maximal_dissipation_violation(turned, turning, [0.0, mu], [0, 2])
    assert worst == pytest.approx(np.sqrt(2) * mu * normal, rel=1e-12)
    reversing = slip_at(np.array([0.0, 0.7, 1.4, 2.0]))
    assert maximal_dissipation_violation(turned, reversing, [0.0, mu], [0, 2]) == (0.0, 0)


def test_verification_without_a_dissipation_check_reports_nan():
    v = Verification(passed=True, method="m", end_state_deviation=0.0, min_gap=0.0,
                     friction_cone_violation=0.0, clock_monotone=True, clock_end_error=0.0)
    assert np.isnan(v.dissipation_violation)
    assert "maximal-dissipation violation nan N s" in v.summary()
    assert np.isnan(v.to_dict()["dissipation_violation"])


def test_verify_options_take_a_replay_object_and_positive_tolerances():
    """The replay method is a strategy object (no strings); bad values raise, naming the
    argument and the value."""
    default = VerifyOptions()
    assert default.replay == AutoReplay(fallback=FesdReplay(
        refinement=4, scheme=RadauIIA(3), relaxation=Scholtes()))
    assert VerifyOptions(replay=FesdReplay(refinement=2, relaxation=L1Penalty())).replay \
        .refinement == 2
    with pytest.raises(InvalidInput, match=r"`replay` must be a Replay object \(ExactReplay\(\), "
                                           r"FesdReplay\(\.\.\.\) or AutoReplay\(\)\), got 'fesd'"):
        VerifyOptions(replay="fesd")
    with pytest.raises(InvalidInput, match="`gap_tolerance` must be a positive number, got 0.0"):
        VerifyOptions(gap_tolerance=0.0)
    with pytest.raises(InvalidInput, match="`end_state_tolerance` must be a positive number, "
                                           "got nan"):
        VerifyOptions(end_state_tolerance=float("nan"))
    with pytest.raises(InvalidInput, match="`refinement` must be a positive integer, got 0"):
        FesdReplay(refinement=0)
    with pytest.raises(InvalidInput, match="`scheme` must be a Scheme"):
        FesdReplay(scheme=3)
    with pytest.raises(InvalidInput, match="`relaxation` must be a Relaxation"):
        FesdReplay(relaxation="scholtes")
    with pytest.raises(InvalidInput, match="`fallback` must be a FesdReplay, got ExactReplay()"):
        AutoReplay(fallback=ExactReplay())


@pytest.fixture(scope="module")
def pushed_particle():
    """A particle pushed along the ground for 0.6 s (3 control intervals, no impact): a
    solved time-freezing plan and what the checks read of it."""
    from tfcontact.ocp import ContactProblem, ContactSolverOptions, solve_contact
    from tfcontact.ocp.contact import time_freezing_plan
    from tfcontact.scenes.particles import point_mass
    from tfcontact.timefreezing import time_freeze

    tf = time_freeze(point_mass(2, mu=0.5, a_n=9.81, controlled=True))
    x = tf.y[tf.q_index][0]
    problem = ContactProblem(system=tf, q0=[0.0, 0.0], v0=[0.0, 0.0], horizon=0.6,
                             n_intervals=3, u_lower=-5.0, u_upper=5.0,
                             running_cost=10 * (x - 0.2) ** 2 + 1e-2 * ca.sumsqr(tf.u))
    options = ContactSolverOptions()
    result = solve_contact(problem, options, verbose=False)
    assert result.ocp.success, result.message
    return time_freezing_plan(problem, result.system, result.ocp, result.physical, options)


def test_each_replay_checks_a_plan_its_own_way(pushed_particle):
    """The exact replay gives the local defects (one per control interval); the FESD replay
    re-simulates on a finer grid and gives none; the other checks do not depend on the
    replay (measured: deviations 1.7e-7 and 1.1e-7)."""
    exact = check_time_freezing_plan(pushed_particle, VerifyOptions(replay=ExactReplay()))
    fesd = check_time_freezing_plan(pushed_particle, VerifyOptions(replay=FesdReplay(refinement=2)))
    auto = check_time_freezing_plan(pushed_particle)
    assert exact.passed and fesd.passed and auto.summary() == exact.summary()
    assert exact.method.startswith("event-detecting reference (DOP853, exact impacts)")
    assert len(exact.local_defects) == 3 and max(exact.local_defects) < 1e-5
    assert fesd.method == "FESD re-simulation, 6 steps x 3 elements, RadauIIA(stages=3)"
    assert fesd.local_defects == () and np.isnan(fesd.defect_sum)
    assert exact.end_state_deviation < 1e-5 and fesd.end_state_deviation < 1e-5
    for name in ("min_gap", "friction_cone_violation", "dissipation_violation",
                 "clock_end_error"):
        assert getattr(exact, name) == getattr(fesd, name)


def test_auto_replay_falls_back_to_fesd_where_the_reference_does_not_apply(pushed_particle,
                                                                           monkeypatch):
    """Where the exact reference raises (here made to: several frictional contacts are such
    a case), `ExactReplay` raises and `AutoReplay` notes why and replays with its fallback;
    the local defects (restarts of the reference per interval) are still computed."""
    def not_applicable(plan, end_state, window=0.0):
        raise IncompatibleOptions("several contacts with friction")

    monkeypatch.setattr(methods, "reference_deviation", not_applicable)
    with pytest.raises(IncompatibleOptions, match="several contacts with friction"):
        check_time_freezing_plan(pushed_particle, VerifyOptions(replay=ExactReplay()))
    auto = check_time_freezing_plan(pushed_particle, VerifyOptions(
        replay=AutoReplay(fallback=FesdReplay(refinement=2))))
    assert auto.passed and auto.method.startswith("FESD re-simulation, 6 steps")
    assert auto.notes[0] == ("event-detecting reference not applicable (several contacts "
                             "with friction); FESD used")
    assert len(auto.local_defects) == 3 and max(auto.local_defects) < 1e-5



def test_the_open_loop_replay_takes_a_start_on_the_ground_up_to_round_off():
    """A start put on the ground by hand lies a few 1e-12 m inside it (finger_edu's tip,
    its angles and table height written to ten digits): the replay starts there in
    persistent contact (a resting mass stays at rest), up to `START_ROUNDOFF`; a start
    1 um inside is an error, not a start."""
    from tfcontact.scenes.particles import point_mass
    from tfcontact.verify.replay import START_ROUNDOFF, ReplayedPlan

    def resting(depth):
        x0 = np.array([-depth, 0.0])
        return ReplayedPlan(cls=point_mass(1), x0=x0, clocks=np.array([0.0, 0.1]),
                            states=np.stack([x0, x0]), controls=np.zeros((1, 0)),
                            horizon=0.1)

    for depth in (5e-12, 0.5 * START_ROUNDOFF):
        replay = resting(depth).replay()
        assert replay.status == "success"
        np.testing.assert_allclose(replay.final_state(), [-depth, 0.0], atol=1e-12)
    with pytest.raises(InvalidInput, match="inside the obstacle"):
        resting(1e-6).replay()
