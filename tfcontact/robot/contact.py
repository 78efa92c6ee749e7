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

A `Terrain` (tfcontact.robot.terrain) can stand where a Ground does: then the gap is the
terrain's g(p) = d(p) - r, the world normal n_w(p) = grad_p g varies with the point,
n(q) = J^T n_w(p(q)) is still grad_q f_c, the tangents follow the local normal, and the
drifts gain the curvature terms pdot^T (d n_w/dp) pdot (and likewise for the tangents).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import FrameNotFound, IncompatibleOptions, InvalidInput
from tfcontact.robot.spec import ContactSpec
from tfcontact.robot.terrain import Terrain
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

    def gap(self, point: Any, radius: float) -> Any:
        """g = normal . p - height - r [m] of a sphere of `radius` centred at `point` (a
        casadi 3-vector), as `Terrain.gap`."""
        return ca.dot(ca.DM(self.normal), point) - self.height - radius

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
        world_normal: n_w (3,), world_tangents: T (3 x n_t): numeric against a `Ground`;
            against a `Terrain` SX expressions in q (3 x 1 and 3 x n_t), the unit normal and
            tangents at the sphere centre's nearest terrain point.
    """

    contact: ContactSpec
    position: ca.SX
    gap: ca.SX
    normal: ca.SX
    tangents: ca.SX
    normal_drift: ca.SX
    tangent_drift: ca.SX
    world_normal: np.ndarray | ca.SX
    world_tangents: np.ndarray | ca.SX

    @property
    def frame(self) -> str:
        return self.contact.frame

    @property
    def radius(self) -> float:
        return self.contact.radius


def contact_terms(twin: RobotTwin, contacts: Sequence[ContactSpec], ground: Ground | Terrain,
                  *, planar: bool) -> list[ContactTerms]:
    """Gap, normal, tangent basis and drifts of each contact against `ground`.

    Args:
        twin: the robot's symbolic twin.
        contacts: contact candidates.
        ground: the half-space, or a `Terrain` (module docstring).
        planar: one tangent (x-z plane motion) instead of two.

    Raises:
        FrameNotFound: a contact frame that is not in the model.
        IncompatibleOptions: a planar robot with a normal outside the x-z plane, or with a
            terrain that depends on y.
        InvalidInput: `ground` is neither a Ground nor a Terrain.
    """
    if isinstance(ground, Terrain):
        return _terrain_terms(twin, contacts, ground, planar=planar)
    if not isinstance(ground, Ground):
        raise InvalidInput(
            f"`ground` must be a Ground or a Terrain, got {type(ground).__name__}"
        )
    n_w = np.asarray(ground.normal)
    T = ground.tangents(planar)
    out = []
    for c in contacts:
        if c.frame not in twin.frame_names:
            raise FrameNotFound(c.frame, twin.frame_names)
        p = twin.frame_position(c.frame)
        J = twin.frame_jacobian(c.frame)[0:3, :]
        drift = twin.frame_drift(c.frame)[0:3]
        gap = ground.gap(p, c.radius)
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


def terrain_tangents(normal: ca.SX, planar: bool) -> ca.SX:
    """Unit tangents (3 x 1 planar, 3 x 2) of a unit world normal n, smooth in n.

    Planar: t = (n_z, 0, -n_x), the in-plane direction (Ground's convention). 3-D: the
    frame of Frisvad (J. Graphics Tools 16, 2012) without its sign branch,
    t_1 = (1 - n_x^2/(1+n_z), -n_x n_y/(1+n_z), -n_x), t_2 = n x t_1, smooth except at
    n_z = -1, which no terrain normal reaches (they all have n_z >= 0); it equals
    Ground's tangents for normals in the x-z plane.
    """
    nx, ny, nz = normal[0], normal[1], normal[2]
    if planar:
        return ca.vertcat(nz, 0.0, -nx)
    c = 1.0 / (1.0 + nz)
    t1 = ca.vertcat(1.0 - nx * nx * c, -nx * ny * c, -nx)
    t2 = ca.vertcat(-nx * ny * c, 1.0 - ny * ny * c, -ny)
    return ca.horzcat(t1, t2)


def _terrain_terms(twin: RobotTwin, contacts: Sequence[ContactSpec], terrain: Terrain, *,
                   planar: bool) -> list[ContactTerms]:
    if planar and not terrain.planar:
        raise IncompatibleOptions(
            "a planar robot moves in the x-z plane but the terrain depends on y (a plane "
            "normal with a y component, or a Box/Hole with a `y` range); use y = None and "
            "normals (n_x, 0, n_z)"
        )
    # the geometry in a free point P and point velocity W, substituted by p(q), J v
    P, W = ca.SX.sym("P", 3), ca.SX.sym("W", 3)
    distance = terrain.distance(P)
    grad = ca.gradient(distance, P)
    unit = grad / ca.norm_2(grad)
    tangents = terrain_tangents(unit, planar)
    # d/dt (grad^T W) at fixed W = W^T Hess W; likewise for T^T W
    normal_curvature = ca.jtimes(ca.dot(grad, W), P, W)
    tangent_curvature = ca.jtimes(ca.mtimes(tangents.T, W), P, W)
    out = []
    for c in contacts:
        if c.frame not in twin.frame_names:
            raise FrameNotFound(c.frame, twin.frame_names)
        p = twin.frame_position(c.frame)
        J = twin.frame_jacobian(c.frame)[0:3, :]
        drift = twin.frame_drift(c.frame)[0:3]
        pdot = ca.mtimes(J, twin.v)

        def at(expr: ca.SX, p: ca.SX = p, pdot: ca.SX = pdot) -> ca.SX:
            return ca.substitute([expr], [P, W], [p, pdot])[0]

        n_w, T = at(grad), at(tangents)
        out.append(ContactTerms(
            contact=c,
            position=p,
            gap=at(distance) - c.radius,
            normal=ca.mtimes(J.T, n_w),
            tangents=ca.mtimes(J.T, T),
            normal_drift=ca.dot(n_w, drift) + at(normal_curvature),
            tangent_drift=ca.mtimes(T.T, drift) + at(tangent_curvature),
            world_normal=at(unit),
            world_tangents=T,
        ))
    return out
