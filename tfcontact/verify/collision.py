"""The full collision model along a plan: every collision body against the terrain and itself.

A plan is computed with contact candidates only (spheres on frames, `ContactSpec`) against
one ground; nothing in the OCP keeps a knee, a base or a shank out of a step. This check
takes the URDF's whole collision model (`Robot.collision_model`, a Pinocchio
`GeometryModel` of coal shapes) and measures, at every sample of the physical trajectory,

* the signed distance d_b(t) [m] of every collision body b to the nearest obstacle of the
  terrain (`Obstacle`: a half-space, a box, any coal shape), and
* the signed distance d_ab(t) [m] of every pair of bodies (a, b) of the robot, minus the
  pairs on one joint (one rigid body) and, by default, those on adjacent joints (parent
  and child, whose geometries meet at the joint by construction).

coal's distance is signed for convex shapes: d < 0 is the penetration depth (GJK/EPA), so
"4 mm through the step" reads d = -4e-3. A body fails when d < -tolerance. A body that is
not the body of a declared contact and comes within `touch_distance` of the terrain gets a
hint: the plan leans on a contact it did not model (declare one on that body's frame, or
raise the body). The declared contacts' own bodies touching the terrain is what a plan
does; they fail only by going through it.

Entry points: `check_collisions(model, collision_model, t, q, obstacles, contacts=...)` on
plain Pinocchio models and arrays, and `check_robot_collisions(robot, t, q, obstacles)` for
a loaded `Robot` (its contacts are the declared ones). A saved trajectory is checked with
`tfcontact.viz.collision_figure.trajectory_collisions`, which also draws the figure.

The samples are checked as given; a body that passes through a thin obstacle between two
samples is found only with `CollisionOptions(substeps=k)`, which adds k - 1 configurations
interpolated on the manifold (`pin.interpolate`) in every sample interval.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.robot import Box, Ground, Hole, Plane, Robot, Terrain

# ----------------------------------------------------------------------------- obstacles


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A fixed piece of terrain: a coal shape placed in the world.

    Args:
        name: the name the report uses ("ground", "step").
        geometry: a coal shape (`coal.Halfspace`, `coal.Box`, `coal.Sphere`, a mesh, ...).
        placement: the shape's pose in the world frame; default the identity.

    Raises:
        InvalidInput: an empty name, a geometry that is not a `coal.CollisionGeometry` or
            a placement that is not a `pin.SE3`.
    """

    name: str
    geometry: coal.CollisionGeometry
    placement: pin.SE3 = field(default_factory=pin.SE3.Identity)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidInput(f"`name` must be a non-empty string, got {self.name!r}")
        if not isinstance(self.geometry, coal.CollisionGeometry):
            raise InvalidInput(
                f"`geometry` of obstacle `{self.name}` must be a coal shape "
                f"(coal.Halfspace, coal.Box, ...), got {type(self.geometry).__name__}; "
                "use halfspace_obstacle or box_obstacle"
            )
        if not isinstance(self.placement, pin.SE3):
            raise InvalidInput(
                f"`placement` of obstacle `{self.name}` must be a pinocchio.SE3, got "
                f"{type(self.placement).__name__}"
            )
        object.__setattr__(self, "placement", pin.SE3(self.placement))  # own copy


def _vector3(value: Any, name: str) -> np.ndarray:
    try:
        out = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise InvalidInput(f"`{name}` must be 3 numbers, got {value!r}") from err
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise InvalidInput(f"`{name}` must be 3 finite numbers, got {value!r}")
    return out


def halfspace_obstacle(name: str = "ground", *, normal: Sequence[float] = (0.0, 0.0, 1.0),
                       height: float = 0.0) -> Obstacle:
    """The solid half-space {x : n . x <= height} below the plane n . x = height.

    Args:
        name: the obstacle's name.
        normal: the plane's normal n, pointing into the free space (normalised here).
        height: the plane's offset along n [m].

    Raises:
        InvalidInput: a zero or non-finite normal, a non-finite height.
    """
    n = _vector3(normal, "normal")
    if np.linalg.norm(n) == 0.0:
        raise InvalidInput(f"`normal` must be a non-zero 3-vector, got {normal!r}")
    if isinstance(height, bool) or not isinstance(height, int | float) \
            or not math.isfinite(height):
        raise InvalidInput(f"`height` must be a finite number [m], got {height!r}")
    return Obstacle(name, coal.Halfspace(n / np.linalg.norm(n), float(height)))


def ground_obstacle(ground: Ground, name: str = "ground") -> Obstacle:
    """The solid side of a contact `Ground` (the half-space its gaps are measured to)."""
    if not isinstance(ground, Ground):
        raise InvalidInput(f"`ground` must be a tfcontact.robot.Ground, got {ground!r}")
    return halfspace_obstacle(name, normal=ground.normal, height=ground.height)


