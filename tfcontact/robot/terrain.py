"""Terrain made of primitives: sloped planes, boxes (steps, platforms), holes (DESIGN.md 4.10).

Every primitive is a *solid* (the ground side), and a contact sphere (centre p, radius r)
has the gap g(p) = d(p) - r, with d the signed distance from p to the solid [m]
(> 0 apart, < 0 penetrating). The terrain is the union of its solids minus its holes.

What is exact and what is smoothed:

* `Plane` (normal n, n_z > 0, through (0, 0, height)): d = n . p - n_z height. Exact.
* `Box` (x-range, optional y-range, top; the solid reaches down without end, so a step,
  a platform or one stair): the box whose edges are rounded with radius `rounding` (the
  Minkowski sum of the box shrunk by rho with a ball of radius rho). Its faces are exact,
  its edges quarter cylinders (corners spheres) of radius rho. d is the exact signed
  distance to this rounded box; outside its inner (shrunk) box d is C1, so the gap is C1
  wherever the penetration is below r + rho: wherever a contact can be. (Even at
  rho = 0 the sphere radius rounds: the gap is C1 for penetrations below r.)
* `Hole` (x-range, optional y-range, in the horizontal planes of the terrain): the plane
  without support over the hole, optionally with a `floor`. The plane minus one hole is
  the union of half-infinite boxes around the hole (two planar, four in 3D) whose edges
  at the rim are rounded, plus the floor; its distance is their minimum (exact). Several
  holes cut the same plane: the plane minus them all is the *intersection* of the
  single-hole solids, whose distance is the maximum of theirs; this is exact because
  the holes are apart (checked on construction: more than twice the rim rounding), so
  the nearest support to a point near one hole is never in another.
* The union of solids: its distance is the minimum of the solids' distances (exact, and
  C0 where two solids are equally near: a sphere in a concave corner such as the foot
  of a step touches both). With `Terrain.smoothing` k > 0 the minimum is replaced by
  the quadratic smooth minimum
      smin_k(a, b) = min(a, b)                                 if |a - b| >= k,
                   = (a + b)/2 - k/4 - (a - b)^2 / (4 k)        otherwise,
  which is C1, exact where the two gaps differ by k or more, and at most k/4 below the
  minimum elsewhere (the contact is met up to k/4 early: conservative). Several solids
  are combined pairwise, in order (errors add: at most (n - 1) k / 4).

Only what the scene needs: `Terrain.relevant_to(region, margin=...)` keeps the primitives
a contact whose centre stays in `region` can reach, so that the gap of a contact that
never comes near a step does not carry the step.

The contact normal is grad_p g (a unit vector wherever the distance is exact; the
smoothed minimum blends two unit vectors), pointing from the nearest point of the solid
towards p.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import IncompatibleOptions, InvalidInput

_INF = math.inf


def _number(value: object, name: str, *, finite: bool = True) -> float:
    """`value` as a float, or `InvalidInput` naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidInput(f"`{name}` must be a number, got {value!r}")
    value = float(value)
    if math.isnan(value) or (finite and not math.isfinite(value)):
        raise InvalidInput(f"`{name}` must be a finite number, got {value!r}")
    return value


def _friction(value: object) -> float:
    mu = _number(value, "friction")
    if mu < 0:
        raise InvalidInput(
            f"`friction` must be >= 0 (Coulomb coefficient [-]), got {mu}; 0 is frictionless"
        )
    return mu


def _rounding(value: object) -> float:
    rho = _number(value, "rounding")
    if rho < 0:
        raise InvalidInput(f"`rounding` must be >= 0 (edge radius [m]), got {rho}")
    return rho


