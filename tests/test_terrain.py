"""tfcontact.robot.terrain: gaps against closed forms, C1 smoothness, relevance, contact
terms against a Ground and against Pinocchio, friction into the CLS, bad input.

References: closed-form distances (planes, box faces, the rounding circle and sphere of an
edge and a corner, hole walls and rims) written here in numpy; the sphere centre of a
contact from Pinocchio's forward kinematics; derivatives by central finite differences.
"""

from __future__ import annotations

import json
import math

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.robot import (
    Box,
    ContactSpec,
    Ground,
    Hole,
    Plane,
    Region,
    Terrain,
    load_robot,
)
from tfcontact.robot.contact import terrain_tangents
from tfcontact.robot.terrain import smooth_min
from tfcontact.timefreezing.from_robot import from_robot

R = 0.02  # contact sphere radius [m]
INF = math.inf


def gap(terrain: Terrain, point, radius: float = R) -> float:
    return float(terrain.gap(np.asarray(point, dtype=float), radius))


def gap_function(terrain: Terrain, radius: float = R) -> ca.Function:
    p = ca.SX.sym("p", 3)
    g = terrain.gap(p, radius)
    return ca.Function("g", [p], [g, ca.gradient(g, p)])


def central_gradient(f: ca.Function, p: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    out = np.zeros(3)
    for i in range(3):
        dp = np.zeros(3)
        dp[i] = eps
        out[i] = (float(f(p + dp)[0]) - float(f(p - dp)[0])) / (2 * eps)
    return out


# ------------------------------------------------------------------ gaps: closed forms
def test_flat_plane_gap_and_normal():
    t = Terrain((Plane(height=0.1),))
    assert gap(t, (0.3, -2.0, 0.5)) == pytest.approx(0.5 - 0.1 - R, abs=1e-15)
    assert gap(t, (0.3, -2.0, 0.05)) == pytest.approx(0.05 - 0.1 - R, abs=1e-15)
    np.testing.assert_allclose(np.array(t.normal((1.0, 2.0, 3.0))).ravel(), [0, 0, 1])


@pytest.mark.parametrize("slope", [(0.3, 0.0), (0.3, -0.1), (-0.5, 0.2)])
def test_sloped_plane_gap_is_the_distance_to_the_plane(slope, rng):
    plane = Plane.sloped(0.2, slope, friction=0.4)
    t = Terrain((plane,))
    sx, sy = slope
    n = np.array([-sx, -sy, 1.0]) / math.sqrt(1 + sx * sx + sy * sy)
    for p in rng.uniform(-1, 1, (5, 3)):
        # distance along n from the point of the plane below p
        foot = np.array([p[0], p[1], 0.2 + sx * p[0] + sy * p[1]])
        assert gap(t, p) == pytest.approx(n @ (p - foot) - R, abs=1e-14)
        np.testing.assert_allclose(np.array(t.normal(p)).ravel(), n, atol=1e-14)
    assert t.height_at(1.0, 2.0) == pytest.approx(0.2 + sx + 2 * sy, abs=1e-14)
    assert t.friction_at(1.0, 2.0) == 0.4


STEP = Box(x=(0.5, 1.5), top=0.05, rounding=0.01, friction=0.8)


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        ((1.0, 0.0, 0.12), 0.12 - 0.05 - R),  # above the top face
        ((0.45, 0.0, 0.02), 0.5 - 0.45 - R),  # beside the left face, below the rounding
        ((1.53, 0.0, -0.2), 1.53 - 1.5 - R),  # beside the right face
        ((1.0, 0.0, 0.03), 0.03 - 0.05 - R),  # penetrating the top (inside, face nearest)
        # near the rounded edge: distance to the rounding circle of radius 0.01 centred
        # at (0.51, 0.04), minus r
        ((0.49, 0.0, 0.07), math.hypot(0.49 - 0.51, 0.07 - 0.04) - 0.01 - R),
        ((0.505, 0.0, 0.052), math.hypot(0.505 - 0.51, 0.052 - 0.04) - 0.01 - R),
    ],
)
def test_planar_box_gap(point, expected):
    t = Terrain((STEP,))
    assert gap(t, point) == pytest.approx(expected, abs=1e-14)


