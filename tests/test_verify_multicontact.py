"""The multi-contact reference simulator (`tfcontact.verify.multicontact`) and its LCP
solver (`tfcontact.verify.lcp`), against closed forms of boxes on the ground with two and
four frictional corner contacts."""

import casadi as ca
import numpy as np
import pytest
from two_contact_box import load_box

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact
from tfcontact.verify import (
    ContactMode,
    EventKind,
    MultiContactOptions,
    ReplayedPlan,
    SimulationStatus,
    defect_segments,
    multicontact_local_defects,
    simulate_multicontact,
    solve_lcp,
)

G = 9.81
MASS, HALF_WIDTH, HALF_HEIGHT = 2.0, 0.5, 0.25  # planar box [kg], a [m], b [m]


def planar_box(mu, *, push=False, restitution=0.0):
    """A uniform box in the x-z plane, q = (x, z, pitch), corners (+-a, -b) in the body
    frame, M = diag(m, m, I); u: a horizontal force at the centre of mass."""
    a, b = HALF_WIDTH, HALF_HEIGHT
    q, v = ca.SX.sym("q", 3), ca.SX.sym("v", 3)
    u = ca.SX.sym("u", 1 if push else 0)
    x, z, pitch = q[0], q[1], q[2]
    contacts = []
    for k, px in enumerate((a, -a)):
        xc = x + px * ca.cos(pitch) - b * ca.sin(pitch)
        zc = z - px * ca.sin(pitch) - b * ca.cos(pitch)
        contacts.append(Contact(gap=zc, tangents=ca.jacobian(xc, q).T, mu=mu,
                                restitution=restitution, name=f"corner{k}"))
    inertia = MASS * (4 * a * a + 4 * b * b) / 12
    force = ca.vertcat(u[0] if push else 0.0, -MASS * G, 0.0)
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.diag(ca.vertcat(MASS, MASS, inertia)), forces=force,
        contacts=tuple(contacts))


def planar_mass_matrix():
    a, b = HALF_WIDTH, HALF_HEIGHT
    return np.diag([MASS, MASS, MASS * (4 * a * a + 4 * b * b) / 12])


def spatial_box(mu, *, push=False, m=3.0, a=0.4, c=0.3, b=0.2):
    """A box with four corner contacts (+-a, +-c, -b), q = (x, y, z, roll, pitch, yaw)
    (ZYX Euler angles for the corners' positions), M = diag(m, m, m, I) constant: a
    Lagrangian system of its own (the angular velocity is taken as the Euler rates), exact
    for the rigid box while it does not rotate, which is all the closed forms need."""
    q, v = ca.SX.sym("q", 6), ca.SX.sym("v", 6)
    u = ca.SX.sym("u", 2 if push else 0)
    roll, pitch, yaw = q[3], q[4], q[5]
    rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, ca.cos(roll), -ca.sin(roll)),
                    ca.horzcat(0, ca.sin(roll), ca.cos(roll)))
    ry = ca.vertcat(ca.horzcat(ca.cos(pitch), 0, ca.sin(pitch)), ca.horzcat(0, 1, 0),
                    ca.horzcat(-ca.sin(pitch), 0, ca.cos(pitch)))
    rz = ca.vertcat(ca.horzcat(ca.cos(yaw), -ca.sin(yaw), 0),
                    ca.horzcat(ca.sin(yaw), ca.cos(yaw), 0), ca.horzcat(0, 0, 1))
    rotation = rz @ ry @ rx
    contacts = []
    for k, (px, py) in enumerate([(a, c), (a, -c), (-a, c), (-a, -c)]):
        corner = q[:3] + rotation @ ca.vertcat(px, py, -b)
        contacts.append(Contact(gap=corner[2], tangents=ca.jacobian(corner[:2], q).T, mu=mu,
                                name=f"corner{k}"))
    inertia = m / 12 * np.array([4 * c * c + 4 * b * b, 4 * a * a + 4 * b * b,
                                 4 * a * a + 4 * c * c])
    force = ca.vertcat(u[0] if push else 0.0, u[1] if push else 0.0, -m * G, 0.0, 0.0, 0.0)
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.diag(ca.vertcat(m, m, m, *inertia)), forces=force,
        contacts=tuple(contacts))