def _interval(value: object, name: str, rounding: float) -> tuple[float, float]:
    """(lo, hi) with lo < hi (either may be infinite) and room for two rounded edges."""
    try:
        lo, hi = value  # type: ignore[misc]
    except (TypeError, ValueError) as err:
        raise InvalidInput(f"`{name}` must be a pair (lo, hi) [m], got {value!r}") from err
    lo, hi = _number(lo, f"{name}[0]", finite=False), _number(hi, f"{name}[1]", finite=False)
    if not lo < hi:
        raise InvalidInput(f"`{name}` must have lo < hi, got ({lo}, {hi})")
    if math.isfinite(hi - lo) and hi - lo <= 2 * rounding:
        raise InvalidInput(
            f"`{name}` = ({lo}, {hi}) is {hi - lo} m wide, not more than twice the rounding "
            f"{rounding} m; widen it or lower `rounding`"
        )
    return lo, hi


def _json_range(bounds: tuple[float, float]) -> list[float | None]:
    """(lo, hi) for JSON: an infinite end is written null (JSON has no infinity)."""
    return [b if math.isfinite(b) else None for b in bounds]


def _range_from_json(bounds: Any) -> Any:
    if isinstance(bounds, list | tuple) and len(bounds) == 2:
        lo, hi = bounds
        return (-_INF if lo is None else lo, _INF if hi is None else hi)
    return bounds  # the primitive's validation names what is wrong


def _casadi(point: object) -> Any:
    """A 3-vector of casadi type (SX, MX, DM); numbers and arrays become DM."""
    if isinstance(point, ca.SX | ca.MX | ca.DM):
        out = point
    else:
        out = ca.DM(np.asarray(point, dtype=float).reshape(-1, 1))
    if out.shape != (3, 1):
        raise InvalidInput(f"`point` must be a 3-vector (x, y, z) [m], got shape {out.shape}")
    return out


def _safe_norm(squares: Any) -> Any:
    """sqrt(s) with a finite derivative at s = 0 (where the value is 0): the distance to
    the inner box is 0 inside it, and a plain sqrt would give NaN derivatives there."""
    positive = squares > 0
    return ca.if_else(positive, ca.sqrt(ca.if_else(positive, squares, 1.0)), 0.0)


def smooth_min(a: Any, b: Any, k: float) -> Any:
    """The quadratic smooth minimum of a and b with smoothing length k [m] (module
    docstring); the plain minimum when k = 0. C1, exact where |a - b| >= k."""
    if k == 0.0:
        return ca.fmin(a, b)
    d = a - b
    # the polynomial branch has no |.| or min, so the derivative is exact at a = b
    return ca.if_else(ca.fabs(d) < k, 0.5 * (a + b) - 0.25 * k - d * d / (4.0 * k),
                      ca.fmin(a, b))


@dataclass(frozen=True)
class Region:
    """An axis-aligned box where the contact sphere centres stay during a task [m].

    Args:
        lower, upper: (x, y, z) bounds; infinite entries leave an axis open (a planar
            task: y = (-inf, inf)).
    """

    lower: tuple[float, float, float] = (-_INF, -_INF, -_INF)
    upper: tuple[float, float, float] = (_INF, _INF, _INF)

    def __post_init__(self) -> None:
        bounds = []
        for name in ("lower", "upper"):
            value = getattr(self, name)
            if isinstance(value, str) or len(value) != 3:
                raise InvalidInput(f"`{name}` must be (x, y, z) [m], got {value!r}")
            bounds.append(tuple(_number(v, f"{name}[{i}]", finite=False)
                                for i, v in enumerate(value)))
        for i, (lo, hi) in enumerate(zip(*bounds, strict=True)):
            if lo > hi:
                raise InvalidInput(
                    f"`lower[{i}]` = {lo} is above `upper[{i}]` = {hi}; swap them"
                )
        object.__setattr__(self, "lower", bounds[0])
        object.__setattr__(self, "upper", bounds[1])


def _box_distance(lo_a: Sequence[float], hi_a: Sequence[float],
                  lo_b: Sequence[float], hi_b: Sequence[float]) -> float:
    """Euclidean distance between two axis-aligned boxes (0 if they meet); infinite
    bounds allowed."""
    total = 0.0
    for la, ha, lb, hb in zip(lo_a, hi_a, lo_b, hi_b, strict=True):
        gap = max(lb - ha, la - hb, 0.0)
        if math.isinf(gap):
            return _INF
        total += gap * gap
    return math.sqrt(total)