def box_obstacle(name: str, size: Sequence[float], *, center: Sequence[float] = (0.0, 0.0, 0.0),
                 rotation: np.ndarray | None = None) -> Obstacle:
    """A solid box (a step, a block) of side lengths `size` [m] centred at `center` [m].

    Args:
        name: the obstacle's name.
        size: full side lengths (l_x, l_y, l_z) [m] along the box's own axes, all > 0.
        center: the box centre in the world [m].
        rotation: a 3x3 rotation matrix from the box's axes to the world; default identity.

    Raises:
        InvalidInput: a non-positive side length, a bad centre or rotation.
    """
    lengths = _vector3(size, "size")
    if np.any(lengths <= 0.0):
        raise InvalidInput(f"`size` must hold three side lengths > 0 [m], got {size!r}")
    rot = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    if rot.shape != (3, 3) or not np.all(np.isfinite(rot)) \
            or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-9) or np.linalg.det(rot) < 0:
        raise InvalidInput(f"`rotation` must be a 3x3 rotation matrix, got {rotation!r}")
    return Obstacle(name, coal.Box(*lengths), pin.SE3(rot, _vector3(center, "center")))


def terrain_obstacles(terrain: Terrain, *, extent: float = 100.0) -> tuple[Obstacle, ...]:
    """The solids of a `tfcontact.robot.Terrain` as obstacles, with the distances of its
    contact gaps.

    * A `Plane` without holes: the half-space below it, named "plane[i]" (i its index in
      `terrain.primitives`).
    * A `Box`: a coal box shrunk by its rounding rho with a swept sphere of radius rho
      (coal's rounded box: the Minkowski sum of `Terrain`'s gap), named "box[i]"; an
      infinite side ends `extent` m from the origin, and the solid reaches `extent` m
      below its top.
    * A plane with holes (horizontal, as `Terrain` requires): the ground around them as
      boxes, "plane[i] beside holes (k)". One hole: the half-infinite boxes of
      `Hole.cut`, rims rounded: exact. Several holes, all without a y-range (a planar
      scene's ditches): the boxes between them, each rounded with the smaller rim
      rounding of its two holes (exact for equal roundings, else a sharper rim: a larger
      solid, distances at most the difference of the roundings too small). Several holes
      in 3D: the cells of the grid of their footprints that no hole covers, with sharp
      rims (distances too small by at most the rounding near a rim, and depths inside
      the ground underestimated near the cells' seams). A hole's floor is the half-space
      below it, "floor of hole[j]".

    The terrain's smooth minimum (`Terrain.smoothing`) is not modelled: coal measures the
    exact distance to the union, which is at most smoothing/4 above the gap's.

    Args:
        terrain: the terrain.
        extent: where infinite sides end, and the depth of boxes [m]; far beyond the
            plan (coal's distances stay exact to 1e-12 with boxes of 1000 m).

    Raises:
        InvalidInput: `terrain` not a Terrain, `extent` not a finite number > 0.
    """
    if not isinstance(terrain, Terrain):
        raise InvalidInput(f"`terrain` must be a tfcontact.robot.Terrain, got "
                           f"{type(terrain).__name__}")
    if isinstance(extent, bool) or not isinstance(extent, int | float) \
            or not (math.isfinite(extent) and extent > 0.0):
        raise InvalidInput(f"`extent` must be a finite number > 0 [m], got {extent!r}")
    index = {id(p): i for i, p in enumerate(terrain.primitives)}
    holes = terrain.holes
    out: list[Obstacle] = []
    for p in terrain.primitives:
        i = index[id(p)]
        if isinstance(p, Box):
            out.append(_rounded_box(f"box[{i}]", p.x, p.y, p.top, p.rounding, extent))
        elif isinstance(p, Plane) and not holes:
            out.append(halfspace_obstacle(f"plane[{i}]", normal=p.normal,
                                          height=p.normal[2] * p.height))
        elif isinstance(p, Plane):
            cells = _ground_beside(holes, extent)
            out += [_rounded_box(f"plane[{i}] beside holes ({k})", x, y, p.height, rho,
                                 extent) for k, (x, y, rho) in enumerate(cells)]
    for hole in holes:
        if hole.floor is not None:
            out.append(halfspace_obstacle(f"floor of hole[{index[id(hole)]}]",
                                          height=hole.floor))
    return tuple(out)


_Range = tuple[float, float]