def resting(v=(0.0, 0.0, 0.0), height=HALF_HEIGHT):
    return np.array([0.0, height, 0.0, *v])


# ---------------------------------------------------------------------- LCP


@pytest.mark.parametrize(("M", "q", "z"), [
    ([[2.0, 1.0], [1.0, 2.0]], [-5.0, -6.0], [4 / 3, 7 / 3]),  # both positive: M z = -q
    ([[2.0, 1.0], [1.0, 2.0]], [-4.0, 3.0], [2.0, 0.0]),  # w_2 = 5 > 0
    ([[1.0, 0.0], [0.0, 1.0]], [1.0, 2.0], [0.0, 0.0]),  # q >= 0: z = 0
    ([[0.0, 1.0], [-1.0, 0.0]], [-1.0, 1.0], [1.0, 1.0]),  # skew (copositive-plus)
])
def test_lcp_known_solutions(M, q, z):
    solution = solve_lcp(np.array(M), np.array(q))
    assert solution.solved
    np.testing.assert_allclose(solution.z, z, atol=1e-12)
    assert solution.residual() < 1e-12


@pytest.mark.parametrize("kind", ["positive_definite", "monotone", "friction"])
def test_lcp_random_solutions_are_complementary_and_feasible(kind, rng):
    for _ in range(60):
        n = int(rng.integers(1, 10))
        a = rng.normal(size=(n, n))
        if kind == "positive_definite":  # a P-matrix: a unique solution
            M, q = a @ a.T + 0.1 * np.eye(n), rng.normal(size=n)
        elif kind == "monotone":  # PSD plus skew: copositive-plus, feasible
            M, q = a @ a.T + (a - a.T), rng.normal(size=n)
        else:  # the planar friction LCP of k random contacts (module verify.multicontact)
            k = max(1, n // 4)
            jac = rng.normal(size=(4, 2 * k))
            delassus = jac.T @ jac + 1e-3 * np.eye(2 * k)  # J columns: n_1, t_1, n_2, ...
            rows = [np.eye(2 * k)[2 * i] for i in range(k)]  # normals
            rows += [sign * np.eye(2 * k)[2 * i + 1] for i in range(k) for sign in (1, -1)]
            H = np.array(rows)  # (3k, 2k): lambda_n, beta (+t, -t) per contact
            n = 4 * k
            M = np.zeros((n, n))
            M[:3 * k, :3 * k] = H @ delassus @ H.T
            for i in range(k):
                beta = slice(k + 2 * i, k + 2 * i + 2)
                M[beta, 3 * k + i] = 1.0  # gamma
                M[3 * k + i, i] = 0.7  # mu
                M[3 * k + i, beta] = -1.0
            q = np.concatenate([rng.normal(size=3 * k), np.zeros(k)])
        solution = solve_lcp(M, q)
        assert solution.solved, (kind, n)
        scale = (1.0 + np.abs(q).max()) * (1.0 + np.abs(solution.z).max())
        assert solution.residual() <= 1e-9 * scale
        np.testing.assert_allclose(solution.w, M @ solution.z + q, atol=1e-12 * scale)


def test_lcp_infeasible_ends_on_a_ray_and_rejects_bad_shapes():
    assert solve_lcp([[-1.0]], [-1.0]).status == "ray"  # w = -z - 1 < 0 for z >= 0
    with pytest.raises(InvalidInput, match=r"`M` must have shape \(2, 2\)"):
        solve_lcp(np.eye(3), np.ones(2))


# ---------------------------------------------------------------------- planar box


@pytest.mark.parametrize("mu", [0.2, 0.6])
def test_planar_box_sliding_stops_at_the_coulomb_time_and_distance(mu):
    """Both corners slide: x'' = -mu g until t* = v0 / (mu g), x(t*) = v0^2 / (2 mu g);
    the friction at height -b tips the box forwards: lambda_front - lambda_back =
    mu b m g / a, their sum m g; at rest both carry m g / 2."""
    v0, a, b = 2.0, HALF_WIDTH, HALF_HEIGHT
    stop = v0 / (mu * G)
    sim = simulate_multicontact(planar_box(mu), resting((v0, 0.0, 0.0)), None, stop + 0.3)
    assert sim.success
    kinds = [(e.kind, e.contact) for e in sim.events]
    assert kinds == [(EventKind.STICK, 0), (EventKind.STICK, 1)]
    np.testing.assert_allclose([e.time for e in sim.events], stop, rtol=1e-9)
    np.testing.assert_allclose(sim.x[-1], [v0**2 / (2 * mu * G), b, 0, 0, 0, 0], atol=1e-9)
    # the samples before the stop event (the event's own samples, located to round-off
    # near t*, may fall an ulp below it and carry the resting forces)
    sliding = (sim.t > 0) & (sim.t < sim.events[0].time)
    assert sliding.sum() >= 1
    weight = MASS * G
    np.testing.assert_allclose(sim.normal_forces[sliding],
                               np.tile([weight / 2 * (1 + mu * b / a),
                                        weight / 2 * (1 - mu * b / a)], (sliding.sum(), 1)),
                               rtol=1e-9)
    np.testing.assert_allclose(sim.tangential_forces[sliding, :, 0],
                               -mu * sim.normal_forces[sliding], rtol=1e-9)
    np.testing.assert_allclose(sim.normal_forces[-1], [weight / 2, weight / 2], rtol=1e-9)
    assert all(mode != ContactMode.OPEN for _, modes in sim.modes for mode in modes)
    assert sim.max_gap_drift < 1e-12


@pytest.mark.parametrize("vx", [3.0, 0.5])
def test_planar_box_dropped_flat_lands_on_both_corners_with_a_frictional_impulse(vx):
    """Dropped from height h with horizontal speed vx: both corners hit at sqrt(2h/g); the
    normal impulse P = m sqrt(2 g h) stops the fall (no rotation: Lambda_front -
    Lambda_back = b |Lambda_t| / a); vx+ = vx - mu P / m if that is positive (slip through
    the impact), else 0 (stick, Lambda_t = -m vx); then the box slides to rest."""
    mu, h, a, b = 0.4, 0.3, HALF_WIDTH, HALF_HEIGHT
    t_hit = np.sqrt(2 * h / G)
    impulse = MASS * np.sqrt(2 * G * h)
    vx_after = max(vx - mu * impulse / MASS, 0.0)
    T = t_hit + vx_after / (mu * G) + 0.2
    sim = simulate_multicontact(planar_box(mu), resting((vx, 0.0, 0.0), HALF_HEIGHT + h),
                                None, T)
    assert sim.success
    (impact,) = sim.impacts
    assert impact.contacts == (0, 1)
    np.testing.assert_allclose(impact.time, t_hit, rtol=1e-10)
    assert [(e.kind, e.contact) for e in sim.events[:2]] == [(EventKind.IMPACT, 0),
                                                               (EventKind.IMPACT, 1)]
    np.testing.assert_allclose(impact.post[3:], [vx_after, 0.0, 0.0], atol=1e-9)
    tangential = -MASS * (vx - vx_after)
    np.testing.assert_allclose(impact.normal_impulses.sum(), impulse, rtol=1e-10)
    np.testing.assert_allclose(impact.tangential_impulses.sum(), tangential, rtol=1e-9)
    np.testing.assert_allclose(impact.normal_impulses[0] - impact.normal_impulses[1],
                               -b * tangential / a, rtol=1e-9)
    x_end = vx * t_hit + vx_after**2 / (2 * mu * G)
    np.testing.assert_allclose(sim.x[-1], [x_end, b, 0, 0, 0, 0], atol=1e-9)


def test_planar_box_dropped_tilted_lands_corner_by_corner_and_comes_to_rest():
    """The lower corner lands first at sqrt(2 h_low / g) (free fall of its height h_low);
    then the box rotates about it and the other corner lands; the energy never rises and
    the box ends at rest, flat on the ground."""
    pitch, z0, mu = 0.2, 0.5, 0.5
    a, b = HALF_WIDTH, HALF_HEIGHT
    sim = simulate_multicontact(planar_box(mu), np.array([0, z0, pitch, 0, 0, 0]), None, 1.5)
    assert sim.success
    impacts = [(e.time, e.contact) for e in sim.events if e.kind == EventKind.IMPACT]
    low = z0 - a * np.sin(pitch) - b * np.cos(pitch)
    assert impacts[0][1] == 0 and impacts[1][1] == 1
    np.testing.assert_allclose(impacts[0][0], np.sqrt(2 * low / G), rtol=1e-10)
    assert impacts[1][0] > impacts[0][0]
    M = planar_mass_matrix()
    energy = 0.5 * np.einsum("ki,ij,kj->k", sim.x[:, 3:], M, sim.x[:, 3:]) + MASS * G * sim.x[:, 1]
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])
    np.testing.assert_allclose(sim.x[-1, 1:], [b, 0, 0, 0, 0], atol=1e-9)
    for impact in sim.impacts:  # inelastic: kinetic energy lost, impulses in the cone
        assert impact.post[3:] @ M @ impact.post[3:] <= impact.pre[3:] @ M @ impact.pre[3:]
        assert np.all(np.abs(impact.tangential_impulses[:, 0])
                      <= mu * impact.normal_impulses + 1e-12)