@dataclass(frozen=True)
class Plane:
    """The solid below a plane through (0, 0, `height`) with upward unit `normal`.

    Args:
        height: the plane's z at x = y = 0 [m].
        normal: pointing into the free space, n_z > 0; normalised on construction.
            `Plane.sloped` builds it from slopes.
        friction: Coulomb coefficient on the plane [-].

    Raises:
        InvalidInput: a non-finite height, a zero normal or one with n_z <= 0 (walls are
            the sides of a `Box`), a negative friction.
    """

    height: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    friction: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "height", _number(self.height, "height"))
        try:
            n = np.asarray(self.normal, dtype=float)
        except (TypeError, ValueError) as err:
            raise InvalidInput(f"`normal` must be 3 numbers, got {self.normal!r}") from err
        if n.shape != (3,) or not np.all(np.isfinite(n)) or not n[2] > 0:
            raise InvalidInput(
                f"`normal` must be a finite 3-vector with n_z > 0 (a plane faces up), got "
                f"{self.normal!r}; e.g. (0, 0, 1) for flat ground, a Box for a wall"
            )
        norm = float(np.linalg.norm(n))
        if abs(norm - 1.0) > 1e-15:  # a unit normal read back from a file stays bit-equal
            n = n / norm
        object.__setattr__(self, "normal", tuple(float(x) + 0.0 for x in n))  # no -0.0
        object.__setattr__(self, "friction", _friction(self.friction))

    @classmethod
    def sloped(cls, height: float = 0.0, slope: tuple[float, float] = (0.0, 0.0), *,
               friction: float = 0.0) -> Plane:
        """The plane z = height + s_x x + s_y y (slope = (s_x, s_y) = (dz/dx, dz/dy) [-]).

        Raises:
            InvalidInput: a slope that is not two finite numbers.
        """
        if isinstance(slope, str) or len(slope) != 2:
            raise InvalidInput(f"`slope` must be (dz/dx, dz/dy), got {slope!r}")
        sx, sy = (_number(s, f"slope[{i}]") for i, s in enumerate(slope))
        return cls(height=height, normal=(-sx, -sy, 1.0), friction=friction)

    @property
    def horizontal(self) -> bool:
        return self.normal[0] == 0.0 and self.normal[1] == 0.0

    def distance(self, point: Any) -> Any:
        """Signed distance of `point` (casadi 3-vector) to the solid [m]."""
        n = self.normal
        return n[0] * point[0] + n[1] * point[1] + n[2] * (point[2] - self.height)

    def height_at(self, x: float, y: float) -> float:
        n = self.normal
        return self.height - (n[0] * x + n[1] * y) / n[2]

    def reaches(self, region: Region, margin: float) -> bool:
        # the distance is linear: its minimum over the region is at a corner
        low = -self.normal[2] * self.height
        for n_a, lo, hi in zip(self.normal, region.lower, region.upper, strict=True):
            if n_a != 0.0:
                low += n_a * (lo if n_a > 0 else hi)
        return low <= margin

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "plane", "height": self.height, "normal": list(self.normal),
                "friction": self.friction}