def _ground_beside(holes: tuple[Hole, ...], extent: float
                   ) -> list[tuple[_Range, _Range | None, float]]:
    """(x, y, rounding) of boxes whose union is a plane minus `holes` (infinite ends
    kept; `_rounded_box` cuts them)."""
    inf = math.inf
    if len(holes) == 1:  # Hole.cut's half-infinite boxes, overlapping: exact
        h = holes[0]
        cells: list[tuple[_Range, _Range | None, float]] = [
            ((-inf, h.x[0]), None, h.rounding), ((h.x[1], inf), None, h.rounding)]
        if h.y is not None:
            cells += [((-inf, inf), (-inf, h.y[0]), h.rounding),
                      ((-inf, inf), (h.y[1], inf), h.rounding)]
        return cells
    if all(h.y is None for h in holes):
        ordered = sorted(holes, key=lambda h: h.x[0])
        cells = [((-inf, ordered[0].x[0]), None, ordered[0].rounding)]
        for a, b in zip(ordered, ordered[1:], strict=False):
            cells.append(((a.x[1], b.x[0]), None, min(a.rounding, b.rounding)))
        cells.append(((ordered[-1].x[1], inf), None, ordered[-1].rounding))
        return cells
    xs = sorted({-inf, inf, *(b for h in holes for b in h.x)})
    ys = sorted({-inf, inf, *(b for h in holes if h.y is not None for b in h.y)})
    cells = []
    for x in zip(xs, xs[1:], strict=False):
        for y in zip(ys, ys[1:], strict=False):
            mid = [(lo + hi) / 2 if math.isfinite(lo + hi) else (hi - 1 if math.isfinite(hi)
                                                                 else lo + 1)
                   for lo, hi in (x, y)]
            if not any(h.covers(*mid) for h in holes):
                cells.append((x, y, 0.0))
    return cells


def _rounded_box(name: str, x: _Range, y: _Range | None, top: float, rounding: float,
                 extent: float) -> Obstacle:
    """The solid {x, y in their ranges, top - extent <= z <= top}, edges rounded: a coal
    box shrunk by `rounding` with that swept-sphere radius; infinite ends at +-extent."""
    ranges = [x, (-math.inf, math.inf) if y is None else y, (top - extent, top)]
    lo = np.array([max(a, -extent) for a, _ in ranges]) + rounding
    hi = np.array([min(b, extent) for _, b in ranges]) - rounding
    if np.any(hi <= lo):
        raise InvalidInput(f"obstacle `{name}` lies beyond `extent` = {extent} m; raise it")
    shape = coal.Box(*(hi - lo))
    shape.setSweptSphereRadius(rounding)
    return Obstacle(name, shape, pin.SE3(np.eye(3), (lo + hi) / 2))


# ----------------------------------------------------------------------------- options