@pytest.mark.parametrize("contact_tolerance", [1e-8, 1e-6])
def test_corners_within_the_contact_tolerance_take_part_in_one_impact(contact_tolerance):
    """The box dropped nearly flat, frictionless, corner 0 lower by delta = 1e-7 m: with a
    contact tolerance above delta both corners take part in one impact, each normal
    impulse m v / 2 and the box at rest; below it, corner 0 alone, with the impulse
    m v / (1 + m a^2 / I) of a single corner (to O(delta / a)), and the box rotates."""
    h, delta, a = 0.05, 1e-7, HALF_WIDTH
    pitch = delta / (2 * a)
    z0 = HALF_HEIGHT + h + a * np.sin(pitch) - HALF_HEIGHT * (1 - np.cos(pitch))
    speed = np.sqrt(2 * G * h)  # of corner 0 at its touchdown
    sim = simulate_multicontact(planar_box(0.0), np.array([0.0, z0, pitch, 0, 0, 0]), None,
                                0.15, options=MultiContactOptions(
                                    contact_tolerance=contact_tolerance))
    assert sim.success
    first = sim.impacts[0]
    assert first.time == pytest.approx(np.sqrt(2 * h / G), rel=1e-8)
    if contact_tolerance > delta:
        assert first.contacts == (0, 1)
        np.testing.assert_allclose(first.normal_impulses, MASS * speed / 2, rtol=1e-5)
        np.testing.assert_allclose(first.post[3:], 0.0, atol=1e-5)
    else:
        inertia = planar_mass_matrix()[2, 2]
        assert first.contacts == (0,)
        np.testing.assert_allclose(first.normal_impulses,
                                   MASS * speed / (1 + MASS * a * a / inertia), rtol=1e-5)
        assert abs(first.post[5]) > 1.0  # it turns about corner 0
        assert len(sim.impacts) > 1