@dataclass(frozen=True)
class Box:
    """A step or platform: the solid {x in `x`, y in `y`, z <= `top`} with rounded edges.

    Args:
        x: (x_min, x_max) [m]; either end may be infinite (a step that continues).
        top: the height of the top face [m].
        y: (y_min, y_max) [m], or None for no bound (a planar scene's step).
        rounding: radius rho of the rounded edges [m] (module docstring); every bounded
            extent must be wider than 2 rho.
        friction: Coulomb coefficient on the box [-].

    Raises:
        InvalidInput: a range with lo >= hi or not wider than 2 rho, a non-finite top, a
            negative rounding or friction.
    """

    x: tuple[float, float]
    top: float
    y: tuple[float, float] | None = None
    rounding: float = 0.0
    friction: float = 0.0

    def __post_init__(self) -> None:
        rho = _rounding(self.rounding)
        object.__setattr__(self, "rounding", rho)
        object.__setattr__(self, "x", _interval(self.x, "x", rho))
        if self.y is not None:
            object.__setattr__(self, "y", _interval(self.y, "y", rho))
        object.__setattr__(self, "top", _number(self.top, "top"))
        object.__setattr__(self, "friction", _friction(self.friction))

    @property
    def _y(self) -> tuple[float, float]:
        return (-_INF, _INF) if self.y is None else self.y

    def distance(self, point: Any) -> Any:
        """Signed distance of `point` to the rounded box [m]: the distance to the box
        shrunk by rho, minus rho."""
        rho = self.rounding
        # s_a > 0 outside the inner box along axis a; only bounded sides count
        sides = []
        for axis, (lo, hi) in ((0, self.x), (1, self._y)):
            terms = []
            if math.isfinite(lo):
                terms.append(lo + rho - point[axis])
            if math.isfinite(hi):
                terms.append(point[axis] - (hi - rho))
            if terms:
                sides.append(terms[0] if len(terms) == 1 else ca.fmax(*terms))
        sides.append(point[2] - (self.top - rho))
        outside = _safe_norm(sum(ca.fmax(s, 0.0) ** 2 for s in sides))
        inside = sides[0]
        for s in sides[1:]:
            inside = ca.fmax(inside, s)
        return outside + ca.fmin(inside, 0.0) - rho

    def covers(self, x: float, y: float) -> bool:
        ylo, yhi = self._y
        return self.x[0] <= x <= self.x[1] and ylo <= y <= yhi

    def height_at(self, x: float, y: float) -> float:
        return self.top if self.covers(x, y) else -_INF

    def reaches(self, region: Region, margin: float) -> bool:
        lo = (self.x[0], self._y[0], -_INF)
        hi = (self.x[1], self._y[1], self.top)
        return _box_distance(lo, hi, region.lower, region.upper) <= margin

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "box", "x": _json_range(self.x), "top": self.top,
                "y": None if self.y is None else _json_range(self.y), "rounding": self.rounding,
                "friction": self.friction}