def test_box_corner_in_3d_is_a_sphere_and_faces_are_exact():
    box = Box(x=(0.0, 1.0), y=(-0.5, 0.5), top=0.2, rounding=0.05)
    t = Terrain((box,))
    corner = np.array([0.05, 0.45, 0.15])  # inner box corner
    p = np.array([-0.1, 0.6, 0.3])
    assert gap(t, p) == pytest.approx(np.linalg.norm(p - corner) - 0.05 - R, abs=1e-14)
    np.testing.assert_allclose(np.array(t.normal(p)).ravel(),
                               (p - corner) / np.linalg.norm(p - corner), atol=1e-14)
    assert gap(t, (0.5, 0.0, 0.4)) == pytest.approx(0.2 - R, abs=1e-14)
    assert gap(t, (0.5, -0.8, 0.1)) == pytest.approx(0.3 - R, abs=1e-14)
    assert gap(t, (0.5, 0.0, -3.0)) == pytest.approx(-0.5 - R, abs=1e-14)  # y faces nearest


def test_step_on_the_ground_is_the_minimum():
    t = Terrain((Plane(friction=0.5), STEP))
    assert gap(t, (0.2, 0.0, 0.1)) == pytest.approx(0.1 - R)  # ground
    assert gap(t, (1.0, 0.0, 0.1)) == pytest.approx(0.05 - R)  # step top
    assert gap(t, (0.47, 0.0, 0.04)) == pytest.approx(0.03 - R)  # the step's face is nearer
    assert t.height_at(0.2) == 0.0 and t.height_at(1.0) == 0.05
    assert t.friction_at(0.2) == 0.5 and t.friction_at(1.0) == 0.8


def test_bottomless_hole_gives_no_support():
    rho = 0.01
    t = Terrain((Plane(), Hole(x=(1.0, 1.4), rounding=rho)))
    # far below the ground inside the hole: only the walls, sideways
    assert gap(t, (1.1, 0.0, -2.0)) == pytest.approx(0.1 - R, abs=1e-14)
    assert gap(t, (1.3, 0.0, -5.0)) == pytest.approx(0.1 - R, abs=1e-14)
    # at the ground's level over the middle of the hole: the rims, 0.2 m away (the
    # rounding circles centred rho outside the footprint and rho below the plane)
    middle = (1.2, 0.0, 0.0)
    assert gap(t, middle) == pytest.approx(math.hypot(0.2 + rho, rho) - rho - R, abs=1e-14)
    # just over the rim: the rounding circle centred at (1 - rho, -rho)
    p = (1.003, 0.0, 0.004)
    assert gap(t, p) == pytest.approx(math.hypot(p[0] - (1 - rho), p[2] + rho) - rho - R,
                                      abs=1e-14)
    # away from the hole the plane is untouched
    assert gap(t, (0.5, 0.0, 0.3)) == pytest.approx(0.3 - R, abs=1e-14)
    assert t.height_at(1.2) == -INF
    with pytest.raises(InvalidInput, match=r"no support at \(1.2, 0.0\): .*bottomless hole"):
        t.friction_at(1.2)


def test_holes_with_floor_and_in_3d():
    t = Terrain((Plane(friction=0.6),
                 Hole(x=(1.0, 2.0), floor=-0.3, friction=0.2),
                 Hole(x=(3.0, 3.5), y=(-0.25, 0.25))))
    assert gap(t, (1.5, 0.0, 0.0)) == pytest.approx(0.3 - R, abs=1e-14)  # the floor
    assert gap(t, (1.1, 0.0, -0.25)) == pytest.approx(0.05 - R, abs=1e-14)  # floor below
    assert gap(t, (1.05, 0.0, -0.1)) == pytest.approx(0.05 - R, abs=1e-14)  # wall nearer
    # the 3-D hole: nearest wall inside, the plane beside it
    assert gap(t, (3.2, 0.1, -1.0)) == pytest.approx(0.15 - R, abs=1e-14)
    assert gap(t, (3.2, 0.6, 0.1)) == pytest.approx(0.1 - R, abs=1e-14)
    assert gap(t, (2.5, 0.0, 0.1)) == pytest.approx(0.1 - R, abs=1e-14)  # between holes
    assert t.friction_at(1.5) == 0.2 and t.friction_at(2.5) == 0.6
    assert t.height_at(3.2, 0.1) == -INF and t.height_at(3.2, 0.3) == 0.0