@pytest.mark.parametrize("ratio", [0.5, 0.9, 1.5])
def test_planar_box_pushed_sticks_below_mu_m_g_and_slides_above(ratio):
    """A force F = ratio mu m g at the centre of mass: no motion for F < mu m g (0.9 is
    past the 1 / (1 + mu b / a) = 0.8 that an even split of the friction would allow:
    the indeterminate sticking forces must be redistributed), x = (F - mu m g) t^2 / (2 m)
    for F > mu m g."""
    mu, T = 0.5, 0.8
    force = ratio * mu * MASS * G
    sim = simulate_multicontact(planar_box(mu, push=True), resting(), lambda t: [force], T)
    assert sim.success
    acceleration = max(force - mu * MASS * G, 0.0) / MASS
    np.testing.assert_allclose(sim.x[-1], [acceleration * T**2 / 2, HALF_HEIGHT, 0,
                                           acceleration * T, 0, 0], atol=1e-9)
    expected = ContactMode.STICK if ratio < 1 else ContactMode.SLIP
    assert sim.modes == ((0.0, (expected, expected)),)


def test_planar_box_pushed_by_a_ramp_slips_exactly_at_mu_m_g():
    """F = k t: the box sticks until k t* = mu m g (the margin of the indeterminate
    sticking forces reaches zero), then x'' = (k t - mu m g) / m:
    x(T) = k (T - t*)^3 / (6 m)."""
    mu, k, T = 0.5, 20.0, 1.0
    slip = mu * MASS * G / k
    sim = simulate_multicontact(planar_box(mu, push=True), resting(), lambda t: [k * t], T)
    assert sim.success
    assert [(e.kind, e.contact) for e in sim.events] == [(EventKind.SLIP, 0),
                                                          (EventKind.SLIP, 1)]
    np.testing.assert_allclose(sim.events[0].time, slip, rtol=1e-10)
    np.testing.assert_allclose(sim.x[-1, [0, 3]], [k * (T - slip)**3 / (6 * MASS),
                                                   k * (T - slip)**2 / (2 * MASS)], atol=1e-10)


