"""tfcontact.robot: loading, the CasADi twin against Pinocchio, contact terms, bad input.

Reference: Pinocchio's own numerics (crba, nonLinearEffects, aba, frame placements,
LOCAL_WORLD_ALIGNED frame Jacobians and classical accelerations) at 20 seeded random
(q, v) per robot, and closed forms (TF-8 hopper, TF-9 monoped Lagrangian).
Tolerance: TOL = 1e-9 relative to the largest entry of the reference (or absolute when
that is below 1): max |twin - pinocchio| <= TOL * max(1, max |pinocchio|).
"""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from tfcontact.errors import FrameNotFound, IncompatibleOptions, InvalidInput, RobotLoadError
from tfcontact.robot import ContactSpec, Ground, Robot, RobotSpec, load_robot, project_robots

TOL = 1e-9
N_SAMPLES = 20

TALOS_UPPER_BODY = (
    "torso_1_joint", "torso_2_joint",
    *(f"arm_{side}_{i}_joint" for side in ("left", "right") for i in range(1, 8)),
    "gripper_left_joint", "gripper_right_joint", "head_1_joint", "head_2_joint",
)

CASES = {
    "solo12": dict(source="solo12", base="floating"),
    "a1": dict(source="a1", base="floating"),
    "bolt": dict(source="bolt", base="floating"),
    "talos_legs": dict(source="talos", base="floating", locked_joints=TALOS_UPPER_BODY),
    "double_pendulum": dict(source="double_pendulum", base="fixed"),
    "hopper": dict(source="robots/hopper.urdf", base="planar"),
    "ball": dict(source="robots/ball.urdf", base="floating"),
    "monoped": dict(source="robots/monoped.urdf", base="planar_xz"),
}


def assert_close(ours: np.ndarray, ref: np.ndarray, what: str) -> None:
    ours, ref = np.asarray(ours, dtype=float), np.asarray(ref, dtype=float)
    assert ours.shape == ref.shape, what
    err = np.max(np.abs(ours - ref))
    scale = max(1.0, float(np.max(np.abs(ref))))
    assert err <= TOL * scale, f"{what}: max error {err:.3e} > {TOL:.0e} * {scale:.3g}"


def _checked_frames(model: pin.Model) -> list[str]:
    """Body frames and fixed-joint frames (feet, tips): the frames contacts attach to."""
    kinds = (pin.FrameType.BODY, pin.FrameType.FIXED_JOINT)
    return [f.name for f in model.frames if f.type in kinds]


class Evaluated:
    """Twin outputs at N_SAMPLES seeded samples, computed with one mapped call."""

    def __init__(self, robot: Robot):
        twin = robot.twin
        nv = robot.nv
        self.frames = _checked_frames(robot.model)
        outs = [ca.vec(twin.M), twin.h, twin.forward_dynamics(method="ldl"),
                twin.forward_dynamics(method="qr")]
        for name in self.frames:
            outs += [twin.frame_position(name), ca.vec(twin.frame_rotation(name)),
                     ca.vec(twin.frame_jacobian(name)), twin.frame_drift(name)]
        f = ca.Function("all", [twin.q, twin.v, twin.tau], outs, {"cse": True})
        rng = np.random.default_rng(20261122)
        self.Q = rng.uniform(-2.0, 2.0, (nv, N_SAMPLES))
        self.V = rng.uniform(-2.0, 2.0, (nv, N_SAMPLES))
        self.T = rng.uniform(-5.0, 5.0, (nv, N_SAMPLES))
        res = [np.array(r) for r in f.map(N_SAMPLES)(self.Q, self.V, self.T)]
        self.M = [res[0][:, i].reshape(nv, nv, order="F") for i in range(N_SAMPLES)]
        self.h = res[1].T
        self.a = res[2].T
        self.a_qr = res[3].T
        self.frame = {}
        for k, name in enumerate(self.frames):
            p, R, J, d = res[4 + 4 * k: 8 + 4 * k]
            self.frame[name] = [
                (p[:, i], R[:, i].reshape(3, 3, order="F"), J[:, i].reshape(6, nv, order="F"),
                 d[:, i])
                for i in range(N_SAMPLES)
            ]


_cache: dict[str, tuple[Robot, Evaluated]] = {}


def _case(name: str) -> tuple[Robot, Evaluated]:
    if name not in _cache:
        robot = load_robot(**CASES[name])
        _cache[name] = (robot, Evaluated(robot))
    return _cache[name]


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    if request.param == "talos_legs":
        pytest.importorskip("example_robot_data")
    return request.param, *_case(request.param)