# ------------------------------------------------------------------ smoothness
@pytest.mark.parametrize("rounding", [0.0, 0.01])
def test_gap_is_c1_across_the_edge_rounding(rounding):
    """Around the step's top-left edge on a circle of radius r (the contact's surface):
    the CasADi gradient equals finite differences and turns continuously."""
    box = Box(x=(0.5, 1.5), top=0.05, rounding=rounding)
    f = gap_function(Terrain((box,)))
    centre = np.array([0.5 + rounding, 0.0, 0.05 - rounding])
    angles = np.linspace(np.pi / 2 - 0.3, np.pi + 0.3, 241)  # top face, edge, side face
    grads = []
    for a in angles:
        p = centre + (rounding + R * 0.9) * np.array([np.cos(a), 0.0, np.sin(a)])
        grad = np.array(f(p)[1]).ravel()
        np.testing.assert_allclose(grad, central_gradient(f, p), atol=1e-6)
        grads.append(grad)
    grads = np.array(grads)
    np.testing.assert_allclose(np.linalg.norm(grads, axis=1), 1.0, atol=1e-12)
    # the gradient turns by no more than the angle step (no jump at the tangency lines)
    step = angles[1] - angles[0]
    turns = np.arccos(np.clip(np.sum(grads[1:] * grads[:-1], axis=1), -1, 1))
    assert np.max(turns) <= step * 1.01


def test_smooth_minimum_is_c1_exact_away_from_the_corner_and_bounded_below():
    k = 0.01
    t_exact = Terrain((Plane(), STEP))
    t_smooth = Terrain((Plane(), STEP), smoothing=k)
    f = gap_function(t_smooth)
    # in the concave corner at the foot of the step: both gaps near, grad continuous
    xs = np.linspace(0.44, 0.5, 121)
    previous = None
    for x in xs:
        p = np.array([x, 0.0, 0.5 - x])  # the diagonal where both gaps are equal at x 0.475
        value, grad = float(f(p)[0]), np.array(f(p)[1]).ravel()
        np.testing.assert_allclose(grad, central_gradient(f, p), atol=1e-6)
        exact = gap(t_exact, p)
        assert exact - k / 4 - 1e-15 <= value <= exact + 1e-15
        if previous is not None:
            assert np.linalg.norm(grad - previous) < 0.05
        previous = grad
    # far from the corner the smoothed gap is the exact one
    for p in ((0.2, 0.0, 0.1), (1.0, 0.0, 0.12), (0.45, 0.0, 0.01)):
        assert gap(t_smooth, p) == gap(t_exact, p)


def test_smooth_min_closed_form():
    assert float(smooth_min(ca.DM(1.0), ca.DM(2.0), 0.5)) == 1.0
    assert float(smooth_min(ca.DM(1.0), ca.DM(1.0), 0.4)) == pytest.approx(0.9)  # -k/4
    assert float(smooth_min(ca.DM(3.0), ca.DM(1.0), 0.0)) == 1.0