# ---------------------------------------------------------------------- 3-D box


def test_spatial_box_sliding_diagonally_stops_along_its_direction():
    """Four corners slide along (cos alpha, sin alpha): the exact cone in slip gives
    t* = v0 / (mu g) and the distance v0^2 / (2 mu g) along the start direction, no
    rotation; the pyramid (16 facets) only decides the stick at the end."""
    mu, v0, alpha, b = 0.5, 2.0, 0.6, 0.2
    direction = np.array([np.cos(alpha), np.sin(alpha)])
    x0 = np.zeros(12)
    x0[2], x0[6:8] = b, v0 * direction
    stop = v0 / (mu * G)
    sim = simulate_multicontact(spatial_box(mu), x0, None, stop + 0.2)
    assert sim.success
    assert [e.kind for e in sim.events] == [EventKind.STICK] * 4
    np.testing.assert_allclose([e.time for e in sim.events], stop, rtol=1e-9)
    end = np.zeros(12)
    end[:2], end[2] = v0**2 / (2 * mu * G) * direction, b
    np.testing.assert_allclose(sim.x[-1], end, atol=1e-9)
    np.testing.assert_allclose(sim.normal_forces[-1].sum(), 3.0 * G, rtol=1e-9)


@pytest.mark.parametrize("ratio", [0.9, 1.2])
def test_spatial_box_pushed_diagonally_sticks_or_slides(ratio):
    """F = ratio mu m g along (cos alpha, sin alpha): the inscribed 16-facet pyramid holds
    it for ratio <= cos(pi/16) = 0.98 (0.9 sticks); 1.2 slides with (F - mu m g) / m along
    the push (the slip direction from rest solved exactly)."""
    mu, m, alpha, b, T = 0.5, 3.0, 0.6, 0.2, 0.4
    direction = np.array([np.cos(alpha), np.sin(alpha)])
    x0 = np.zeros(12)
    x0[2] = b
    force = ratio * mu * m * G * direction
    sim = simulate_multicontact(spatial_box(mu, push=True), x0, lambda t: force, T)
    assert sim.success
    acceleration = max(ratio - 1.0, 0.0) * mu * G
    end = np.zeros(12)
    end[:2], end[2] = acceleration * T**2 / 2 * direction, b
    end[6:8] = acceleration * T * direction
    np.testing.assert_allclose(sim.x[-1], end, atol=1e-9)


# ---------------------------------------------------------------------- failures


def painleve_rod():
    """A rod (length 2, m = 1, I = 1/3) on its lower end, mu = 2: at 0.8 rad, sliding
    towards its base, n^T M^-1 (n - mu B s) = 1 + 3 cos^2 - 6 cos sin < 0 (Painleve)."""
    q, v = ca.SX.sym("q", 3), ca.SX.sym("v", 3)
    end_x, end_z = q[0] - ca.cos(q[2]), q[1] - ca.sin(q[2])
    contact = Contact(gap=end_z, tangents=ca.jacobian(end_x, q).T, mu=2.0, name="end")
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=ca.SX(0, 1), mass_matrix=ca.diag(ca.vertcat(1.0, 1.0, 1 / 3)),
        forces=ca.vertcat(0.0, -G, 0.0), contacts=(contact,))


def test_painleve_slip_and_the_event_cap_are_statuses():
    pitch = 0.8
    start = np.array([0.0, np.sin(pitch), pitch, -1.0, 0.0, 0.0])
    sim = simulate_multicontact(painleve_rod(), start, None, 0.5)
    assert sim.status == SimulationStatus.PAINLEVE
    assert "Painleve" in sim.message and not sim.success
    capped = simulate_multicontact(planar_box(0.5), np.array([0, 0.5, 0.2, 0, 0, 0]), None,
                                   1.5, options=MultiContactOptions(max_events=1))
    assert capped.status == SimulationStatus.MAX_EVENTS
    assert "max_events" in capped.message