@dataclass(frozen=True)
class CollisionOptions:
    """What the collision check judges and skips.

    Args:
        tolerance: the penetration allowed [m]: a body fails when its signed distance to
            an obstacle or to another body is below -tolerance. The default matches
            `VerifyOptions.gap_tolerance`.
        touch_distance: a body that is not a declared contact's body touches the terrain
            when its distance is below this [m] (>= 0); it gets a "missing contact" hint.
        self_collision: check the robot's bodies against each other.
        skip_adjacent: skip the pairs of bodies on a parent and a child joint (bodies on
            one joint, one rigid body, are always skipped).
        ignore_bodies: collision bodies (geometry names such as ``"foot_0"``, or link
            names) left out of every check.
        ignore_pairs: pairs of bodies (geometry or link names) left out of the
            self-collision check.
        substeps: configurations checked per sample interval (1: the samples only; k: k - 1
            more, interpolated on the manifold), to catch a body passing through a thin
            obstacle between samples.
        meshes_as_convex: check a mesh body (a coal BVH, e.g. an STL) as the convex hull
            of its vertices. coal's distance of a mesh is not signed (a mesh sunk into the
            ground measures a wrong depth, and mesh-mesh distances cost about 100 times
            more); the hull's are (GJK/EPA), at the price of a shape that contains the mesh:
            its distances are lower bounds of the mesh's.

    Raises:
        InvalidInput: a tolerance that is not a non-negative finite number, a flag that is
            not a bool, names that are not non-empty strings, a pair that is not two
            names, `substeps` not a positive integer.
    """

    tolerance: float = 1e-3
    touch_distance: float = 1e-3
    self_collision: bool = True
    skip_adjacent: bool = True
    ignore_bodies: tuple[str, ...] = ()
    ignore_pairs: tuple[tuple[str, str], ...] = ()
    substeps: int = 1
    meshes_as_convex: bool = True

    def __post_init__(self) -> None:
        for name in ("tolerance", "touch_distance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not (math.isfinite(value) and value >= 0.0):
                raise InvalidInput(f"`{name}` must be a non-negative number [m], got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in ("self_collision", "skip_adjacent", "meshes_as_convex"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInput(f"`{name}` must be True or False, got {getattr(self, name)!r}")
        if isinstance(self.ignore_bodies, str):
            raise InvalidInput(
                f"`ignore_bodies` must be a sequence of body names, got the string "
                f"{self.ignore_bodies!r}; write ({self.ignore_bodies!r},)"
            )
        bodies = tuple(self.ignore_bodies)
        for b in bodies:
            if not isinstance(b, str) or not b:
                raise InvalidInput(f"`ignore_bodies` must hold body names, got {b!r}")
        pairs = []
        for p in self.ignore_pairs:
            if isinstance(p, str) or len(tuple(p)) != 2 \
                    or not all(isinstance(n, str) and n for n in p):
                raise InvalidInput(
                    f"`ignore_pairs` must hold pairs of body names, got {p!r}; "
                    "write (('thigh_0', 'shank_0'),)"
                )
            pairs.append((p[0], p[1]))
        object.__setattr__(self, "ignore_bodies", bodies)
        object.__setattr__(self, "ignore_pairs", tuple(pairs))
        object.__setattr__(self, "substeps", positive_int(self.substeps, "substeps"))


# ----------------------------------------------------------------------------- results


class CollisionStatus(enum.Enum):
    """How a collision check ended; `message` says what to do."""

    CLEAR = "clear"
    UNDECLARED_CONTACT = "undeclared_contact"
    PENETRATION = "penetration"

    @property
    def message(self) -> str:
        return {
            CollisionStatus.CLEAR: "no body goes through the terrain or another body",
            CollisionStatus.UNDECLARED_CONTACT: (
                "a body that is not a declared contact touches the terrain (within the "
                "tolerance): the plan leans on a force it did not model; declare a contact "
                "on that body or keep it clear"),
            CollisionStatus.PENETRATION: (
                "a body goes through the terrain or another body: add the obstacle to the "
                "problem (a contact or a clearance) or change the task"),
        }[self]


@dataclass(frozen=True)
class BodyDistance:
    """The closest approach of one collision body to the terrain.

    Attributes:
        body: the geometry's name (``"base_0"``).
        link: the frame the geometry hangs on (the URDF link).
        min_distance: the smallest signed distance to any obstacle [m] (< 0: penetration).
        time: the physical time [s] of that minimum (the first one).
        obstacle: the obstacle it is closest to then.
        contact: the body is a declared contact's body (touching is expected): its frame
            is a contact's, or it sits on a contact's joint and touches the terrain only
            inside that contact's sphere (a lower leg whose mesh holds the foot).
    """

    body: str
    link: str
    min_distance: float
    time: float
    obstacle: str
    contact: bool


@dataclass(frozen=True)
class PairDistance:
    """The closest approach of two collision bodies of the robot [m] and its time [s];
    `meshes_apart`: their convex hulls overlap beyond the tolerance (`min_distance`), but
    the meshes themselves do not intersect at any sample where they do (not a collision).
    """

    body_a: str
    body_b: str
    min_distance: float
    time: float
    meshes_apart: bool = False


@dataclass(frozen=True, eq=False)
class CollisionReport:
    """The outcome of a collision check of one trajectory.

    Attributes:
        status: a `CollisionStatus`.
        passed: no body went deeper than `tolerance` into an obstacle or another body.
        worst: the worst offender in words, e.g. "body 'knee_0' (link 'knee') 4.0 mm
            through obstacle 'step' at t = 0.410 s", or the closest approach when clear.
        hints: one line per non-contact body that touches the terrain, naming the
            contact that is missing.
        bodies: per collision body checked against the terrain, its `BodyDistance`.
        pairs: per self-collision pair checked, its `PairDistance`.
        times: the physical times checked [s], shape (S,) (samples and substeps).
        terrain_distance: shape (S, len(bodies)), each body's distance to the nearest
            obstacle [m] (inf: no obstacle).
        pair_distance: shape (S, len(pairs)), each pair's distance [m].
        skipped_pairs: the self-collision pairs left out, with the reason.
        tolerance: the penetration allowed [m].
        notes: what was not checked.
    """

    status: CollisionStatus
    passed: bool
    worst: str
    hints: tuple[str, ...]
    bodies: tuple[BodyDistance, ...]
    pairs: tuple[PairDistance, ...]
    times: np.ndarray
    terrain_distance: np.ndarray
    pair_distance: np.ndarray
    skipped_pairs: tuple[tuple[str, str, str], ...]
    tolerance: float
    notes: tuple[str, ...] = ()

    def body(self, name: str) -> BodyDistance:
        """The `BodyDistance` of a body, by geometry or link name."""
        for b in self.bodies:
            if name in (b.body, b.link):
                return b
        raise InvalidInput(
            f"no body `{name}` in the report; bodies: {', '.join(b.body for b in self.bodies)}"
        )

    def summary(self) -> str:
        flag = "PASSED" if self.passed else "FAILED"
        text = (f"collisions {flag} ({self.status.value}, tol {self.tolerance:.0e} m, "
                f"{len(self.bodies)} bodies x {self.times.size} times, {len(self.pairs)} "
                f"self pairs): {self.worst}")
        return "; ".join((text, *self.hints))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types (the per-time arrays left out)."""
        return {
            "status": self.status.value,
            "passed": self.passed,
            "worst": self.worst,
            "hints": list(self.hints),
            "tolerance": self.tolerance,
            "bodies": [vars(b).copy() for b in self.bodies],
            "pairs": [vars(p).copy() for p in self.pairs],
            "skipped_pairs": [list(p) for p in self.skipped_pairs],
            "n_times": int(self.times.size),
            "notes": list(self.notes),
        }


# ----------------------------------------------------------------------------- the check


def check_robot_collisions(robot: Robot, t: np.ndarray, q: np.ndarray,
                           obstacles: Sequence[Obstacle], *,
                           options: CollisionOptions | None = None) -> CollisionReport:
    """`check_collisions` on a loaded robot, its `contacts` as the declared contacts.

    Args:
        robot: a `Robot` from `load_robot` (its `collision_model` is the URDF's).
        t: physical times [s], shape (S,); q: configurations, shape (S, nq).
        obstacles: the terrain.
        options: a `CollisionOptions`; default `CollisionOptions()`.
    """
    if not isinstance(robot, Robot):
        raise InvalidInput(f"`robot` must be a tfcontact Robot, got {type(robot).__name__}")
    return check_collisions(robot.model, robot.collision_model, t, q, obstacles,
                            contacts=tuple(c.frame for c in robot.contacts),
                            contact_radii=tuple(c.radius for c in robot.contacts),
                            options=options)


def check_collisions(
    model: pin.Model,
    collision_model: pin.GeometryModel,
    t: np.ndarray,
    q: np.ndarray,
    obstacles: Sequence[Obstacle],
    *,
    contacts: Sequence[str] = (),
    contact_radii: Sequence[float] = (),
    options: CollisionOptions | None = None,
) -> CollisionReport:
    """Distances of every collision body to the terrain and to each other along a motion.

    At every time t_k (and `options.substeps - 1` interpolated configurations per
    interval) the geometry placements are updated from q_k and coal computes the signed
    distances of the pairs (body, obstacle) and (body, body) (`pin.computeDistances`).

    Main arguments:
        model: the Pinocchio model of `q`.
        collision_model: its `GeometryModel` (`Robot.collision_model`); not modified.
        t: physical times [s], shape (S,), non-decreasing (an impact repeats a time).
        q: configurations, shape (S, model.nq).
        obstacles: the terrain, `Obstacle`s with distinct names (may be empty: then only
            the self-collisions are checked).

    Other arguments:
        contacts: the frames of the declared contacts: a body whose frame is one of them
            (or sits on the same joint at the same place, e.g. a URDF link and its fixed
            joint) may touch the terrain; other bodies touching it get a hint.
        contact_radii: the radii [m] of the contacts' spheres, in the order of `contacts`
            (or empty): a body on a contact's joint whose mesh also holds that sphere
            (finger_edu's lower link and its tip) may touch the terrain inside the sphere
            (its nearest point within radius + `touch_distance` of the frame); touching
            elsewhere gets the hint.
        options: a `CollisionOptions`; default `CollisionOptions()`.

    Returns:
        A `CollisionReport`.

    Raises:
        InvalidInput: arrays of the wrong shape or with non-finite values, times that
            decrease, obstacles that are not `Obstacle`s or share a name, contact frames or
            ignored bodies that are not in the model, radii that do not match `contacts`.
    """
    options = CollisionOptions() if options is None else options
    if not isinstance(options, CollisionOptions):
        raise InvalidInput(f"`options` must be a CollisionOptions, got {type(options).__name__}")
    if not isinstance(model, pin.Model) or not isinstance(collision_model, pin.GeometryModel):
        raise InvalidInput("`model` and `collision_model` must be a pinocchio Model and "
                           "GeometryModel (Robot.model, Robot.collision_model)")
    times, configs = _check_samples(t, q, model.nq)
    obstacles = tuple(obstacles)
    for o in obstacles:
        if not isinstance(o, Obstacle):
            raise InvalidInput(
                f"`obstacles` must hold Obstacle objects, got {type(o).__name__}; build them "
                "with halfspace_obstacle, box_obstacle or Obstacle(name, geometry, placement)"
            )
    names = [o.name for o in obstacles]
    if len(set(names)) != len(names):
        raise InvalidInput(f"`obstacles` share a name: {names}; give each a distinct name")
    if isinstance(contacts, str):
        raise InvalidInput(f"`contacts` must be a sequence of frame names, got the string "
                           f"{contacts!r}; write ({contacts!r},)")
    frames = [f.name for f in model.frames]
    for c in contacts:
        if not isinstance(c, str) or not model.existFrame(c):
            raise InvalidInput(
                f"`contacts` names frame {c!r}, which is not in the model; frames: "
                f"{', '.join(frames)}")

    radii = np.asarray(contact_radii, dtype=float).reshape(-1)
    if radii.size and (radii.size != len(contacts) or not np.all(np.isfinite(radii))
                       or np.any(radii < 0)):
        raise InvalidInput(f"`contact_radii` must be one radius >= 0 [m] per contact "
                           f"({len(contacts)}), got {tuple(contact_radii)!r}")

    geoms = list(collision_model.geometryObjects)
    links = [model.frames[g.parentFrame].name for g in geoms]
    known = set(links) | {g.name for g in geoms}
    for name in (*options.ignore_bodies, *(n for p in options.ignore_pairs for n in p)):
        if name not in known:
            raise InvalidInput(
                f"`CollisionOptions` names body `{name}`, which is not in the collision "
                f"model; bodies: {', '.join(g.name for g in geoms)} (links: "
                f"{', '.join(dict.fromkeys(links))})")
    ignored = set(options.ignore_bodies)
    bodies = [i for i, g in enumerate(geoms) if g.name not in ignored and links[i] not in ignored]
    contact_ids = [model.getFrameId(c) for c in contacts]
    is_contact = {i: any(_same_place(model, geoms[i].parentFrame, f) for f in contact_ids)
                  for i in bodies}
    # bodies on a contact's joint that may hold its sphere: (frame, radius) per body
    spheres: dict[int, list[tuple[int, float]]] = {}
    for i in bodies if radii.size else ():
        held = [(f, float(r)) for f, r in zip(contact_ids, radii, strict=True)
                if model.frames[f].parentJoint == geoms[i].parentJoint]
        if held and not is_contact[i]:
            spheres[i] = held

    # One geometry model holding the robot's bodies and the obstacles (on the universe).
    work, meshes = _working_model(geoms, options.meshes_as_convex)
    obstacle_ids = [work.addGeometryObject(pin.GeometryObject(
        f"obstacle:{o.name}", 0, 0, o.placement, o.geometry)) for o in obstacles]
    terrain_pairs = [(b, k) for b in bodies for k in range(len(obstacles))]
    for b, k in terrain_pairs:
        work.addCollisionPair(pin.CollisionPair(b, obstacle_ids[k]))
    self_pairs, skipped = _self_pairs(model, geoms, links, bodies, options)
    for a, b in self_pairs:
        work.addCollisionPair(pin.CollisionPair(a, b))

    times, configs = _substeps(model, times, configs, options.substeps)
    n_terrain = len(terrain_pairs)
    distances = np.empty((times.size, len(work.collisionPairs)))
    data = model.createData()
    # a sphere-holding body's first touch outside its contact's sphere: (sample, distance,
    # obstacle)
    touches_elsewhere: dict[int, tuple[int, float, str]] = {}
    body_column = {b: j for j, b in enumerate(bodies)}
    for k, qk in enumerate(configs):
        # A fresh GeometryData per configuration: Pinocchio's requests warm-start GJK from
        # the last call, and EPA's penetration depths then depend on the order of the
        # samples (measured on solo12's base in a step: -11 mm instead of -24 mm).
        geom_data = work.createData()
        pin.computeDistances(model, data, work, geom_data, qk)
        distances[k] = [r.min_distance for r in geom_data.distanceResults]
        if spheres:
            pin.updateFramePlacements(model, data)
            for p, (b, o) in enumerate(terrain_pairs):
                result = geom_data.distanceResults[p]
                if (b in spheres and b not in touches_elsewhere
                        and result.min_distance < options.touch_distance):
                    near = np.asarray(result.getNearestPoint1())  # on the body, world frame
                    if not any(np.linalg.norm(near - data.oMf[f].translation)
                               <= r + options.touch_distance for f, r in spheres[b]):
                        touches_elsewhere[b] = (k, float(result.min_distance),
                                                obstacles[o].name)
    per_obstacle = distances[:, :n_terrain].reshape(times.size, len(bodies), len(obstacles))
    pair_distance = distances[:, n_terrain:]
    if obstacles:
        nearest = np.argmin(per_obstacle, axis=2)
        terrain_distance = np.min(per_obstacle, axis=2)
    else:
        nearest = np.zeros((times.size, len(bodies)), dtype=int)
        terrain_distance = np.full((times.size, len(bodies)), np.inf)

    for b in spheres:
        # it touched, and only inside its contact's sphere: the declared contact touches
        touched = bool(np.any(terrain_distance[:, body_column[b]] < options.touch_distance))
        is_contact[b] = touched and b not in touches_elsewhere
    body_rows = []
    for j, i in enumerate(bodies):
        k = int(np.argmin(terrain_distance[:, j]))
        body_rows.append(BodyDistance(
            body=geoms[i].name, link=links[i], min_distance=float(terrain_distance[k, j]),
            time=float(times[k]), obstacle=obstacles[nearest[k, j]].name if obstacles else "",
            contact=is_contact[i]))
    tol = options.tolerance
    apart = _meshes_apart(model, collision_model, self_pairs, pair_distance, configs, tol,
                          {i for i, g in enumerate(geoms) if g.name in meshes})
    pair_rows = []
    for j, (a, b) in enumerate(self_pairs):
        k = int(np.argmin(pair_distance[:, j]))
        pair_rows.append(PairDistance(geoms[a].name, geoms[b].name,
                                      float(pair_distance[k, j]), float(times[k]),
                                      meshes_apart=j in apart))
    hints = []
    for i, b in zip(bodies, body_rows, strict=True):
        if b.contact or not b.min_distance < options.touch_distance:
            continue
        when, distance, obstacle = b.time, b.min_distance, b.obstacle
        if i in touches_elsewhere:  # where it first touches outside its contact's sphere
            k, distance, obstacle = touches_elsewhere[i]
            when = float(times[k])
        hints.append(f"body '{b.body}' touches obstacle '{obstacle}' at t = "
                     f"{when:.3f} s (distance {_mm(distance)} mm): declare a contact on it "
                     f"(ContactSpec on frame '{b.link}') or keep it above the terrain "
                     "(a task's [[bodies]])")
    hints = tuple(hints)
    offenders = [(b.min_distance, _through(b)) for b in body_rows] if obstacles else []
    offenders += [(p.min_distance, f"body '{p.body_a}' {_depth(p.min_distance)} body "
                   f"'{p.body_b}' at t = {p.time:.3f} s") for p in pair_rows
                  if not p.meshes_apart]
    passed = all(d >= -tol for d, _ in offenders)
    if not passed:
        status = CollisionStatus.PENETRATION
    elif hints:
        status = CollisionStatus.UNDECLARED_CONTACT
    else:
        status = CollisionStatus.CLEAR
    worst = min(offenders, key=lambda o: o[0])[1] if offenders else "no bodies checked"
    notes = []
    if not geoms:
        notes.append("the collision model has no bodies: nothing checked")
    if not obstacles:
        notes.append("no obstacles: the terrain was not checked")
    if meshes:
        notes.append(f"{len(meshes)} mesh bodies checked as their convex hulls: their "
                     "distances are lower bounds")
    overlapping = [p for p in pair_rows if p.meshes_apart]
    if overlapping:
        notes.append("convex hulls overlapping while their meshes do not intersect (not "
                     "collisions): " + ", ".join(f"'{p.body_a}' and '{p.body_b}' (hulls "
                                                 f"{-1e3 * p.min_distance:.1f} mm deep)"
                                                 for p in overlapping))
    if options.substeps == 1:
        notes.append("checked at the samples only (a body may pass through a thin obstacle "
                     "between two samples: CollisionOptions(substeps=k))")
    return CollisionReport(
        status=status, passed=passed, worst=worst, hints=hints, bodies=tuple(body_rows),
        pairs=tuple(pair_rows), times=times, terrain_distance=terrain_distance,
        pair_distance=pair_distance, skipped_pairs=tuple(skipped), tolerance=tol,
        notes=tuple(notes))


def _check_samples(t: Any, q: Any, nq: int) -> tuple[np.ndarray, np.ndarray]:
    times = np.asarray(t, dtype=float)
    configs = np.asarray(q, dtype=float)
    if times.ndim != 1 or times.size < 1:
        raise InvalidInput(f"`t` must have shape (S,) with S >= 1, got shape {times.shape}")
    if configs.shape != (times.size, nq):
        raise InvalidInput(
            f"`q` must have shape (S, nq) = ({times.size}, {nq}), got shape {configs.shape}")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(configs))):
        raise InvalidInput("`t` and `q` must be finite (NaN or inf found)")
    if np.any(np.diff(times) < 0):
        k = int(np.flatnonzero(np.diff(times) < 0)[0])
        raise InvalidInput(f"`t` must be non-decreasing, got t[{k}] = {times[k]} > "
                           f"t[{k + 1}] = {times[k + 1]}")
    return times, configs


def _working_model(geoms: list, meshes_as_convex: bool) -> tuple[pin.GeometryModel, list[str]]:
    """A new geometry model of the bodies (same indices), meshes replaced by their convex
    hulls if asked; the robot's own model and shapes are left untouched."""
    work, meshes = pin.GeometryModel(), []
    for g in geoms:
        shape = g.geometry
        if meshes_as_convex and isinstance(shape, coal.BVHModelBase):
            shape = shape.clone()
            shape.buildConvexRepresentation(False)
            shape = shape.convex
            meshes.append(g.name)
        work.addGeometryObject(pin.GeometryObject(g.name, g.parentJoint, g.parentFrame,
                                                  g.placement, shape))
    return work, meshes


def _meshes_apart(model: pin.Model, collision_model: pin.GeometryModel,
                  pairs: list[tuple[int, int]], distances: np.ndarray, configs: np.ndarray,
                  tol: float, hulls: set[int]) -> set[int]:
    """The indices of the self-collision `pairs` with a body checked as its convex hull
    (`hulls`) whose hulls overlap by more than `tol` somewhere and whose own shapes (coal's
    mesh collision test, exact but unsigned) intersect at none of those samples: a hull
    contains its mesh, so an overlap of hulls is a candidate, the meshes decide.
    (solo12's base hull reaches over its upper legs near the hips: 1.9 mm in a jump whose
    meshes stay apart.) A body wholly inside a closed mesh counts as intersecting it.
    """
    candidates = [j for j, (a, b) in enumerate(pairs)
                  if (a in hulls or b in hulls) and np.min(distances[:, j]) < -tol]
    if not candidates:
        return set()
    data, geom_data = model.createData(), collision_model.createData()
    request = coal.CollisionRequest()
    shapes = collision_model.geometryObjects
    apart = set(candidates)
    corners: dict[int, np.ndarray | None] = {}

    def triangles(i: int) -> np.ndarray | None:
        if i not in corners:
            corners[i] = _triangles(shapes[i].geometry)
        return corners[i]

    for k in np.unique(np.nonzero(distances[:, candidates] < -tol)[0]):
        pin.updateGeometryPlacements(model, data, collision_model, geom_data, configs[k])
        for j in [j for j in apart if distances[k, j] < -tol]:
            a, b = pairs[j]
            result = coal.CollisionResult()
            placement_a, placement_b = geom_data.oMg[a], geom_data.oMg[b]
            coal.collide(shapes[a].geometry, coal.Transform3s(placement_a.rotation,
                                                              placement_a.translation),
                         shapes[b].geometry, coal.Transform3s(placement_b.rotation,
                                                              placement_b.translation),
                         request, result)
            # coal's mesh test sees the surfaces: a body wholly inside a mesh is no
            # surface crossing, so one point of each is tested inside the other
            if result.isCollision() or _inside(triangles(a), placement_a,
                                               _a_point(shapes[b].geometry, placement_b)) \
                    or _inside(triangles(b), placement_b,
                               _a_point(shapes[a].geometry, placement_a)):
                apart.discard(j)
    return apart


RAY = np.array([0.5773, 0.5774, 0.5775])
"""The direction of `_inside`'s ray: skewed, so that it does not run along an axis-aligned
mesh's edges."""


def _a_point(shape: object, placement: pin.SE3) -> np.ndarray:
    """A point of the body in the world: a mesh's first vertex, else its frame's origin
    (inside a primitive: sphere, box, cylinder, ...)."""
    if isinstance(shape, coal.BVHModelBase) and shape.num_vertices:
        return placement.act(np.asarray(shape.vertices(), dtype=float)[0])
    return np.asarray(placement.translation, dtype=float)


def _triangles(shape: object) -> np.ndarray | None:
    """A mesh's triangles as their corners (n, 3, 3) in its frame; None for other shapes."""
    if not isinstance(shape, coal.BVHModelBase) or not shape.num_tris:
        return None
    vertices = np.asarray(shape.vertices(), dtype=float)
    corners = np.array([[t[i] for i in range(3)]
                        for t in map(shape.tri_indices, range(shape.num_tris))])
    return vertices[corners]


def _inside(triangles: np.ndarray | None, placement: pin.SE3, point: np.ndarray) -> bool:
    """Whether the world `point` lies inside the closed mesh of `triangles` (`_triangles`;
    None: not a mesh, False) at `placement`: the parity of a ray's crossings of its
    triangles (Moller-Trumbore)."""
    if triangles is None:
        return False
    local = placement.rotation.T @ (np.asarray(point, dtype=float) - placement.translation)
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    p = np.cross(RAY, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-18
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = local - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ RAY) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return bool(np.count_nonzero(hits) % 2)


def _same_place(model: pin.Model, frame_a: int, frame_b: int) -> bool:
    """Two frames are one: the same frame, or on the same joint at the same placement."""
    if frame_a == frame_b:
        return True
    fa, fb = model.frames[frame_a], model.frames[frame_b]
    return fa.parentJoint == fb.parentJoint and fa.placement.isApprox(fb.placement, 1e-9)


def _self_pairs(model: pin.Model, geoms: list, links: list[str], bodies: list[int],
                options: CollisionOptions):
    pairs, skipped = [], []
    if not options.self_collision:
        return pairs, skipped
    ignored = {frozenset(p) for p in options.ignore_pairs}
    for ia, a in enumerate(bodies):
        for b in bodies[ia + 1:]:
            ja, jb = geoms[a].parentJoint, geoms[b].parentJoint
            names = (geoms[a].name, geoms[b].name)
            if ja == jb:
                skipped.append((*names, "same joint"))
            elif options.skip_adjacent and (model.parents[ja] == jb or model.parents[jb] == ja):
                skipped.append((*names, "adjacent joints"))
            elif any(frozenset((x, y)) in ignored for x in (names[0], links[a])
                     for y in (names[1], links[b])):
                skipped.append((*names, "ignore_pairs"))
            else:
                pairs.append((a, b))
    return pairs, skipped


def _substeps(model: pin.Model, times: np.ndarray, configs: np.ndarray,
              substeps: int) -> tuple[np.ndarray, np.ndarray]:
    if substeps == 1 or times.size < 2:
        return times, configs
    out_t, out_q = [times[0]], [configs[0]]
    for k in range(times.size - 1):
        for j in range(1, substeps + 1):
            s = j / substeps
            out_t.append(times[k] + s * (times[k + 1] - times[k]))
            out_q.append(pin.interpolate(model, configs[k], configs[k + 1], s))
    return np.asarray(out_t), np.asarray(out_q)


def _mm(d: float) -> str:
    return f"{1e3 * d:+.1f}"


def _depth(d: float) -> str:
    return f"{-1e3 * d:.1f} mm into" if d < 0 else f"{1e3 * d:.1f} mm from"


def _through(b: BodyDistance) -> str:
    where = "through" if b.min_distance < 0 else "from"
    return (f"body '{b.body}' (link '{b.link}') {abs(1e3 * b.min_distance):.1f} mm {where} "
            f"obstacle '{b.obstacle}' at t = {b.time:.3f} s")