def test_twin_dynamics_match_pinocchio(case):
    name, robot, ev = case
    model, data = robot.model, robot.data
    assert model.nq == model.nv
    for i in range(N_SAMPLES):
        q, v, tau = ev.Q[:, i], ev.V[:, i], ev.T[:, i]
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert_close(ev.M[i], M, f"{name} M sample {i}")
        assert_close(ev.h[i], pin.nonLinearEffects(model, data, q, v), f"{name} h sample {i}")
        a = pin.aba(model, data, q, v, tau)
        assert_close(ev.a[i], a, f"{name} fd (ldl) sample {i}")
        assert_close(ev.a_qr[i], a, f"{name} fd (qr) sample {i}")


def test_twin_frames_match_pinocchio(case):
    name, robot, ev = case
    model, data = robot.model, robot.data
    assert ev.frames, "no frame checked"
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for i in range(N_SAMPLES):
        q, v = ev.Q[:, i], ev.V[:, i]
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        pin.updateFramePlacements(model, data)
        pin.computeJointJacobians(model, data, q)
        for fname in ev.frames:
            fid = model.getFrameId(fname)
            p, R, J, drift = ev.frame[fname][i]
            what = f"{name} frame {fname} sample {i}"
            assert_close(p, data.oMf[fid].translation, what + " position")
            assert_close(R, data.oMf[fid].rotation, what + " rotation")
            assert_close(J, pin.getFrameJacobian(model, data, fid, lwa), what + " jacobian")
            acc = pin.getFrameClassicalAcceleration(model, data, fid, lwa)
            assert_close(drift, acc.vector, what + " drift")


def test_jacobian_convention_linear_first_world_aligned():
    """J v = (dp/dt, w) with dR/dt = [w]x R, by central differences along v (solo12 foot)."""
    robot, _ = _case("solo12")
    twin = robot.twin
    f = ca.Function("f", [twin.q], [twin.frame_position("FL_FOOT"),
                                    twin.frame_rotation("FL_FOOT"), twin.frame_jacobian("FL_FOOT")])
    rng = np.random.default_rng(5)
    q, v, eps = rng.uniform(-1, 1, robot.nv), rng.uniform(-1, 1, robot.nv), 1e-6
    p_plus, R_plus, _ = (np.array(x) for x in f(q + eps * v))
    p_minus, R_minus, _ = (np.array(x) for x in f(q - eps * v))
    _, R, J = (np.array(x) for x in f(q))
    twist = J @ v
    np.testing.assert_allclose(twist[:3], ((p_plus - p_minus) / (2 * eps)).ravel(), atol=1e-8)
    w_hat = (R_plus - R_minus) / (2 * eps) @ R.T
    np.testing.assert_allclose(twist[3:], [w_hat[2, 1], w_hat[0, 2], w_hat[1, 0]], atol=1e-8)


def test_talos_keeps_rotor_inertia():
    robot, _ = _case("talos_legs")
    assert robot.nv == 18
    assert robot.model.armature[6:].min() > 0.0  # reflected rotor inertia of the leg joints


def test_floating_base_is_the_free_flyer_in_zyx_angles():
    """Same frame placements as example-robot-data's quaternion free-flyer model."""
    import example_robot_data

    robot, _ = _case("solo12")
    ref = example_robot_data.load("solo12").model
    ref_data = ref.createData()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, robot.nq)
        yaw, pitch, roll = q[3:6]
        quat = pin.Quaternion(pin.rpy.rpyToMatrix(roll, pitch, yaw)).coeffs()
        q_ref = np.concatenate([q[:3], quat, q[6:]])
        pin.framesForwardKinematics(robot.model, robot.data, q)
        pin.framesForwardKinematics(ref, ref_data, q_ref)
        for fname in ("FL_FOOT", "HR_FOOT", "base_link"):
            ours = robot.data.oMf[robot.model.getFrameId(fname)]
            theirs = ref_data.oMf[ref.getFrameId(fname)]
            assert_close(ours.homogeneous, theirs.homogeneous, fname)


def test_planar_base_coordinates():
    """planar: q = (x, z, pitch) puts the base at (x, 0, z) rotated by Ry(pitch)."""
    robot, _ = _case("hopper")
    q = np.zeros(robot.nq)
    q[:3] = 0.3, 0.7, 0.4
    pin.framesForwardKinematics(robot.model, robot.data, q)
    base = robot.data.oMf[robot.model.getFrameId("base")]
    assert_close(base.translation, [0.3, 0.0, 0.7], "base position")
    assert_close(base.rotation, pin.utils.rotate("y", 0.4), "base rotation")