@pytest.mark.parametrize("push_ratio", [0.0, 0.5])
def test_a_restart_inside_the_ground_that_separates_lands_back_at_its_depth(push_ratio):
    """A plan's restart 2e-8 m inside the ground (within the start tolerance) with a
    separating normal velocity 3e-7 m/s (above `velocity_tolerance`): free flight back to
    the start's depth after 2 v_n / g, an inelastic landing, then rest (stick below
    mu m g) - not a touchdown event at t = 0 over and over until the event cap."""
    depth, vn, mu = 2e-8, 3e-7, 0.5
    start = resting(v=(0.0, vn, 0.0), height=HALF_HEIGHT - depth)
    push = np.array([push_ratio * mu * MASS * G])
    sim = simulate_multicontact(planar_box(mu, push=True), start, lambda t: push, 0.05,
                                options=MultiContactOptions(start_gap_tolerance=1e-7))
    assert sim.success, sim.message
    assert len(sim.impacts) == 1
    # The flight's apex is 5e-15 m, a few ulps of z = 0.25 m: the landing time to 1 %.
    assert sim.impacts[0].time == pytest.approx(2 * vn / G, rel=1e-2)
    assert {e.kind for e in sim.events} == {EventKind.IMPACT}
    assert sim.modes[-1][1] == (ContactMode.STICK, ContactMode.STICK)
    np.testing.assert_allclose(sim.final_state(), start * [1, 1, 1, 0, 0, 0], atol=1e-12)


def test_contact_equations_that_cannot_be_solved_end_the_simulation_not_the_caller(
        monkeypatch):
    """A least-squares solve of the contact rows that fails (numpy's LinAlgError: bolt on a
    step, a restart whose trial step reached non-finite states) ends the simulation with
    status integration_failed and a message, as a failed replay; it does not raise out of
    the verification (which then lost the plan's output)."""
    from tfcontact.verify import multicontact

    calls = {"n": 0}
    lstsq = np.linalg.lstsq

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] > 2:
            raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")
        return lstsq(*args, **kwargs)

    monkeypatch.setattr(multicontact.np.linalg, "lstsq", failing)
    push = np.array([0.2 * 0.5 * MASS * G])
    sim = simulate_multicontact(planar_box(0.5, push=True), resting(), lambda t: push, 0.05)
    assert calls["n"] > 2
    assert sim.status == SimulationStatus.INTEGRATION_FAILED and not sim.success
    assert "could not be solved" in sim.message and "SVD" in sim.message


def test_inputs_are_checked():
    with pytest.raises(InvalidInput, match="`facets` must be even"):
        MultiContactOptions(facets=5)
    with pytest.raises(InvalidInput, match="`rtol` must be a positive number"):
        MultiContactOptions(rtol=0.0)
    with pytest.raises(IncompatibleOptions, match="restitution 0.5"):
        simulate_multicontact(planar_box(0.5, restitution=0.5), resting(), None, 1.0)
    with pytest.raises(InvalidInput, match="inside an obstacle"):
        simulate_multicontact(planar_box(0.5), resting(height=0.2), None, 1.0)
    with pytest.raises(InvalidInput, match=r"`x0` must be finite with shape \(6,\)"):
        simulate_multicontact(planar_box(0.5), np.zeros(4), None, 1.0)


# ---------------------------------------------------------------------- local defects


def pushed_box_plan(mu, ratios, dt):
    """The box pushed by ratios[k] mu m g on interval k, from rest, in closed form:
    x'' = (F - mu m g) / m while it moves (or F > mu m g), else at rest."""
    clocks = dt * np.arange(len(ratios) + 1)
    x, v, states = 0.0, 0.0, [resting()]
    for ratio in ratios:
        a_slide = (ratio - 1.0) * mu * G
        if v == 0.0 and ratio <= 1.0:
            pass
        elif a_slide >= 0 or v + a_slide * dt > 0:
            x, v = x + v * dt + a_slide * dt**2 / 2, v + a_slide * dt
        else:  # stops inside the interval, then sticks (ratio < 1)
            x, v = x - v**2 / (2 * a_slide), 0.0
        states.append(resting((v, 0.0, 0.0)) + np.array([x, 0, 0, 0, 0, 0]))
    controls = (np.array(ratios) * mu * MASS * G)[:, None]
    return clocks, np.array(states), controls


