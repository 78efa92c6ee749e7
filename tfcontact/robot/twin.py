"""The CasADi symbolic twin of a Pinocchio model (DESIGN.md sections 2 and 3).

The pip wheel of Pinocchio has no `pinocchio.casadi`, so the rigid-body algorithms
are transcribed here into CasADi SX from the model data (`model.parents`,
`model.jointPlacements`, `model.inertias`, joint types, `model.frames`,
`model.armature`, `model.gravity`). Pinocchio stays the numeric reference: the tests
compare every expression with `pin.crba`, `pin.nonLinearEffects`,
`pin.computeFrameJacobian` and `pin.getFrameClassicalAcceleration`.

Conventions (the same as Pinocchio's):

* Spatial vectors are **linear-first**: a motion is (v, w), a force is (f, tau).
* All recursions run in **world coordinates at the world origin** O: the motion
  subspace of a revolute joint with world axis a through the point p is
  S = (p x a, a), that of a prismatic joint S = (a, 0). The velocity of a body is
  V = (v_O, w) with v_O the velocity of the body-fixed point at O.
* A spatial inertia is stored as (m, h = m c, I_O) with c the world centre of mass and
  I_O = I_c - m [c]x [c]x the rotational inertia about O: I (v, w) = (m v + w x h,
  h x v + I_O w).
* Frame Jacobians and drifts are LOCAL_WORLD_ALIGNED: the linear part is the velocity
  (acceleration) of the frame origin, both parts in world axes.

Every joint of the model must have nq == nv (no quaternions, no unbounded revolute
joints). Composite joints are split into 1-DoF "elementary" joints: translation =
PX PY PZ, spherical ZYX = RZ RY RX, which have the same placement map and the same
velocity coordinates (v = dq/dt).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from tfcontact.errors import FrameNotFound, InvalidInput, RobotLoadError

_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]),
         "Z": np.array([0.0, 0.0, 1.0])}


@dataclass(frozen=True)
class _Elementary:
    """A 1-DoF joint: `placement` from the previous frame, then a motion along `axis`."""

    placement: pin.SE3
    revolute: bool
    axis: np.ndarray


def _split_joint(jmodel) -> list[_Elementary]:
    """Split a Pinocchio joint model into 1-DoF joints with the same placement map."""
    name = jmodel.shortname()
    eye = pin.SE3.Identity()
    if name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return [_Elementary(eye, True, _AXES[name[-1]])]
    if name in ("JointModelPX", "JointModelPY", "JointModelPZ"):
        return [_Elementary(eye, False, _AXES[name[-1]])]
    if name == "JointModelRevoluteUnaligned":
        return [_Elementary(eye, True, np.array(jmodel.extract().axis, dtype=float))]
    if name == "JointModelPrismaticUnaligned":
        return [_Elementary(eye, False, np.array(jmodel.extract().axis, dtype=float))]
    if name == "JointModelTranslation":
        return [_Elementary(eye, False, _AXES[a]) for a in "XYZ"]
    if name == "JointModelSphericalZYX":
        return [_Elementary(eye, True, _AXES[a]) for a in "ZYX"]
    if name == "JointModelComposite":
        composite = jmodel.extract()
        out: list[_Elementary] = []
        for placement, sub in zip(composite.jointPlacements, composite.joints, strict=True):
            parts = _split_joint(sub)
            first = parts[0]
            out.append(_Elementary(placement * first.placement, first.revolute, first.axis))
            out.extend(parts[1:])
        return out
    raise RobotLoadError(
        f"joint type `{name}` is not supported by the symbolic twin (supported: revolute "
        "RX/RY/RZ/unaligned, prismatic PX/PY/PZ/unaligned, translation, spherical ZYX and "
        "their composites, all with nq == nv); change the joint in the URDF (e.g. "
        "`continuous` -> `revolute`) or lock it with `locked_joints`"
    )


def _rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rotation matrix about the unit `axis` by `angle` [rad] (Rodrigues)."""
    c, s = ca.cos(angle), ca.sin(angle)
    if np.array_equal(axis, _AXES["X"]):
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
    if np.array_equal(axis, _AXES["Y"]):
        return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))
    if np.array_equal(axis, _AXES["Z"]):
        return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    k = ca.DM(_skew_np(axis))
    return ca.DM.eye(3) + s * k + (1 - c) * ca.mtimes(k, k)