# ------------------------------------------------------------------ relevance
def test_relevant_to_keeps_only_what_a_contact_can_reach():
    far_box = Box(x=(5.0, 6.0), top=0.3)
    hole = Hole(x=(8.0, 8.5))
    terrain = Terrain((Plane(), STEP, far_box, hole), smoothing=0.005)
    region = Region(lower=(-0.5, -INF, 0.0), upper=(0.49, INF, 1.0))
    kept = terrain.relevant_to(region, margin=R)
    assert kept.primitives == (Plane(), STEP)  # the step's face is 1 cm away: reached
    assert kept.smoothing == 0.005
    assert terrain.relevant_to(region, margin=0.0).primitives == (Plane(),)
    whole = Region(lower=(-INF, -INF, 0.0), upper=(INF, INF, 1.0))
    assert terrain.relevant_to(whole, margin=R) == terrain
    # high above everything: the region never meets the ground
    with pytest.raises(InvalidInput, match="no solid of the terrain comes within"):
        terrain.relevant_to(Region(lower=(0.0, 0.0, 1.0), upper=(1.0, 1.0, 2.0)), margin=R)
    # a sloped plane that dips away from the region is dropped, one that rises is kept
    sloped = Terrain((Plane.sloped(0.0, (0.5, 0.0)), Plane(height=-1.0)))
    near = Region(lower=(1.0, -INF, 0.6), upper=(2.0, INF, 0.7))
    assert sloped.relevant_to(near, margin=R).primitives == (Plane.sloped(0.0, (0.5, 0.0)),)


# ------------------------------------------------------------------ contact terms
def _terms_function(robot, ground):
    outs = []
    for ct in robot.contact_terms(ground):
        outs += [ct.gap, ct.normal, ct.tangents, ct.normal_drift, ct.tangent_drift]
    return ca.Function("c", [robot.q, robot.v], outs)


@pytest.fixture(scope="module")
def hopper():
    return load_robot("hopper", base="planar", contacts=(ContactSpec("foot", R),))


@pytest.fixture(scope="module")
def solo():
    pytest.importorskip("example_robot_data")
    feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
    return load_robot("solo12", base="floating", contacts=tuple(ContactSpec(f, R) for f in feet))


def test_ground_and_the_equivalent_plane_give_the_same_terms_planar(hopper, rng):
    normal = (0.3, 0.0, 1.0)
    ground = Ground(height=-0.05, normal=normal)
    n_z = ground.normal[2]
    plane = Terrain((Plane(height=-0.05 / n_z, normal=normal),))
    f_ground, f_plane = _terms_function(hopper, ground), _terms_function(hopper, plane)
    for _ in range(5):
        q, v = rng.uniform(-1, 1, hopper.nv), rng.uniform(-1, 1, hopper.nv)
        for a, b in zip(f_ground(q, v), f_plane(q, v), strict=True):
            np.testing.assert_allclose(np.array(a), np.array(b), atol=1e-13)


def test_ground_and_the_equivalent_plane_give_the_same_terms_3d(solo, rng):
    normal = (0.2, -0.1, 1.0)
    ground = Ground(height=0.1, normal=normal)
    plane = Terrain((Plane(height=0.1 / ground.normal[2], normal=normal),))
    f_ground, f_plane = _terms_function(solo, ground), _terms_function(solo, plane)
    q, v = rng.uniform(-1, 1, solo.nv), rng.uniform(-1, 1, solo.nv)
    a, b = [np.array(x) for x in f_ground(q, v)], [np.array(x) for x in f_plane(q, v)]
    for k in range(4):
        g = slice(5 * k, 5 * k + 5)
        (ga, na, Ba, da, ta), (gb, nb, Bb, db, tb) = a[g], b[g]
        np.testing.assert_allclose(ga, gb, atol=1e-13)
        np.testing.assert_allclose(na, nb, atol=1e-13)
        np.testing.assert_allclose(da, db, atol=1e-12)
        # the tangent frames differ by a rotation in the plane: same span, same drift norm
        np.testing.assert_allclose(Ba @ np.linalg.pinv(Ba) @ Bb, Bb, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(ta), np.linalg.norm(tb), atol=1e-12)
    T = solo.contact_terms(plane)[0].world_tangents
    T = np.array(ca.Function("T", [solo.q], [T])(q))
    np.testing.assert_allclose(T.T @ T, np.eye(2), atol=1e-14)
    np.testing.assert_allclose(T.T @ np.asarray(ground.normal), np.zeros(2), atol=1e-14)