@dataclass(frozen=True)
class Hole:
    """A region without support in the horizontal planes of the terrain.

    Args:
        x: (x_min, x_max) of the footprint [m], finite.
        y: (y_min, y_max) [m], finite, or None for no bound (a planar scene's ditch).
        rounding: radius of the rounded rim [m].
        floor: height of the hole's bottom [m] (below the plane), or None: bottomless.
        friction: Coulomb coefficient on the floor [-]; 0 for a bottomless hole.

    Raises:
        InvalidInput: an infinite or empty footprint, a negative rounding or friction.
        IncompatibleOptions: a friction on a bottomless hole.
    """

    x: tuple[float, float]
    y: tuple[float, float] | None = None
    rounding: float = 0.0
    floor: float | None = None
    friction: float = 0.0

    def __post_init__(self) -> None:
        rho = _rounding(self.rounding)
        object.__setattr__(self, "rounding", rho)
        for name in ("x", "y"):
            value = getattr(self, name)
            if value is None and name == "y":
                continue
            lo, hi = _interval(value, name, 0.0)
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise InvalidInput(
                    f"`{name}` of a hole must be finite, got ({lo}, {hi}); a plane that "
                    "ends is a `Box` with an infinite side"
                )
            object.__setattr__(self, name, (lo, hi))
        if self.floor is not None:
            object.__setattr__(self, "floor", _number(self.floor, "floor"))
        object.__setattr__(self, "friction", _friction(self.friction))
        if self.floor is None and self.friction != 0.0:
            raise IncompatibleOptions(
                f"a bottomless hole has no surface, but `friction` = {self.friction}; give "
                "a `floor` height or leave friction at 0"
            )

    @property
    def _y(self) -> tuple[float, float]:
        return (-_INF, _INF) if self.y is None else self.y

    def covers(self, x: float, y: float) -> bool:
        ylo, yhi = self._y
        return self.x[0] < x < self.x[1] and ylo < y < yhi

    def cut(self, plane: Plane, smoothing: float) -> Any:
        """A function point -> signed distance to `plane` minus this hole: the minimum
        over the half-infinite boxes around the hole (rims rounded) and the floor."""
        h, rho = plane.height, self.rounding
        sides = [Box(x=(-_INF, self.x[0]), top=h, rounding=rho),
                 Box(x=(self.x[1], _INF), top=h, rounding=rho)]
        if self.y is not None:
            sides += [Box(x=(-_INF, _INF), y=(-_INF, self.y[0]), top=h, rounding=rho),
                      Box(x=(-_INF, _INF), y=(self.y[1], _INF), top=h, rounding=rho)]
        solids: list[Any] = sides
        if self.floor is not None:
            solids = [*sides, Plane(height=self.floor)]

        def distance(point: Any) -> Any:
            out = solids[0].distance(point)
            for solid in solids[1:]:
                out = smooth_min(out, solid.distance(point), smoothing)
            return out

        return distance

    def reaches(self, region: Region, margin: float) -> bool:
        lo = (self.x[0] - self.rounding, self._y[0] - self.rounding, -_INF)
        hi = (self.x[1] + self.rounding, self._y[1] + self.rounding, _INF)
        return _box_distance(lo, hi, region.lower, region.upper) <= margin

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "hole", "x": list(self.x),
                "y": None if self.y is None else list(self.y), "rounding": self.rounding,
                "floor": self.floor, "friction": self.friction}


Primitive = Plane | Box | Hole
_KINDS: dict[str, type] = {"plane": Plane, "box": Box, "hole": Hole}