def _skew_np(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _cross(a: ca.SX, b: ca.SX) -> ca.SX:
    return ca.cross(a, b)


def _motion_cross(V: tuple[ca.SX, ca.SX], m: tuple[ca.SX, ca.SX]) -> tuple[ca.SX, ca.SX]:
    """V x m for motions, linear-first: (w x m_v + v x m_w, w x m_w)."""
    v, w = V
    mv, mw = m
    return _cross(w, mv) + _cross(v, mw), _cross(w, mw)


def _force_cross(V: tuple[ca.SX, ca.SX], f: tuple[ca.SX, ca.SX]) -> tuple[ca.SX, ca.SX]:
    """V x* f for forces, linear-first: (w x f_lin, w x f_ang + v x f_lin)."""
    v, w = V
    fl, fa = f
    return _cross(w, fl), _cross(w, fa) + _cross(v, fl)


@dataclass
class _Inertia:
    """World spatial inertia about the origin: mass m, first moment h = m c, I_O."""

    m: ca.SX
    h: ca.SX
    I: ca.SX

    def __add__(self, other: _Inertia) -> _Inertia:
        return _Inertia(self.m + other.m, self.h + other.h, self.I + other.I)

    def apply(self, V: tuple[ca.SX, ca.SX]) -> tuple[ca.SX, ca.SX]:
        v, w = V
        return self.m * v + _cross(w, self.h), _cross(self.h, v) + ca.mtimes(self.I, w)


class RobotTwin:
    """CasADi SX expressions of a Pinocchio model's kinematics and dynamics.

    Symbols (all columns of length nv, nq == nv is required):
        q: generalised positions [m, rad]; v: generalised velocities [m/s, rad/s];
        tau: generalised forces [N, N m].

    Expressions:
        M (nv x nv, in q): joint-space inertia matrix (CRBA, with `model.armature` on
            the diagonal), equal to `pin.crba`.
        h (nv, in q, v): bias forces, h = C(q, v) v + g(q), equal to
            `pin.nonLinearEffects` (RNEA with zero acceleration).
        forward_dynamics(tau): a = M^-1 (tau - h), solved with M (sparse LDL^T or QR,
            never an explicit inverse).

    Per frame (`frame_position`, `frame_rotation`, `frame_jacobian`, `frame_drift`):
    placement p(q) [m], R(q); LOCAL_WORLD_ALIGNED Jacobian J(q) (6 x nv, linear
    rows first); drift dJ/dt v (6, in q, v): the classical acceleration of the frame
    origin at zero joint acceleration, equal to `pin.getFrameClassicalAcceleration`
    after `pin.forwardKinematics(model, data, q, v, 0)`.

    Args:
        model: a Pinocchio model whose joints all have nq == nv.

    Raises:
        RobotLoadError: a joint type the twin cannot transcribe.
    """

    def __init__(self, model: pin.Model):
        if model.nq != model.nv:
            bad = [
                f"{model.names[i]} ({model.joints[i].shortname()}: nq={model.joints[i].nq}, "
                f"nv={model.joints[i].nv})"
                for i in range(1, model.njoints)
                if model.joints[i].nq != model.joints[i].nv
            ]
            raise RobotLoadError(
                f"the symbolic twin needs nq == nv but the model has nq={model.nq}, "
                f"nv={model.nv}: joints {', '.join(bad)}; load the robot with base='floating' "
                "or 'planar' instead of a quaternion free-flyer, and use `revolute` instead "
                "of `continuous` joints"
            )
        self.model = model
        self.nq = model.nq
        self.nv = model.nv
        self.q = ca.SX.sym("q", self.nv)
        self.v = ca.SX.sym("v", self.nv)
        self.tau = ca.SX.sym("tau", self.nv)
        self.frame_names: tuple[str, ...] = tuple(f.name for f in model.frames)
        self._build()
        self._functions: dict[str, ca.Function] = {}

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        model, q, v = self.model, self.q, self.v
        n = model.njoints
        zero3 = ca.SX.zeros(3, 1)
        # Placement (R, p) of every Pinocchio joint frame, and for each one its last
        # elementary joint (bodies and frames attach there).
        self._R: list[ca.SX] = [ca.SX.eye(3)] * n
        self._p: list[ca.SX] = [zero3] * n
        # Per elementary joint k: v index, parent elementary index (-1: world), S (lin, ang),
        # world velocity V, acceleration A0 (zero qdd, no gravity), inertia.
        idx: list[int] = []
        parent: list[int] = []
        S: list[tuple[ca.SX, ca.SX]] = []
        V: list[tuple[ca.SX, ca.SX]] = []
        A0: list[tuple[ca.SX, ca.SX]] = []
        inertia: list[_Inertia | None] = []
        last = [-1] * n  # last elementary joint of each Pinocchio joint (-1: the world)
        for i in range(1, n):
            jm = model.joints[i]
            R = self._R[model.parents[i]]
            p = self._p[model.parents[i]]
            X = model.jointPlacements[i]
            prev = last[model.parents[i]]
            for j, e in enumerate(_split_joint(jm)):
                Xe = X * e.placement if j == 0 else e.placement
                p = p + ca.mtimes(R, ca.DM(Xe.translation))
                R = ca.mtimes(R, ca.DM(Xe.rotation))
                k = jm.idx_v + j
                axis = ca.mtimes(R, ca.DM(e.axis))
                if e.revolute:
                    s = (_cross(p, axis), axis)
                    R = ca.mtimes(R, _rotation(e.axis, q[k]))
                else:
                    s = (axis, zero3)
                    p = p + axis * q[k]
                Vp = V[prev] if prev >= 0 else (zero3, zero3)
                Ap = A0[prev] if prev >= 0 else (zero3, zero3)
                Vk = (Vp[0] + s[0] * v[k], Vp[1] + s[1] * v[k])
                c = _motion_cross(Vk, s)
                Ak = (Ap[0] + c[0] * v[k], Ap[1] + c[1] * v[k])
                idx.append(k)
                parent.append(prev)
                S.append(s)
                V.append(Vk)
                A0.append(Ak)
                inertia.append(None)
                prev = len(idx) - 1
            last[i] = prev
            self._R[i], self._p[i] = R, p
            Y = model.inertias[i]
            if Y.mass != 0.0 or np.any(Y.inertia != 0.0):
                c_w = p + ca.mtimes(R, ca.DM(Y.lever))
                Ic = ca.mtimes(ca.mtimes(R, ca.DM(Y.inertia)), R.T)
                cx = ca.skew(c_w)
                inertia[prev] = _Inertia(
                    ca.SX(Y.mass), Y.mass * c_w, Ic - Y.mass * ca.mtimes(cx, cx)
                )
        self._idx, self._parent, self._S, self._V, self._A0 = idx, parent, S, V, A0
        self._last = last
        nel = len(idx)

        # CRBA in world coordinates: composite inertias need no transforms.
        composite: list[_Inertia | None] = list(inertia)
        for k in range(nel - 1, -1, -1):
            pk = parent[k]
            ck = composite[k]
            if pk >= 0 and ck is not None:
                composite[pk] = ck if composite[pk] is None else composite[pk] + ck
        M = ca.SX(self.nv, self.nv)  # structurally sparse: zero where joints do not share a path
        for k in range(nel):
            if composite[k] is None:
                continue
            F = composite[k].apply(S[k])
            j = k
            while j >= 0:
                val = ca.dot(S[j][0], F[0]) + ca.dot(S[j][1], F[1])
                M[idx[j], idx[k]] = val
                if j != k:
                    M[idx[k], idx[j]] = val
                j = parent[j]
        for k in range(self.nv):
            if model.armature[k] != 0.0:
                M[k, k] = M[k, k] + float(model.armature[k])
        self.M: ca.SX = M

        # RNEA with zero acceleration (gravity as an upward acceleration of the world).
        g = model.gravity
        a_root = (ca.DM(-g.linear), ca.DM(-g.angular))
        forces: list[tuple[ca.SX, ca.SX] | None] = [None] * nel
        for k in range(nel):
            if inertia[k] is None:
                continue
            Ak = (A0[k][0] + a_root[0], A0[k][1] + a_root[1])
            IA = inertia[k].apply(Ak)
            vf = _force_cross(V[k], inertia[k].apply(V[k]))
            forces[k] = (IA[0] + vf[0], IA[1] + vf[1])
        h = ca.SX.zeros(self.nv, 1)
        for k in range(nel - 1, -1, -1):
            F = forces[k]
            if F is None:
                continue
            h[idx[k]] = ca.dot(S[k][0], F[0]) + ca.dot(S[k][1], F[1])
            pk = parent[k]
            if pk >= 0:
                Fp = forces[pk]
                forces[pk] = F if Fp is None else (Fp[0] + F[0], Fp[1] + F[1])
        self.h: ca.SX = h

    # ----------------------------------------------------------------- frames
    def _frame(self, name: str) -> pin.Frame:
        if not self.model.existFrame(name):
            raise FrameNotFound(name, self.frame_names)
        return self.model.frames[self.model.getFrameId(name)]

    def frame_position(self, name: str) -> ca.SX:
        """World position of the origin of frame `name` [m], a 3-column in q."""
        f = self._frame(name)
        j = f.parentJoint
        return self._p[j] + ca.mtimes(self._R[j], ca.DM(f.placement.translation))

    def frame_rotation(self, name: str) -> ca.SX:
        """Rotation of frame `name` to world axes, 3 x 3 in q."""
        f = self._frame(name)
        return ca.mtimes(self._R[f.parentJoint], ca.DM(f.placement.rotation))

    def _support(self, joint: int) -> list[int]:
        out = []
        k = self._last[joint]
        while k >= 0:
            out.append(k)
            k = self._parent[k]
        return out

    def frame_jacobian(self, name: str) -> ca.SX:
        """LOCAL_WORLD_ALIGNED Jacobian of frame `name`, 6 x nv in q, linear rows first.

        Column k is (S_lin + S_ang x p_f, S_ang) for joints k supporting the frame.
        """
        f = self._frame(name)
        pf = self.frame_position(name)
        J = ca.SX(6, self.nv)  # structural zeros off the support of the frame
        for k in self._support(f.parentJoint):
            lin, ang = self._S[k]
            J[0:3, self._idx[k]] = lin + _cross(ang, pf)
            J[3:6, self._idx[k]] = ang
        return J

    def frame_drift(self, name: str) -> ca.SX:
        """dJ/dt v of frame `name` (LOCAL_WORLD_ALIGNED), a 6-column in q and v.

        The classical acceleration of the frame origin at zero joint acceleration:
        linear a_lin + a_ang x p + w x (v + w x p), angular a_ang, with (v, w), (a_lin,
        a_ang) the world spatial velocity and acceleration of the parent body at O.
        """
        f = self._frame(name)
        pf = self.frame_position(name)
        k = self._last[f.parentJoint]
        if k < 0:
            return ca.SX.zeros(6, 1)
        v, w = self._V[k]
        al, aa = self._A0[k]
        vp = v + _cross(w, pf)
        return ca.vertcat(al + _cross(aa, pf) + _cross(w, vp), aa)

    # --------------------------------------------------------------- dynamics
    def forward_dynamics(self, tau: ca.SX | None = None, *, method: str = "ldl") -> ca.SX:
        """a = M(q)^-1 (tau - h(q, v)) [m/s^2, rad/s^2], solved with M (no inverse).

        Args:
            tau: generalised forces, an nv-column; default the symbol `self.tau`.
            method: ``"ldl"`` (default): sparse symbolic LDL^T of M (`casadi.ldl`,
                fill-reducing ordering, no pivoting, valid since M is symmetric positive
                definite), which exploits the zeros between branches of the kinematic
                tree; ``"qr"``: `casadi.solve` (symbolic QR), about 2.5x more operations
                on solo12.

        Raises:
            InvalidInput: an unknown `method`.
        """
        tau = self.tau if tau is None else tau
        if method == "ldl":
            D, LT, p = ca.ldl(self.M)
            return ca.ldl_solve(tau - self.h, D, LT, p)
        if method == "qr":
            return ca.solve(self.M, tau - self.h)
        raise InvalidInput(f"`method` must be 'ldl' or 'qr', got {method!r}")

    def function(self, kind: str) -> ca.Function:
        """A cached `casadi.Function` of the main expressions.

        `kind` is ``"M"`` (q -> M), ``"h"`` (q, v -> h), ``"fd"`` (q, v, tau -> a, sparse
        LDL^T) or ``"fd_qr"`` (the same by `casadi.solve`).
        """
        if kind not in self._functions:
            q, v, tau = self.q, self.v, self.tau
            opts = {"cse": True}
            if kind == "M":
                f = ca.Function("M", [q], [self.M], ["q"], ["M"], opts)
            elif kind == "h":
                f = ca.Function("h", [q, v], [self.h], ["q", "v"], ["h"], opts)
            elif kind in ("fd", "fd_qr"):
                method = "ldl" if kind == "fd" else "qr"
                f = ca.Function(kind, [q, v, tau], [self.forward_dynamics(method=method)],
                                ["q", "v", "tau"], ["a"], opts)
            else:
                raise InvalidInput(f"`kind` must be 'M', 'h', 'fd' or 'fd_qr', got {kind!r}")
            self._functions[kind] = f
        return self._functions[kind]