def test_terrain_terms_near_a_rounded_edge_against_pinocchio_and_differences(hopper, rng):
    """Gap, n = grad_q f_c, B = J^T T(p) and both drifts (with the edge's curvature)."""
    q, v = rng.uniform(-0.5, 0.5, hopper.nv), rng.uniform(-1, 1, hopper.nv)
    model, data = hopper.model, hopper.data
    frame = model.getFrameId("foot")
    pin.framesForwardKinematics(model, data, q)
    p = data.oMf[frame].translation.copy()
    rho = 0.01
    # a step whose top-left edge lies down-right of the foot: the rounded edge is nearest
    box = Box(x=(p[0] + 0.03, INF), top=p[2] - 0.03, rounding=rho)
    terrain = Terrain((Plane(height=p[2] - 1.0), box))
    f = _terms_function(hopper, terrain)
    g, n, B, n_drift, t_drift = [np.array(x) for x in f(q, v)]
    centre = np.array([box.x[0] + rho, p[1], box.top - rho])
    assert g.item() == pytest.approx(np.linalg.norm(p - centre) - rho - R, abs=1e-13)
    n_w = (p - centre) / np.linalg.norm(p - centre)
    J = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
    np.testing.assert_allclose(n.ravel(), J.T @ n_w, atol=1e-12)
    t_w = np.array([n_w[2], 0.0, -n_w[0]])
    np.testing.assert_allclose(B.ravel(), J.T @ t_w, atol=1e-12)
    eps = 1e-6
    fd = np.array([(float(f(q + eps * e, v)[0]) - float(f(q - eps * e, v)[0])) / (2 * eps)
                   for e in np.eye(hopper.nv)])
    np.testing.assert_allclose(n.ravel(), fd, atol=1e-8)
    nv_plus, nv_minus = (float(np.array(f(q + s * eps * v, v)[1]).ravel() @ v) for s in (1, -1))
    assert n_drift.item() == pytest.approx((nv_plus - nv_minus) / (2 * eps), abs=1e-6)
    tv_plus, tv_minus = (float(np.array(f(q + s * eps * v, v)[2]).ravel() @ v) for s in (1, -1))
    assert t_drift.item() == pytest.approx((tv_plus - tv_minus) / (2 * eps), abs=1e-6)
    # the curvature term is there: the drift differs from n_w . (dJ/dt v)
    pin.forwardKinematics(model, data, q, v, np.zeros(hopper.nv))
    accel = pin.getFrameClassicalAcceleration(model, data, frame,
                                              pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).linear
    pdot = J @ v
    curvature = (pdot @ pdot - (n_w @ pdot) ** 2) / np.linalg.norm(p - centre)
    assert n_drift.item() == pytest.approx(n_w @ accel + curvature, abs=1e-9)


def test_3d_tangents_are_orthonormal_and_smooth_up_to_walls():
    n = ca.SX.sym("n", 3)
    T = ca.Function("T", [n], [terrain_tangents(n, planar=False)])
    for normal in ([0, 0, 1], [1, 0, 0], [0, -1, 0], [0.3, 0.4, np.sqrt(0.75)]):
        normal = np.asarray(normal, dtype=float)
        t = np.array(T(normal))
        np.testing.assert_allclose(t.T @ t, np.eye(2), atol=1e-14)
        np.testing.assert_allclose(t.T @ normal, np.zeros(2), atol=1e-14)
        np.testing.assert_allclose(np.cross(t[:, 0], t[:, 1]), normal, atol=1e-14)


def test_planar_robot_rejects_a_terrain_that_depends_on_y(hopper):
    terrain = Terrain((Plane(), Box(x=(0.5, 1.0), y=(-1.0, 1.0), top=0.1)))
    with pytest.raises(IncompatibleOptions, match="the terrain depends on y"):
        hopper.contact_terms(terrain)
    with pytest.raises(InvalidInput, match="must be a Ground or a Terrain, got Plane"):
        hopper.contact_terms(Plane())