def test_local_defects_vanish_for_the_closed_form_and_not_for_a_wrong_plan():
    mu, dt = 0.5, 0.2
    ratios = [1.5, 1.5, 0.3, 0.3, 0.3]
    clocks, states, controls = pushed_box_plan(mu, ratios, dt)
    cls = planar_box(mu, push=True)
    plan = ReplayedPlan(cls=cls, x0=states[0], clocks=clocks, states=states,
                        controls=controls, horizon=float(clocks[-1]))
    segments = defect_segments(clocks, np.zeros(len(ratios), dtype=bool))
    defects = np.array(multicontact_local_defects(plan, segments, gap_tolerance=1e-9))
    assert defects.shape == (len(ratios),)
    assert np.all(defects < 1e-9)
    _, frictionless, _ = pushed_box_plan(0.3, ratios, dt)  # the plan of a wrong friction
    wrong = ReplayedPlan(cls=cls, x0=states[0], clocks=clocks, states=frictionless,
                         controls=controls, horizon=float(clocks[-1]))
    wrong_defects = np.array(multicontact_local_defects(wrong, segments, gap_tolerance=1e-9))
    assert np.all(wrong_defects[:2] > 0.1)


# ---------------------------------------------------------------------- robustness, URDF


def test_random_tilted_drops_end_at_rest_without_gaining_energy(rng):
    """Seeded drops with random friction, tilt, spin and horizontal speed: every run
    succeeds, the energy never rises (beyond the integrator's tolerance) and the box ends
    flat at rest."""
    M = planar_mass_matrix()
    for _ in range(8):
        mu, pitch = rng.uniform(0.3, 1.0), rng.uniform(-0.5, 0.5)  # at rest by T = 2 s
        vx, spin = rng.uniform(-2.0, 2.0), rng.uniform(-1.5, 1.5)
        sim = simulate_multicontact(planar_box(mu), np.array([0, 0.6, pitch, vx, 0, spin]),
                                    None, 2.0)
        assert sim.success, sim.message
        energy = (0.5 * np.einsum("ki,ij,kj->k", sim.x[:, 3:], M, sim.x[:, 3:])
                  + MASS * G * sim.x[:, 1])
        assert np.diff(energy).max() <= 1e-9 * energy[0]
        np.testing.assert_allclose(sim.x[-1, 1:], [HALF_HEIGHT, 0, 0, 0, 0], atol=1e-9)


def test_urdf_box_through_the_robot_layer_slides_to_the_coulomb_stop(tmp_path):
    """The same sliding box from a URDF (planar base, two 1 mm contact spheres whose
    centres are 0.249 m below the body's): the CLS of `from_robot` is simulated as is.
    Stop at v0 / (mu g); the friction acts at the spheres' centres, so the normal forces
    split as m g / 2 (1 +- mu 0.249 / a)."""
    from tfcontact.timefreezing import from_robot

    robot = load_box(tmp_path, 0.5, 0.249, 0.001)
    mu, v0 = 0.4, 2.0
    cls = from_robot(robot, mu=mu)
    stop = v0 / (mu * G)
    sim = simulate_multicontact(cls, np.array([0.0, 0.25, 0.0, v0, 0.0, 0.0]), None,
                                stop + 0.2)
    assert sim.success
    np.testing.assert_allclose([e.time for e in sim.events], stop, rtol=1e-9)
    np.testing.assert_allclose(sim.x[-1], [v0**2 / (2 * mu * G), 0.25, 0, 0, 0, 0],
                               atol=1e-9)
    sliding = (sim.t > 0) & (sim.t < sim.events[0].time)
    split = mu * 0.249 / 0.5
    np.testing.assert_allclose(sim.normal_forces[sliding][0],
                               [MASS * G / 2 * (1 + split), MASS * G / 2 * (1 - split)],
                               rtol=1e-9)