@dataclass(frozen=True)
class Terrain:
    """A union of solids (`Plane`, `Box`) minus `Hole`s in its horizontal planes.

    Args:
        primitives: at least one `Plane` or `Box`; holes need a horizontal plane and cut
            every plane of the terrain.
        smoothing: length k of the smooth minimum that joins the solids [m] (module
            docstring); 0: the exact minimum (C0 in concave corners).

    Raises:
        InvalidInput: an empty tuple, an entry that is not a primitive, a negative
            smoothing, holes that overlap or come within twice their rim rounding of each
            other, or a floor not below its plane.
        IncompatibleOptions: a hole in a terrain without planes or with a sloped plane.
    """

    primitives: tuple[Primitive, ...]
    smoothing: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.primitives, Plane | Box | Hole):
            raise InvalidInput("`primitives` must be a tuple of primitives, e.g. (Plane(),)")
        primitives = tuple(self.primitives)
        for i, p in enumerate(primitives):
            if not isinstance(p, Plane | Box | Hole):
                raise InvalidInput(
                    f"`primitives[{i}]` must be a Plane, Box or Hole, got {type(p).__name__}"
                )
        object.__setattr__(self, "primitives", primitives)
        k = _number(self.smoothing, "smoothing")
        if k < 0:
            raise InvalidInput(f"`smoothing` must be >= 0 [m], got {k}; 0 is the exact minimum")
        object.__setattr__(self, "smoothing", k)
        if not self.planes and not self.boxes:
            raise InvalidInput(
                "the terrain has no solid: give at least one Plane or Box in `primitives`"
            )
        if self.holes:
            sloped = [p for p in self.planes if not p.horizontal]
            if not self.planes or sloped:
                raise IncompatibleOptions(
                    "holes cut horizontal planes only, but the terrain has "
                    + ("no plane" if not self.planes else f"the sloped plane {sloped[0]}")
                    + "; use horizontal planes, or model the ground around the hole with "
                    "Boxes"
                )
            for plane in self.planes:
                for hole in self.holes:
                    if hole.floor is not None and hole.floor >= plane.height:
                        raise InvalidInput(
                            f"hole floor {hole.floor} m is not below the plane at "
                            f"{plane.height} m; lower `floor`"
                        )
            for i, a in enumerate(self.holes):
                for b in self.holes[i + 1:]:
                    # apart by more than both rims: the nearest support near one hole is
                    # then never inside another (what makes the max over holes exact)
                    room = a.rounding + b.rounding
                    apart = (b.x[0] - a.x[1] > room or a.x[0] - b.x[1] > room
                             or (a.y is not None and b.y is not None
                                 and (b.y[0] - a.y[1] > room or a.y[0] - b.y[1] > room)))
                    if not apart:
                        raise InvalidInput(
                            f"holes {a.x, a.y} and {b.x, b.y} overlap or are not more than "
                            f"{room} m (their rim roundings) apart; merge them into one hole"
                        )

    @property
    def planes(self) -> tuple[Plane, ...]:
        return tuple(p for p in self.primitives if isinstance(p, Plane))

    @property
    def boxes(self) -> tuple[Box, ...]:
        return tuple(p for p in self.primitives if isinstance(p, Box))

    @property
    def holes(self) -> tuple[Hole, ...]:
        return tuple(p for p in self.primitives if isinstance(p, Hole))

    @property
    def planar(self) -> bool:
        """True when nothing depends on y (planes with n_y = 0, no y-ranges): usable by a
        robot that moves in the x-z plane."""
        return (all(p.normal[1] == 0.0 for p in self.planes)
                and all(p.y is None for p in (*self.boxes, *self.holes)))

    # ------------------------------------------------------------------ geometry
    def distance(self, point: Any) -> Any:
        """Signed distance from `point` (casadi 3-vector or array (x, y, z)) to the
        terrain [m]: a casadi expression of the same type (DM for numbers)."""
        point = _casadi(point)
        k = self.smoothing
        parts = []
        for plane in self.planes:
            if self.holes:
                # the plane minus every hole: the intersection of the single-hole solids
                cuts = [hole.cut(plane, k)(point) for hole in self.holes]
                d = cuts[0]
                for c in cuts[1:]:
                    d = ca.fmax(d, c)
                parts.append(d)
            else:
                parts.append(plane.distance(point))
        parts += [box.distance(point) for box in self.boxes]
        out = parts[0]
        for d in parts[1:]:
            out = smooth_min(out, d, k)
        return out

    def gap(self, point: Any, radius: float) -> Any:
        """g = distance(p) - r [m] of a sphere of `radius` [m] centred at `point`."""
        r = _number(radius, "radius")
        if r < 0:
            raise InvalidInput(f"`radius` must be >= 0 [m], got {r}")
        return self.distance(point) - r

    def normal(self, point: Any) -> Any:
        """The unit world normal grad_p d / |grad_p d| at `point` (casadi 3-vector of the
        point's type): from the nearest point of the terrain towards `point`."""
        point = _casadi(point)
        if isinstance(point, ca.DM):
            p = ca.SX.sym("p", 3)
            return ca.DM(ca.Function("n", [p], [self.normal(p)])(point))
        grad = ca.gradient(self.distance(point), point)
        return grad / ca.norm_2(grad)

    def height_at(self, x: float, y: float = 0.0) -> float:
        """The highest support surface at (x, y) [m] (edges sharp, so within `rounding`
        of an edge the rounded surface is lower); -inf inside a bottomless hole."""
        return self._support_at(x, y)[0]

    def friction_at(self, x: float, y: float = 0.0) -> float:
        """The Coulomb coefficient of the highest support surface at (x, y) [-].

        Raises:
            InvalidInput: (x, y) is inside a bottomless hole (no support).
        """
        height, mu = self._support_at(x, y)
        if mu is None:
            raise InvalidInput(f"no support at ({x}, {y}): it is inside a bottomless hole")
        return mu

    def _support_at(self, x: float, y: float) -> tuple[float, float | None]:
        x, y = _number(x, "x"), _number(y, "y")
        best: tuple[float, float | None] = (-_INF, None)
        hole = next((h for h in self.holes if h.covers(x, y)), None)
        for plane in self.planes:
            if hole is None:
                candidate = (plane.height_at(x, y), plane.friction)
            elif hole.floor is not None:
                candidate = (hole.floor, hole.friction)
            else:
                continue
            if candidate[0] > best[0]:
                best = candidate
        for box in self.boxes:
            if box.covers(x, y) and box.top > best[0]:
                best = (box.top, box.friction)
        return best

    @property
    def friction(self) -> float:
        """The Coulomb coefficient shared by every surface (planes, boxes, hole floors).

        Raises:
            IncompatibleOptions: the surfaces differ; the time-freezing contact has one
                constant coefficient, so give `mu` per contact (`from_robot(mu=...)`) or
                model only the surfaces one contact reaches (`relevant_to`).
        """
        values = {p.friction for p in (*self.planes, *self.boxes)}
        values |= {h.friction for h in self.holes if h.floor is not None}
        if len(values) != 1:
            raise IncompatibleOptions(
                f"the terrain's surfaces have different friction coefficients "
                f"{sorted(values)}; a contact has one constant coefficient: give `mu` per "
                "contact, or keep only the surfaces it reaches with `relevant_to(region)`"
            )
        return values.pop()

    def relevant_to(self, region: Region, *, margin: float = 0.0) -> Terrain:
        """The terrain with only the primitives a sphere centred in `region` can reach.

        A primitive is kept when its sharp solid (which contains the rounded one) comes
        within `margin` of the region: give the largest contact radius plus any slack
        [m]. A hole is kept when its footprint widened by its rim comes within `margin`
        of the region's x-y footprint and a plane is kept.

        Raises:
            InvalidInput: `region` is not a `Region`, a negative margin, or no solid can
                be reached (the contacts never touch the terrain: drop them).
        """
        if not isinstance(region, Region):
            raise InvalidInput(
                f"`region` must be a Region(lower, upper), got {type(region).__name__}"
            )
        margin = _number(margin, "margin")
        if margin < 0:
            raise InvalidInput(f"`margin` must be >= 0 [m], got {margin}")
        kept = [p for p in self.primitives
                if not isinstance(p, Hole) and p.reaches(region, margin)]
        if not kept:
            raise InvalidInput(
                f"no solid of the terrain comes within {margin} m of {region}: a contact "
                "there never touches the ground; drop it or widen the region"
            )
        if any(isinstance(p, Plane) for p in kept):
            kept += [h for h in self.holes if h.reaches(region, margin)]
        order = {id(p): i for i, p in enumerate(self.primitives)}
        kept.sort(key=lambda p: order[id(p)])
        return Terrain(tuple(kept), smoothing=self.smoothing)

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (for sidecars); `Terrain.from_dict` reads it back."""
        return {"kind": "terrain", "smoothing": self.smoothing,
                "primitives": [p.to_dict() for p in self.primitives]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Terrain:
        """The terrain `to_dict` described.

        Raises:
            InvalidInput: not a terrain description, or an unknown primitive kind.
        """
        if not isinstance(data, dict) or data.get("kind") != "terrain":
            raise InvalidInput(f"not a terrain description (kind 'terrain'): {data!r}")
        primitives = []
        for i, item in enumerate(data.get("primitives", ())):
            fields = dict(item)
            kind = fields.pop("kind", None)
            if kind not in _KINDS:
                raise InvalidInput(
                    f"`primitives[{i}]` has kind {kind!r}; use one of {sorted(_KINDS)}"
                )
            for key in ("x", "y"):
                if fields.get(key) is not None:
                    fields[key] = _range_from_json(fields[key])
            if "normal" in fields:
                fields["normal"] = tuple(fields["normal"])
            primitives.append(_KINDS[kind](**fields))
        return cls(tuple(primitives), smoothing=data.get("smoothing", 0.0))