# ------------------------------------------------------------------ project robots
def _sample(f: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
    return [np.array(r) for r in f.map(args[0].shape[1])(*args)]


def test_hopper_matches_tf8_kinematics_and_documented_mass_matrix():
    """TF-8 with theta = -pitch: foot gap and Jacobians exact; M as documented in the URDF."""
    robot = load_robot("robots/hopper.urdf", base="planar", locked_joints=("hip_joint",),
                       contacts=(ContactSpec("foot", 0.02),))
    assert robot.joint_names == ("root_joint", "leg_joint")
    ct = robot.contact_terms()[0]
    f = ca.Function("f", [robot.q], [ca.vec(robot.twin.M), ct.gap, ct.normal, ct.tangents])
    rng = np.random.default_rng(8)
    Q = np.vstack([rng.uniform(-1, 1, (3, N_SAMPLES)), rng.uniform(0.1, 0.5, (1, N_SAMPLES))])
    M, gap, n, t = _sample(f, Q)
    mb, ml, Ib, Il = 1.0, 0.1, 0.25, 0.025
    for i in range(N_SAMPLES):
        x, z, pitch, ell = Q[:, i]
        theta = -pitch
        s, c = np.sin(pitch), np.cos(pitch)
        M_tf8 = np.diag([mb + ml, mb + ml, Ib + Il, ml])
        coupling = ml * np.array([[0, 0, -ell * c, -s], [0, 0, ell * s, -c],
                                  [-ell * c, ell * s, ell**2, 0], [-s, -c, 0, 0]])
        assert_close(M[:, i].reshape(4, 4, order="F"), M_tf8 + coupling, f"M sample {i}")
        assert_close(gap[0, i], z - ell * np.cos(theta) - 0.02, "gap")
        d_theta = np.diag([1.0, 1.0, -1.0, 1.0])  # d theta / d pitch = -1
        J_n = np.array([0, 1, ell * np.sin(theta), -np.cos(theta)])
        J_t = np.array([1, 0, ell * np.cos(theta), np.sin(theta)])
        assert_close(n[:, i], d_theta @ J_n, "normal")
        assert_close(t[:, i], d_theta @ J_t, "tangent")


def test_ball_mass_matrix():
    robot = load_robot("robots/ball.urdf", base="planar_xz")
    M = np.array(ca.Function("M", [robot.q], [robot.twin.M])([0.3, -0.2]))
    assert_close(M, np.eye(2), "ball M")
    h = np.array(ca.Function("h", [robot.q, robot.v], [robot.twin.h])([0.3, -0.2], [1, 2]))
    assert_close(h.ravel(), [0.0, 9.81], "ball gravity")


def test_monoped_matches_tf9_lagrangian():
    """M(q) and h(q, v) against the Lagrangian of TF-9's kinematics (built here by hand)."""
    robot = load_robot("robots/monoped.urdf", base="planar_xz")
    q = ca.SX.sym("q", 4)
    v = ca.SX.sym("v", 4)
    qx, qz, ph, pk = ca.vertsplit(q)
    down = lambda a: ca.vertcat(ca.sin(a), ca.cos(a))  # noqa: E731
    hip = ca.vertcat(qx, qz)
    knee = hip - 0.2 * down(ph)
    bodies = [  # (mass, centre of mass, rotational inertia, absolute angle)
        (3.975, hip, 0.0, 0.0),
        (1.782, hip - 0.016 * down(ph), 0.001, ph),
        (0.548, knee - 0.1 * down(ph + pk), 0.0032, ph + pk),
    ]
    M = ca.SX.zeros(4, 4)
    V = 0
    for m, c, inertia, angle in bodies:
        Jc = ca.jacobian(c, q)
        Jw = ca.jacobian(angle, q) if inertia else ca.SX.zeros(1, 4)
        M += m * Jc.T @ Jc + inertia * Jw.T @ Jw
        V += m * 9.81 * c[1]
    # h = dM/dt v - 1/2 d(v^T M v)/dq + dV/dq
    h = ca.jacobian(M @ v, q) @ v - 0.5 * ca.gradient(v.T @ M @ v, q) + ca.gradient(V, q)
    ref = ca.Function("ref", [q, v], [ca.vec(M), h])
    ours = ca.Function("ours", [robot.q, robot.v], [ca.vec(robot.twin.M), robot.twin.h])
    rng = np.random.default_rng(9)
    Q, Vs = rng.uniform(-1.5, 1.5, (4, N_SAMPLES)), rng.uniform(-2, 2, (4, N_SAMPLES))
    for a, b, what in zip(_sample(ours, Q, Vs), _sample(ref, Q, Vs), ("M", "h"), strict=True):
        for i in range(N_SAMPLES):
            assert_close(a[:, i], b[:, i], f"monoped {what} sample {i}")
    foot = ca.Function("p", [robot.q], [robot.twin.frame_position("foot")])
    for i in range(5):
        x, z, h_, k = Q[:, i]
        expected = np.array([x - 0.2 * np.sin(h_) - 0.2 * np.sin(h_ + k), 0.0,
                             z - 0.2 * np.cos(h_) - 0.2 * np.cos(h_ + k)])
        assert_close(np.array(foot(Q[:, i])).ravel(), expected, "foot")


# ------------------------------------------------------------------ contacts
@pytest.mark.parametrize(
    ("case_name", "feet", "ground"),
    [
        ("solo12", ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"),
         Ground(height=0.1, normal=(0.2, -0.1, 1.0))),
        ("hopper", ("foot",), Ground(height=-0.05, normal=(0.3, 0.0, 1.0))),
    ],
)
def test_contact_terms_against_pinocchio_and_finite_differences(case_name, feet, ground):
    base = _case(case_name)[0]
    radius = 0.02
    robot = load_robot(base.spec.source, base=base.spec.base,
                       contacts=tuple(ContactSpec(f, radius) for f in feet))
    terms = robot.contact_terms(ground)
    n_t = 1 if robot.planar else 2
    n_w = np.asarray(ground.normal)
    T = terms[0].world_tangents
    assert T.shape == (3, n_t)
    assert_close(T.T @ n_w, np.zeros(n_t), "tangents orthogonal to the normal")
    assert_close(T.T @ T, np.eye(n_t), "tangents orthonormal")
    outs = []
    for ct in terms:
        outs += [ct.gap, ct.normal, ct.tangents, ct.normal_drift, ct.tangent_drift]
    f = ca.Function("c", [robot.q, robot.v], outs)
    rng = np.random.default_rng(4)
    q, v = rng.uniform(-1, 1, robot.nv), rng.uniform(-1, 1, robot.nv)
    res = [np.array(r) for r in f(q, v)]
    eps = 1e-6
    pin.framesForwardKinematics(robot.model, robot.data, q)
    for k, foot in enumerate(feet):
        gap, n, B, n_drift, t_drift = res[5 * k: 5 * k + 5]
        p = robot.data.oMf[robot.model.getFrameId(foot)].translation
        assert_close(gap, [[n_w @ p - ground.height - radius]], f"{foot} gap")
        # normal = grad gap (central differences), and B = J^T T
        fd = np.zeros(robot.nv)
        for j in range(robot.nv):
            dq = np.zeros(robot.nv)
            dq[j] = eps
            fd[j] = (float(f(q + dq, v)[5 * k]) - float(f(q - dq, v)[5 * k])) / (2 * eps)
        np.testing.assert_allclose(n.ravel(), fd, atol=1e-8, err_msg=f"{foot} normal vs FD")
        J = pin.computeFrameJacobian(robot.model, robot.data, q, robot.model.getFrameId(foot),
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        assert_close(B, J.T @ T, f"{foot} tangents")
        # drift = d/dt (n(q)^T v) at zero acceleration, by central differences along v
        nv_plus = float(ca.dot(f(q + eps * v, v)[5 * k + 1], v))
        nv_minus = float(ca.dot(f(q - eps * v, v)[5 * k + 1], v))
        np.testing.assert_allclose(n_drift.item(), (nv_plus - nv_minus) / (2 * eps), atol=1e-7)
        tv_plus = np.array(f(q + eps * v, v)[5 * k + 2]).T @ v
        tv_minus = np.array(f(q - eps * v, v)[5 * k + 2]).T @ v
        np.testing.assert_allclose(t_drift.ravel(), (tv_plus - tv_minus) / (2 * eps), atol=1e-7)


def test_planar_robot_rejects_ground_normal_with_y_component():
    robot = load_robot("robots/ball.urdf", base="planar_xz", contacts=(ContactSpec("ball", 0.05),))
    with pytest.raises(IncompatibleOptions, match=r"has a y component; use a normal \(n_x, 0"):
        robot.contact_terms(Ground(normal=(0.0, 0.5, 1.0)))


# ------------------------------------------------------------------ specs
def test_spec_round_trips_through_json():
    spec = RobotSpec("robots/hopper.urdf", base="planar", locked_joints=("hip_joint",),
                     contacts=(ContactSpec("foot", 0.02),))
    text = json.dumps(spec.to_dict())
    again = RobotSpec.from_dict(json.loads(text))
    assert again == spec
    robot = load_robot(again)
    assert robot.spec == spec
    assert robot.contacts == spec.contacts
    assert robot.nv == 4


def test_locked_positions_place_the_locked_joints():
    """Monoped with the knee locked at 0.5 rad: the foot is where TF-9's kinematics put it."""
    robot = load_robot("monoped", base="planar_xz", locked_joints=("knee_joint",),
                       locked_positions=(0.5,))
    assert robot.spec.to_dict()["locked_positions"] == [0.5]
    assert RobotSpec.from_dict(json.loads(json.dumps(robot.spec.to_dict()))) == robot.spec
    q = np.array([0.1, 0.4, 0.3])
    foot = np.array(ca.Function("p", [robot.q], [robot.twin.frame_position("foot")])(q)).ravel()
    expected = [0.1 - 0.2 * np.sin(0.3) - 0.2 * np.sin(0.8), 0.0,
                0.4 - 0.2 * np.cos(0.3) - 0.2 * np.cos(0.8)]
    assert_close(foot, expected, "foot with locked knee")
    with pytest.raises(InvalidInput, match=r"`locked_positions` has 2 values for 1 "
                       r"`locked_joints`.*one per locked joint or none"):
        RobotSpec("monoped", locked_joints=("knee_joint",), locked_positions=(0.5, 0.1))


def test_relative_path_resolves_against_repository_root(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_robot("robots/ball.urdf").nv == 0


def test_project_robots_load_by_name():
    assert project_robots() == ("ball", "hopper", "monoped")
    robot = load_robot("monoped", base="planar_xz")
    assert robot.joint_names == ("root_joint", "hip_joint", "knee_joint")
    assert "foot" in robot.frame_names


# ------------------------------------------------------------------ bad input
def test_missing_urdf(tmp_path):
    with pytest.raises(RobotLoadError, match=r"URDF file `robots/nope.urdf` not found.*pass an"):
        load_robot("robots/nope.urdf")


def test_malformed_xml(tmp_path):
    path = tmp_path / "broken.urdf"
    path.write_text('<robot name="x"><link name="a"><joint ')
    with pytest.raises(RobotLoadError, match=r"broken.urdf` is not valid XML.*fix the file"):
        load_robot(str(path))


def test_malformed_urdf(tmp_path):
    path = tmp_path / "nolimits.urdf"
    path.write_text('<robot name="x"><link name="a"/><link name="b"/>'
                    '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
                    "</joint></robot>")
    with pytest.raises(RobotLoadError, match=r"could not be parsed.*does not specify limits"):
        load_robot(str(path))


def test_unknown_robot_name():
    with pytest.raises(RobotLoadError, match=r"`solo13` is neither a URDF path, a robot of the "
                       r"project's `robots/` \(ball, hopper, monoped\) nor.*solo12"):
        load_robot("solo13")


def test_unknown_contact_frame():
    with pytest.raises(FrameNotFound, match=r"frame `toe` is not in the model; pick one of:.*foot"):
        load_robot("robots/monoped.urdf", base="planar_xz", contacts=(ContactSpec("toe", 0.02),))
    robot = load_robot("robots/monoped.urdf", base="planar_xz")
    with pytest.raises(FrameNotFound, match=r"frame `toe`"):
        robot.twin.frame_jacobian("toe")


@pytest.mark.parametrize("radius", [0.0, -0.01, float("nan")])
def test_non_positive_radius(radius):
    with pytest.raises(InvalidInput, match=r"`radius` must be > 0 \[m\].*small sphere"):
        ContactSpec("foot", radius)


def test_base_the_model_cannot_take(tmp_path):
    with pytest.raises(IncompatibleOptions, match=r"`base`='floating' cannot be used with "
                       r"`double_pendulum`.*fixed to the world.*use base='fixed'"):
        load_robot("double_pendulum", base="floating")
    anchored = tmp_path / "anchored.urdf"
    anchored.write_text('<robot name="x"><link name="world"/><link name="b"/>'
                        '<joint name="j" type="fixed"><parent link="world"/><child link="b"/>'
                        "</joint></robot>")
    with pytest.raises(IncompatibleOptions, match=r"root link is `world`.*use base='fixed'"):
        load_robot(str(anchored), base="planar")
    continuous = tmp_path / "continuous.urdf"
    continuous.write_text('<robot name="x"><link name="a"/><link name="b"/>'
                          '<joint name="wheel" type="continuous"><parent link="a"/>'
                          '<child link="b"/><axis xyz="0 1 0"/></joint></robot>')
    with pytest.raises(IncompatibleOptions, match=r"`wheel` \(JointModelRUBY\).*replace "
                       r"`continuous` by `revolute`"):
        load_robot(str(continuous))
    with pytest.raises(InvalidInput, match=r"`base` must be one of fixed, planar, "
                       r"planar_xz, vertical, floating, got 'free'"):
        load_robot("robots/ball.urdf", base="free")


def test_unknown_locked_joint():
    with pytest.raises(InvalidInput, match=r"`locked_joints` names joints that are not in the "
                       r"model: \['ankle'\]; joints: root_joint, hip_joint, knee_joint"):
        load_robot("robots/monoped.urdf", base="planar_xz", locked_joints=("ankle",))


def test_spec_arguments_are_exclusive():
    spec = RobotSpec("robots/ball.urdf")
    with pytest.raises(IncompatibleOptions, match=r"takes base, locked_joints, contacts and "
                       r"locked_positions from the RobotSpec"):
        load_robot(spec, base="planar")


def test_a_vertical_base_is_a_rail_in_z():
    """base="vertical" (a leg test bench): one prismatic z coordinate before the joints,
    the weight of the whole robot on it (h(q, 0)[z] = m g), planar contacts (one tangent)."""
    import pinocchio as pin

    from tfcontact.robot import BASE_COORDINATES, ContactSpec, load_robot
    from tfcontact.timefreezing.from_robot import from_robot

    robot = load_robot("hopper", base="vertical", contacts=(ContactSpec("foot", 0.02),))
    assert BASE_COORDINATES["vertical"] == (("z", "m"),)
    assert robot.nq == robot.nv == 3 and robot.planar
    q = np.array([0.4, 0.3, 0.25])
    h = ca.Function("h", [robot.twin.q, robot.twin.v], [robot.twin.h])(q, np.zeros(3))
    mass = pin.computeTotalMass(robot.model)
    assert float(h[0]) == pytest.approx(mass * 9.81, rel=1e-3)
    np.testing.assert_allclose(np.asarray(ca.Function("m", [robot.twin.q], [robot.twin.M])(q)),
                               pin.crba(robot.model, robot.data, q), atol=1e-12)
    cls = from_robot(robot, mu=0.5)
    assert cls.contacts[0].n_tangents == 1


def test_a_fixed_base_arm_moving_in_the_xz_plane_gets_planar_contacts():
    """example-robot-data's finger_edu with its first joint (about a tilted axis) locked
    turns its tip about world y only: one tangent, as on a planar base. Unlocked its tip
    leaves the plane and gets two; so does a fixed-base solo12 leg's foot."""
    import pinocchio as pin

    tip = (ContactSpec("finger_tip_link", 0.0095),)
    locked = load_robot("finger_edu", locked_joints=("finger_base_to_upper_joint",),
                        contacts=tip)
    free = load_robot("finger_edu", contacts=tip)
    assert locked.planar and not free.planar
    assert locked.contact_terms()[0].world_tangents.shape == (3, 1)
    assert free.contact_terms()[0].world_tangents.shape == (3, 2)
    assert not load_robot("solo12", contacts=(ContactSpec("FL_FOOT", 0.016),)).planar
    # the reason, from positions (not the Jacobians the property reads): the locked
    # finger's tip keeps its y wherever its joints turn, the free one's does not
    def tip_y(robot, configurations):
        model, data = robot.model, robot.model.createData()
        frame = model.getFrameId("finger_tip_link")
        ys = []
        for q in configurations:
            pin.framesForwardKinematics(model, data, q)
            ys.append(data.oMf[frame].translation[1])
        return np.array(ys)

    rng = np.random.default_rng(1)
    assert np.ptp(tip_y(locked, rng.uniform(-2, 2, (5, locked.model.nq)))) < 1e-12
    assert np.ptp(tip_y(free, rng.uniform(-2, 2, (5, free.model.nq)))) > 1e-2
