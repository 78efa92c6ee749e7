"""Contact candidates against a ground half-space: gap, normal, tangents (DESIGN.md 4.3, 4.4).

A contact candidate is a sphere of radius r on a frame with world centre p(q). The
ground is the half-space {x : n_w . x >= height} with unit normal n_w. Then

* gap f_c(q) = n_w . p(q) - height - r  [m]  (> 0: apart, < 0: penetrating),
* normal n(q) = grad_q f_c = J(q)^T n_w, an nv-column (J: the 3 x nv world-aligned
  linear Jacobian of the sphere centre),
* tangent basis B(q) = J(q)^T [t_1 (, t_2)]: one world tangent for a planar base (the
  ground direction in the x-z plane), two orthonormal ones in 3D,
* drift d/dt (n(q)^T v) at zero acceleration = n_w . (dJ/dt v) [m/s^2], the term
  d/dq(n^T v) v of the contact-breaking condition phi (DESIGN.md 4.3), and likewise
  B^T-drift for the tangents.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import FrameNotFound, IncompatibleOptions, InvalidInput
from tfcontact.robot.spec import ContactSpec
from tfcontact.robot.twin import RobotTwin


@dataclass(frozen=True)
class Ground:
    """The half-space {x : normal . x >= height} (the allowed side).

    Args:
        height: offset of the plane along `normal` [m]; for the default z-up normal the
            ground height.
        normal: outward normal (pointing into the free space), normalised on
            construction; default z-up.

    Raises:
        InvalidInput: a non-finite height, or a normal that is not a non-zero 3-vector.
    """

    height: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if isinstance(self.height, bool) or not isinstance(self.height, int | float) or \
                not math.isfinite(self.height):
            raise InvalidInput(f"`height` must be a finite number [m], got {self.height!r}")
        try:
            n = np.asarray(self.normal, dtype=float)
        except (TypeError, ValueError) as err:
            raise InvalidInput(f"`normal` must be 3 numbers, got {self.normal!r}") from err
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0.0:
            raise InvalidInput(
                f"`normal` must be a non-zero finite 3-vector, got {self.normal!r}; "
                "e.g. (0, 0, 1) for flat ground"
            )
        n = n / np.linalg.norm(n)
        object.__setattr__(self, "height", float(self.height))
        object.__setattr__(self, "normal", tuple(float(x) for x in n))

    def tangents(self, planar: bool) -> np.ndarray:
        """World tangent directions as columns (3 x 1 if `planar`, else 3 x 2).

        t_1 is the world x axis projected on the plane (the y axis if the normal is
        along x), t_2 = n x t_1; both unit vectors.

        Raises:
            IncompatibleOptions: `planar` with a normal outside the x-z plane.
        """
        n = np.asarray(self.normal)
        if planar and abs(n[1]) > 1e-12:
            raise IncompatibleOptions(
                f"a planar robot moves in the x-z plane but the ground normal {self.normal} "
                "has a y component; use a normal (n_x, 0, n_z)"
            )
        seed = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t1 = seed - n * (n @ seed)
        t1 /= np.linalg.norm(t1)
        if planar:
            return t1.reshape(3, 1)
        return np.column_stack([t1, np.cross(n, t1)])


@dataclass(frozen=True)
class ContactTerms:
    """Symbolic terms of one contact candidate (expressions in the twin's q, v).

    Attributes:
        contact: the `ContactSpec` (frame, radius).
        position: sphere centre p(q) in world coordinates [m], 3 x 1.
        gap: f_c(q) = n_w . p - height - r [m], 1 x 1.
        normal: n(q) = grad_q f_c = J^T n_w, nv x 1.
        tangents: B(q) = J^T T, nv x n_t (n_t = 1 planar, 2 in 3D).
        normal_drift: n_w . (dJ/dt v) = d/dq(n(q)^T v) v [m/s^2], 1 x 1, in q and v.
        tangent_drift: T^T (dJ/dt v), n_t x 1, in q and v.
        world_normal: n_w (3,), world_tangents: T (3 x n_t), numeric.
    """

    contact: ContactSpec
    position: ca.SX
    gap: ca.SX
    normal: ca.SX
    tangents: ca.SX
    normal_drift: ca.SX
    tangent_drift: ca.SX
    world_normal: np.ndarray
    world_tangents: np.ndarray

    @property
    def frame(self) -> str:
        return self.contact.frame

    @property
    def radius(self) -> float:
        return self.contact.radius


def contact_terms(twin: RobotTwin, contacts: Sequence[ContactSpec], ground: Ground, *,
                  planar: bool) -> list[ContactTerms]:
    """Gap, normal, tangent basis and drifts of each contact against `ground`.

    Args:
        twin: the robot's symbolic twin.
        contacts: contact candidates.
        ground: the half-space.
        planar: one tangent (x-z plane motion) instead of two.

    Raises:
        FrameNotFound: a contact frame that is not in the model.
        IncompatibleOptions: a planar robot with a normal outside the x-z plane.
    """
    n_w = np.asarray(ground.normal)
    T = ground.tangents(planar)
    out = []
    for c in contacts:
        if c.frame not in twin.frame_names:
            raise FrameNotFound(c.frame, twin.frame_names)
        p = twin.frame_position(c.frame)
        J = twin.frame_jacobian(c.frame)[0:3, :]
        drift = twin.frame_drift(c.frame)[0:3]
        gap = ca.dot(ca.DM(n_w), p) - ground.height - c.radius
        out.append(ContactTerms(
            contact=c,
            position=p,
            gap=gap,
            normal=ca.mtimes(J.T, ca.DM(n_w)),
            tangents=ca.mtimes(J.T, ca.DM(T)),
            normal_drift=ca.dot(ca.DM(n_w), drift),
            tangent_drift=ca.mtimes(ca.DM(T).T, drift),
            world_normal=n_w,
            world_tangents=T,
        ))
    return out