# ------------------------------------------------------------------ friction into the CLS
def test_from_robot_takes_friction_from_the_terrain_or_per_contact(hopper, solo):
    terrain = Terrain((Plane(friction=0.7), Box(x=(0.5, INF), top=0.05, friction=0.7)))
    assert [c.mu for c in from_robot(hopper, terrain).contacts] == [0.7]
    assert [c.mu for c in from_robot(hopper, terrain, mu=0.2).contacts] == [0.2]
    assert [c.mu for c in from_robot(hopper).contacts] == [0.0]  # Ground: as before
    assert from_robot(hopper).contacts[0].n_tangents == 0
    mixed = Terrain((Plane(friction=0.7), Box(x=(0.5, INF), top=0.05, friction=0.3)))
    with pytest.raises(IncompatibleOptions, match=r"different friction coefficients \[0.3, 0.7\]"):
        from_robot(hopper, mixed)
    assert [c.mu for c in from_robot(hopper, mixed, mu=[0.3]).contacts] == [0.3]
    cls = from_robot(solo, mu=(0.1, 0.2, 0.0, 0.4))
    assert [c.mu for c in cls.contacts] == [0.1, 0.2, 0.0, 0.4]
    assert [c.n_tangents for c in cls.contacts] == [2, 2, 0, 2]
    with pytest.raises(InvalidInput, match=r"`mu` has 2 coefficients but the robot has 4"):
        from_robot(solo, mu=(0.1, 0.2))
    with pytest.raises(InvalidInput, match="`mu` must be a number or one number per contact"):
        from_robot(hopper, mu="0.3")


def test_time_frozen_hopper_on_a_terrain_builds():
    from tfcontact.timefreezing import Inelastic, time_freeze

    robot = load_robot("hopper", base="planar", locked_joints=("hip_joint",),
                       contacts=(ContactSpec("foot", R),))
    terrain = Terrain((Plane(friction=0.5), Box(x=(0.6, INF), top=0.05, rounding=0.01,
                                                 friction=0.5)), smoothing=0.005)
    tf = time_freeze(from_robot(robot, terrain), method=Inelastic())
    assert tf.n_y == 2 * robot.nv + 1


