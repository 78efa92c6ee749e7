"""The ground of a trajectory's scene, for drawing: boxes for meshcat, sections for figures.

A sidecar's `scene["terrain"]` is either flat ground, `{"type": "flat", "height": h,
"normal": n}` (the half-space n . p >= h of `tfcontact.robot.Ground`; default h = 0,
n = z), or a terrain of primitives, `{"kind": "terrain", "primitives": [...]}`
(`tfcontact.robot.Terrain.to_dict()`: planes with any height and slope, boxes (steps,
platforms), holes with an optional floor). `scene_terrain` reads both as a `Terrain`, so
the replay and the figures draw one kind of object:

* `terrain_boxes`: boxes (centre, lengths, rotation) that draw the terrain in 3-D over a
  square around the motion: each plane as a slab (tilted along its normal), cut around
  the holes' footprints so that a hole is a gap in the ground, each hole's floor, and
  each box down to the lowest plane. Rounded edges are drawn sharp.
* `terrain_section`: the height of the highest support along x at one y, NaN where there
  is none (inside a bottomless hole, beside a box without a plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.robot import Plane, Terrain

#: Thickness of a drawn plane without holes [m] (the replay's ground slab, as before).
SLAB = 0.02
#: Depth drawn below a bottomless hole's rim [m]: the ground around it is a slab this thick.
BOTTOMLESS_DEPTH = 0.2
#: Depth drawn below a box that stands on no plane [m].
FREE_BOX_DEPTH = 0.2


@dataclass(frozen=True)
class DrawnBox:
    """One box of the drawn terrain.

    Attributes:
        center: (x, y, z) [m] in the world frame.
        lengths: (lx, ly, lz) [m] along the box's own axes.
        rotation: 3 x 3 world rotation of the box's axes (identity unless the plane is
            sloped: then the box's z axis is the plane's normal).
        role: "ground" (a plane), "box" (a step or platform) or "floor" (a hole's bottom).
    """

    center: tuple[float, float, float]
    lengths: tuple[float, float, float]
    rotation: np.ndarray
    role: str


def scene_terrain(scene: dict[str, Any]) -> Terrain | None:
    """The scene's terrain as a `Terrain` (module docstring); flat at 0 when absent; None
    for `{"type": "none"}` (a scene of `scene["boxes"]` only, e.g. a ball in a box).

    Raises:
        InvalidInput: an unknown terrain description, or a flat ground facing down or
            sideways (n_z <= 0).
    """
    terrain = scene.get("terrain", {"type": "flat", "height": 0.0})
    if not isinstance(terrain, dict):
        raise InvalidInput(f"`scene['terrain']` must be an object, got {terrain!r}")
    if terrain.get("kind") == "terrain":
        return Terrain.from_dict(terrain)
    kind = terrain.get("type", "flat")
    if kind == "none":
        return None
    if kind not in ("flat", "plane"):
        raise InvalidInput(
            f"`scene['terrain']` of type {kind!r} cannot be drawn: give flat ground "
            "{\"type\": \"flat\", \"height\", \"normal\"}, {\"type\": \"none\"} or a "
            "Terrain.to_dict()")
    n = np.asarray(terrain.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    if n.shape != (3,) or not np.all(np.isfinite(n)) or not n[2] > 0:
        raise InvalidInput(f"flat ground needs a finite normal with n_z > 0, got {n.tolist()}")
    n = n / np.linalg.norm(n)
    # the Ground's plane n . p = h crosses the z axis at h / n_z (a Plane's height)
    return Terrain((Plane(height=float(terrain.get("height", 0.0)) / float(n[2]),
                          normal=tuple(n)),))


def _rotation_to(normal: tuple[float, float, float]) -> np.ndarray:
    """A rotation whose third column is `normal` and whose first lies in the x-z plane
    when it can (so a slope along x tilts the slab about y only)."""
    n = np.asarray(normal, dtype=float)
    if n[0] == 0.0 and n[1] == 0.0:
        return np.eye(3)
    x = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(x) < 1e-9:
        x = np.array([0.0, 1.0, 0.0]) - n[1] * n
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


def _clip(lo: float, hi: float, a: float, b: float) -> tuple[float, float] | None:
    lo, hi = max(lo, a), min(hi, b)
    return (lo, hi) if hi > lo else None


def _free_cells(x: tuple[float, float], y: tuple[float, float],
                holes: list[tuple[tuple[float, float], tuple[float, float]]]
                ) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Rectangles covering the rectangle x * y minus the holes' rectangles (strips along y
    in each x-slab between the holes' x-edges)."""
    xs = sorted({x[0], x[1], *(v for hx, _ in holes for v in hx if x[0] < v < x[1])})
    cells = []
    for a, b in zip(xs[:-1], xs[1:], strict=True):
        mid = (a + b) / 2
        cuts = sorted(hy for hx, hy in holes if hx[0] < mid < hx[1])
        lo = y[0]
        for c, d in cuts:
            if c > lo:
                cells.append(((a, b), (lo, min(c, y[1]))))
            lo = max(lo, d)
        if lo < y[1]:
            cells.append(((a, b), (lo, y[1])))
    return [(cx, cy) for cx, cy in cells if cx[1] > cx[0] and cy[1] > cy[0]]


def terrain_boxes(terrain: Terrain, center_xy: tuple[float, float] | np.ndarray,
                  size: float) -> list[DrawnBox]:
    """Boxes drawing `terrain` over the square of side `size` [m] centred at `center_xy`.

    A horizontal plane without holes is one slab of thickness `SLAB` whose top is the
    plane (the replay's ground as it always was); a sloped plane the same slab tilted;
    holes cut the slabs of the (horizontal) planes, which then reach down to the lowest
    hole floor (or `BOTTOMLESS_DEPTH`) so the pit's walls show, and each floor is a slab.
    Boxes reach down to the lowest plane below their top. Infinite ranges are cut to the
    square; primitives outside it are left out.
    """
    if not isinstance(terrain, Terrain):
        raise InvalidInput(f"`terrain` must be a Terrain, got {type(terrain).__name__}")
    if not (math.isfinite(size) and size > 0):
        raise InvalidInput(f"`size` must be a positive length [m], got {size!r}")
    cx, cy = float(center_xy[0]), float(center_xy[1])
    square_x, square_y = (cx - size / 2, cx + size / 2), (cy - size / 2, cy + size / 2)
    out: list[DrawnBox] = []
    holes = []
    for hole in terrain.holes:
        hx = _clip(*hole.x, *square_x)
        hy = _clip(*(hole.y or (-math.inf, math.inf)), *square_y)
        if hx is not None and hy is not None:
            holes.append((hole, hx, hy))
    floors = [h.floor for h, _, _ in holes if h.floor is not None]
    eye = np.eye(3)
    for plane in terrain.planes:
        if not holes:
            z = plane.height_at(cx, cy)
            rotation = _rotation_to(plane.normal)
            top = np.array([cx, cy, z])
            # the slab's top face through (cx, cy, z): its centre half a slab below,
            # along the normal; wide enough to cover the square once tilted
            stretch = 1.0 / max(float(plane.normal[2]), 0.2)
            center = top - rotation[:, 2] * SLAB / 2
            out.append(DrawnBox(tuple(center), (size * stretch, size * stretch, SLAB),
                                rotation, "ground"))
            continue
        h = plane.height
        bottomless = any(hole.floor is None for hole, _, _ in holes)
        bottom = min([*floors, h - BOTTOMLESS_DEPTH if bottomless else h]) - SLAB
        for (x0, x1), (y0, y1) in _free_cells(square_x, square_y,
                                              [(hx, hy) for _, hx, hy in holes]):
            out.append(DrawnBox(((x0 + x1) / 2, (y0 + y1) / 2, (h + bottom) / 2),
                                (x1 - x0, y1 - y0, h - bottom), eye, "ground"))
    for hole, (x0, x1), (y0, y1) in holes:
        if hole.floor is not None:
            out.append(DrawnBox(((x0 + x1) / 2, (y0 + y1) / 2, hole.floor - SLAB / 2),
                                (x1 - x0, y1 - y0, SLAB), eye, "floor"))
    for box in terrain.boxes:
        bx = _clip(*box.x, *square_x)
        by = _clip(*(box.y or (-math.inf, math.inf)), *square_y)
        if bx is None or by is None:
            continue
        below = [p.height_at((bx[0] + bx[1]) / 2, (by[0] + by[1]) / 2)
                 for p in terrain.planes]
        below = [z for z in below if z < box.top]
        bottom = min(below) - SLAB if below else box.top - FREE_BOX_DEPTH
        out.append(DrawnBox(((bx[0] + bx[1]) / 2, (by[0] + by[1]) / 2, (box.top + bottom) / 2),
                            (bx[1] - bx[0], by[1] - by[0], box.top - bottom), eye, "box"))
    return out


def terrain_section(terrain: Terrain, x: np.ndarray, y: float = 0.0) -> np.ndarray:
    """The height [m] of the terrain's highest support at each x (and this y), NaN where
    there is none; edges sharp (`Terrain.height_at`)."""
    z = np.array([terrain.height_at(float(xi), float(y)) for xi in np.ravel(x)])
    z[~np.isfinite(z)] = np.nan
    return z.reshape(np.shape(x))


def section_grid(terrain: Terrain, lo: float, hi: float, n: int = 400) -> np.ndarray:
    """x samples in [lo, hi] [m] with points just beside every box and hole edge, so that a
    section drawn through them has vertical steps."""
    edges = [v for p in (*terrain.boxes, *terrain.holes) for v in p.x if lo < v < hi]
    eps = 1e-9 * max(1.0, hi - lo)
    extra = [v + s for v in edges for s in (-eps, eps)]
    return np.unique(np.concatenate([np.linspace(lo, hi, n), extra]))


def surface_normals(terrain: Terrain, points: np.ndarray) -> np.ndarray:
    """The terrain's unit normal [-] at the point nearest each of `points` (k, 3) [m]."""
    import casadi as ca

    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if points.shape[0] == 0:
        return np.zeros((0, 3))
    if len(terrain.planes) == 1 and not terrain.boxes and not terrain.holes:
        return np.tile(np.asarray(terrain.planes[0].normal), (points.shape[0], 1))
    p = ca.SX.sym("p", 3)
    normal = ca.Function("normal", [p], [terrain.normal(p)])
    return np.asarray(normal.map(points.shape[0])(points.T)).T


def surface_tangents(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents (t1, t2) of unit normals (k, 3): t1 the world x axis projected on the
    surface (y where |n_x| >= 0.9), t2 = n x t1, as `tfcontact.robot.Ground`."""
    n = np.asarray(normal, dtype=float).reshape(-1, 3)
    seed = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = seed - n * np.sum(n * seed, axis=1, keepdims=True)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)