# ------------------------------------------------------------------ files
def test_description_round_trips_through_strict_json():
    sloped = Terrain((Plane.sloped(-0.5, (0.2, 0.1)),))
    assert Terrain.from_dict(json.loads(json.dumps(sloped.to_dict()))) == sloped
    terrain = Terrain((Plane(0.1, friction=0.5),
                       Box(x=(0.5, INF), top=0.3, rounding=0.02, friction=0.9),
                       Hole(x=(-1.0, -0.5), y=(0.0, 1.0), floor=-0.2, friction=0.1)),
                      smoothing=0.01)
    text = json.dumps(terrain.to_dict(), allow_nan=False)
    assert Terrain.from_dict(json.loads(text)) == terrain
    with pytest.raises(InvalidInput, match="not a terrain description"):
        Terrain.from_dict({"kind": "ground"})
    with pytest.raises(InvalidInput, match=r"`primitives\[0\]` has kind 'wall'"):
        Terrain.from_dict({"kind": "terrain", "primitives": [{"kind": "wall"}]})


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("build", "error", "match"),
    [
        (lambda: Plane(normal=(0.0, 0.0, -1.0)), InvalidInput, r"n_z > 0 \(a plane faces up\)"),
        (lambda: Plane(height=math.nan), InvalidInput, "`height` must be a finite number"),
        (lambda: Plane(friction=-0.1), InvalidInput, r"`friction` must be >= 0"),
        (lambda: Plane.sloped(0.0, (0.1,)), InvalidInput, r"`slope` must be \(dz/dx, dz/dy\)"),
        (lambda: Box(x=(1.0, 0.5), top=0.0), InvalidInput, "`x` must have lo < hi"),
        (lambda: Box(x=(0.0, 0.1), top=0.0, rounding=0.05), InvalidInput,
         "not more than twice the rounding"),
        (lambda: Box(x=(0.0, 1.0), top=0.0, rounding=-0.01), InvalidInput,
         r"`rounding` must be >= 0"),
        (lambda: Box(x=0.5, top=0.0), InvalidInput, r"`x` must be a pair \(lo, hi\)"),
        (lambda: Box(x=(0.0, 1.0), top=True), InvalidInput, "`top` must be a number"),
        (lambda: Hole(x=(0.0, INF)), InvalidInput, "`x` of a hole must be finite"),
        (lambda: Hole(x=(0.0, 1.0), friction=0.3), IncompatibleOptions,
         "a bottomless hole has no surface"),
        (lambda: Terrain(()), InvalidInput, "the terrain has no solid"),
        (lambda: Terrain(Plane()), InvalidInput, "must be a tuple of primitives"),
        (lambda: Terrain((Plane(), "box")), InvalidInput,
         r"`primitives\[1\]` must be a Plane, Box or Hole, got str"),
        (lambda: Terrain((Plane(),), smoothing=-1.0), InvalidInput, "`smoothing` must be >= 0"),
        (lambda: Terrain((Box(x=(0.0, 1.0), top=0.0), Hole(x=(2.0, 3.0)))), IncompatibleOptions,
         "holes cut horizontal planes only, but the terrain has no plane"),
        (lambda: Terrain((Plane.sloped(0.0, (0.1, 0.0)), Hole(x=(2.0, 3.0)))),
         IncompatibleOptions, "but the terrain has the sloped plane"),
        (lambda: Terrain((Plane(), Hole(x=(0.0, 1.0)), Hole(x=(0.5, 2.0)))), InvalidInput,
         "overlap or are not more than"),
        (lambda: Terrain((Plane(), Hole(x=(0.0, 1.0), floor=0.1))), InvalidInput,
         "is not below the plane"),
        (lambda: Region(lower=(1.0, 0.0, 0.0), upper=(0.0, 1.0, 1.0)), InvalidInput,
         r"`lower\[0\]` = 1.0 is above `upper\[0\]`"),
        (lambda: Terrain((Plane(),)).relevant_to((0, 1)), InvalidInput,
         "`region` must be a Region"),
        (lambda: Terrain((Plane(),)).gap((0.0, 0.0), R), InvalidInput,
         r"`point` must be a 3-vector"),
    ],
)
def test_validation_errors_name_the_field_and_the_fix(build, error, match):
    with pytest.raises(error, match=match):
        build()


def test_trajectory_directions_follow_the_terrain_normal_at_the_foot(hopper, rng):
    """`terrain_directions` (the sidecar's world frame of forces on a terrain): at a foot
    beside a rounded box edge, the unit normal from the edge's centre line to the foot
    (Pinocchio's foot position) and the planar tangent perpendicular to it."""
    from tfcontact.plan_format import terrain_directions

    q = rng.uniform(-0.5, 0.5, hopper.nv)
    model, data = hopper.model, hopper.data
    pin.framesForwardKinematics(model, data, q)
    p = data.oMf[model.getFrameId("foot")].translation.copy()
    rho = 0.01
    box = Box(x=(p[0] + 0.03, INF), top=p[2] - 0.03, rounding=rho)
    (n_w, t_w), = terrain_directions(hopper, Terrain((Plane(height=p[2] - 1.0), box)))(q)
    centre = np.array([box.x[0] + rho, p[1], box.top - rho])
    expected = (p - centre) / np.linalg.norm(p - centre)
    np.testing.assert_allclose(n_w, expected, atol=1e-12)
    assert t_w.shape == (3, 1)
    np.testing.assert_allclose(t_w.ravel(), [expected[2], 0.0, -expected[0]], atol=1e-12)
    # on a 20 % slope far from the box: the slope's normal, whatever the foot's height
    slope = Terrain((Plane.sloped(p[2] - 0.3, (0.2, 0.0)),))
    (n_w, _), = terrain_directions(hopper, slope)(q)
    np.testing.assert_allclose(n_w, np.array([-0.2, 0.0, 1.0]) / math.hypot(0.2, 1.0),
                               atol=1e-12)
