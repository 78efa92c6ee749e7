"""Task files: a TOML file with the fields of `Task`, and the task files shipped with
tfcontact (`shipped_tasks`).

    name = "vertical-hop"
    horizon = 1.0
    n_intervals = 20
    [robot]
    source = "hopper"             # a URDF path, a project robot or an example-robot-data name
    base = "planar"
    locked = { hip_joint = 0.0 }
    [[contacts]]
    frame = "foot"
    radius = 0.02
    friction = 0.45
    [start]
    z = 0.52
    [[waypoints]]
    t = 0.5
    z = 0.8
    [goals]
    lift_offs = { foot = 1 }

A relative URDF path is read relative to the task file's folder first.

A known contact sequence replaces the discovery (`Task.stances`): each stance names the
contacts down from its start until the next one's,

    [[stances]]
    closed = ["left_foot", "right_foot"]
    start = 0.0
    [[stances]]
    closed = ["right_foot"]       # the left foot lifts at this control jump
    start = 0.2

Points of the robot that must not touch the terrain (`Task.bodies`) are kept above it:

    [[bodies]]
    frame = "FL_KFE"              # a knee
    radius = 0.025
    discovery = false             # kept by the stance re-solve only (default: both)

Two points of the robot that must not meet (`Task.apart`: two legs swinging through each
other in a flight) are kept apart, their frames' origins at least `distance` from each
other:

    [[apart]]
    frames = ["FL_FOOT", "HL_FOOT"]
    distance = 0.06               # the two spheres' radii summed [m]
    discovery = false             # as for bodies

The terrain is one plane (`[terrain]` with `height` and `normal`, default flat at 0) or
primitives (`tfcontact.robot.Terrain`), each with the fields of its robot-layer class
(ranges as [lo, hi], `inf` for an open end, y omitted in a planar scene):

    [terrain]
    smoothing = 0.005                                   # [m], joins the solids C1
    region = { lower = [-0.5, -1, -1], upper = [1.5, 1, 1.5] }   # optional
    [[terrain.primitives]]
    kind = "plane"            # height, normal or slope = [dz/dx, dz/dy], friction
    friction = 0.8
    [[terrain.primitives]]
    kind = "box"              # x, top, y, rounding, friction: a step or platform
    x = [0.6, inf]
    top = 0.05
    rounding = 0.01
    friction = 0.8
    [[terrain.primitives]]
    kind = "hole"             # x, y, rounding, floor, friction
    x = [1.2, 1.4]
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.robot.terrain import Box, Hole, Plane, Region, Terrain
from tfcontact.task.spec import (
    RESOLVE_SETTINGS,
    ApartEntry,
    BodyEntry,
    ContactEntry,
    Continuation,
    Costs,
    Goals,
    PlaneTerrain,
    PrimitiveTerrain,
    RobotEntry,
    StanceEntry,
    Task,
    Waypoint,
)

SHIPPED = Path(__file__).resolve().parent / "shipped"
"""The folder of the task files shipped with tfcontact (`tfcontact plan --list`)."""

_TOP = {"name", "description", "robot", "contacts", "horizon", "n_intervals", "start",
        "actuated", "effort", "bounds", "terrain", "waypoints", "goals", "costs", "solver",
        "guess", "a_n", "gap_scale", "exact_resolve",
        "complementarity_tolerance", "finite_elements", "friction_model", "periodic",
        "period", "period_from", "barrier", "resolve_elements", "resolve",
        "start_ranges", "attempts", "stances", "ties", "continuation", "discretization",
        "stop_residual", "bodies", "apart", "blas_threads"}
_ROBOT = {"source", "base", "locked"}
_CONTACT = {"frame", "radius", "friction", "restitution", "no_slip", "no_slip_gain",
            "clearance", "clearance_speed",
            "eps_t", "reach"}
_TERRAIN = {"height", "normal"}
_PRIMITIVE_TERRAIN = {"primitives", "smoothing", "region"}
_PRIMITIVES: dict[str, tuple[type, set[str], tuple[str, ...]]] = {
    "plane": (Plane, {"kind", "height", "normal", "slope", "friction"}, ()),
    "box": (Box, {"kind", "x", "top", "y", "rounding", "friction"}, ("x", "top")),
    "hole": (Hole, {"kind", "x", "y", "rounding", "floor", "friction"}, ("x",)),
}
_GOALS = {"end", "tolerance", "progress", "lift_offs", "lift_height", "moves", "end_height",
          "height_tolerance", "flight", "flight_height"}
_COSTS = {"tracking", "terminal", "control"}
_CONTINUATION = {"task", "sigma"}


def _table(data: object, where: str, keys: set[str], required: tuple[str, ...] = ()
           ) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise InvalidInput(f"`{where}` must be a table, got {data!r}")
    unknown = sorted(set(data) - keys)
    if unknown:
        raise InvalidInput(f"`{where}` has unknown keys {unknown}; its keys: "
                           f"{', '.join(sorted(keys))}")
    missing = [k for k in required if k not in data]
    if missing:
        raise InvalidInput(f"`{where}` lacks {missing}")
    return dict(data)


def _listed(value: object, where: str) -> tuple:
    if not isinstance(value, list | tuple):
        raise InvalidInput(f"`{where}` must be an array of names, e.g. [\"z\", \"v_z\"], "
                           f"got {value!r}")
    return tuple(value)


def task_from_dict(data: Mapping[str, Any], folder: Path | None = None) -> Task:
    """The `Task` of a parsed task file (`folder`: where relative URDF paths are looked up
    first).

    Raises:
        InvalidInput: an unknown or missing key, or a bad value, naming the field.
    """
    top = _table(data, "task", _TOP, ("name", "robot", "contacts", "horizon", "n_intervals"))
    robot = _table(top["robot"], "robot", _ROBOT, ("source",))
    source = robot["source"]
    if folder is not None and isinstance(source, str) and source.endswith(".urdf"):
        local = folder / source
        if not Path(source).is_absolute() and local.is_file():
            source = str(local)
    contacts = top["contacts"]
    if not isinstance(contacts, list):
        raise InvalidInput("`contacts` must be an array of tables: [[contacts]]")
    waypoints = top.get("waypoints", [])
    if not isinstance(waypoints, list):
        raise InvalidInput("`waypoints` must be an array of tables: [[waypoints]]")
    parsed_waypoints = []
    for k, w in enumerate(waypoints):
        if not isinstance(w, Mapping) or "t" not in w:
            raise InvalidInput(f"`waypoints[{k}]` must be a table with a time t [s] and "
                               "coordinates, e.g. t = 0.5, z = 0.8")
        parsed_waypoints.append(Waypoint(w["t"], {n: v for n, v in w.items() if n != "t"}))
    actuated = top.get("actuated")
    bodies = top.get("bodies", [])
    if not isinstance(bodies, list):
        raise InvalidInput("`bodies` must be an array of tables: [[bodies]] with frame and "
                           "radius")
    apart = top.get("apart", [])
    if not isinstance(apart, list):
        raise InvalidInput("`apart` must be an array of tables: [[apart]] with frames and "
                           "distance")
    stances = top.get("stances", [])
    if not isinstance(stances, list):
        raise InvalidInput("`stances` must be an array of tables: [[stances]] with closed "
                           "and start")
    return Task(
        name=top["name"], description=top.get("description", ""),
        robot=RobotEntry(source=source, base=robot.get("base", "fixed"),
                         locked=robot.get("locked", {})),
        contacts=tuple(ContactEntry(**_table(c, f"contacts[{k}]", _CONTACT,
                                             ("frame", "radius")))
                       for k, c in enumerate(contacts)),
        horizon=top["horizon"], n_intervals=top["n_intervals"],
        start=top.get("start", {}),
        actuated=None if actuated is None else tuple(actuated)
        if isinstance(actuated, list) else actuated,
        effort=top.get("effort", {}),
        bounds=top.get("bounds", {}),
        start_ranges=top.get("start_ranges", {}),
        terrain=terrain_from_dict(top.get("terrain", {})),
        waypoints=tuple(parsed_waypoints),
        goals=Goals(**_table(top.get("goals", {}), "goals", _GOALS)),
        costs=Costs(**_table(top.get("costs", {}), "costs", _COSTS)),
        solver=top.get("solver", "default"), guess=top.get("guess", "start"),
        a_n=top.get("a_n", 100.0), gap_scale=top.get("gap_scale", 30.0),
        exact_resolve=top.get("exact_resolve", False),
        resolve_elements=top.get("resolve_elements"), attempts=top.get("attempts"),
        resolve=_table(top.get("resolve", {}), "resolve", set(RESOLVE_SETTINGS)),
        complementarity_tolerance=top.get("complementarity_tolerance"),
        finite_elements=top.get("finite_elements"),
        discretization=top.get("discretization", "fesd"),
        stop_residual=top.get("stop_residual"),
        friction_model=top.get("friction_model", "cone"),
        barrier=top.get("barrier"),
        blas_threads=top.get("blas_threads"),
        periodic=_listed(top.get("periodic", ()), "periodic"),
        period=top.get("period"), period_from=top.get("period_from", 0.0),
        ties=top.get("ties", {}),
        continuation=_continuation(top.get("continuation"), folder),
        bodies=tuple(BodyEntry(**_table(b, f"bodies[{k}]", {"frame", "radius", "discovery"},
                                        ("frame", "radius")))
                     for k, b in enumerate(bodies)),
        apart=tuple(ApartEntry(**_table(a, f"apart[{k}]", {"frames", "distance", "discovery"},
                                        ("frames", "distance")))
                    for k, a in enumerate(apart)),
        stances=tuple(StanceEntry(**_table(e, f"stances[{k}]", {"closed", "start"},
                                           ("closed", "start")))
                      for k, e in enumerate(stances)),
    )


def _continuation(data: object, folder: Path | None) -> Continuation | None:
    """A `[continuation]` table: `task` a shipped task's name or a task file (a path
    relative to this file's folder), `sigma` optional."""
    if data is None:
        return None
    table = _table(data, "continuation", _CONTINUATION, ("task",))
    source = table["task"]
    if not isinstance(source, str) or not source:
        raise InvalidInput(f"`continuation.task` must name a shipped task or a task file, "
                           f"got {source!r}")
    if source.endswith(".toml"):
        path = Path(source)
        if folder is not None and not path.is_absolute():
            path = folder / path
    else:
        shipped = shipped_tasks()
        if source not in shipped:
            raise InvalidInput(f"`continuation.task`: no shipped task `{source}`; shipped: "
                               f"{', '.join(shipped)}, or a task file PATH.toml")
        path = shipped[source]
    try:
        before = load_task(path)
    except InvalidInput as error:
        raise InvalidInput(f"`continuation.task`: {error}") from None
    return Continuation(before, **{k: v for k, v in table.items() if k != "task"})


def terrain_from_dict(data: object) -> PlaneTerrain | PrimitiveTerrain:
    """The terrain of a task file's `[terrain]` table: one plane (`height`, `normal`) or
    `primitives` (module docstring).

    Raises:
        InvalidInput: unknown keys, both forms at once, a bad primitive (its index named).
    """
    if not isinstance(data, Mapping) or "primitives" not in data:
        table = _table(data, "terrain", _TERRAIN | _PRIMITIVE_TERRAIN)
        extra = sorted(set(table) & (_PRIMITIVE_TERRAIN - {"primitives"}))
        if extra:
            raise InvalidInput(f"`terrain` has {extra} but no primitives; add "
                               "[[terrain.primitives]] or drop them")
        return PlaneTerrain(**{k: tuple(v) if k == "normal" and isinstance(v, list) else v
                               for k, v in table.items()})
    if set(data) & _TERRAIN:
        raise InvalidInput("`terrain` has both a plane's height/normal and primitives; give "
                           "the plane as [[terrain.primitives]] kind = \"plane\"")
    table = _table(data, "terrain", _PRIMITIVE_TERRAIN)
    items = table["primitives"]
    if not isinstance(items, list) or not items:
        raise InvalidInput("`terrain.primitives` must be an array of tables: "
                           "[[terrain.primitives]] with kind = \"plane\", \"box\" or \"hole\"")
    primitives = [_primitive(item, f"terrain.primitives[{i}]")
                  for i, item in enumerate(items)]
    region = None
    if "region" in table:
        bounds = _table(table["region"], "terrain.region", {"lower", "upper"},
                        ("lower", "upper"))
        try:
            region = Region(**{k: tuple(v) if isinstance(v, list) else v
                               for k, v in bounds.items()})
        except InvalidInput as error:
            raise InvalidInput(f"`terrain.region`: {error}") from None
    try:
        terrain = Terrain(tuple(primitives), smoothing=table.get("smoothing", 0.0))
    except (InvalidInput, IncompatibleOptions) as error:
        raise InvalidInput(f"`terrain`: {error}") from None
    return PrimitiveTerrain(terrain, region)


def _primitive(item: object, where: str) -> Plane | Box | Hole:
    kind = item.get("kind") if isinstance(item, Mapping) else None
    if kind not in _PRIMITIVES:
        raise InvalidInput(f"`{where}.kind` must be one of {', '.join(_PRIMITIVES)}, got "
                           f"{kind!r}")
    cls, keys, required = _PRIMITIVES[kind]
    fields = _table(item, where, keys, required)
    fields.pop("kind")
    fields = {k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()}
    try:
        if "slope" in fields:
            if "normal" in fields:
                raise InvalidInput("give `normal` or `slope`, not both")
            return Plane.sloped(fields.get("height", 0.0), fields["slope"],
                                friction=fields.get("friction", 0.0))
        return cls(**fields)
    except (InvalidInput, IncompatibleOptions) as error:
        raise InvalidInput(f"`{where}` ({kind}): {error}") from None


def load_task(path: str | Path) -> Task:
    """Read and validate a task file.

    Raises:
        InvalidInput: the file is missing, not TOML, or a field is bad (the message names
            the file and the field).
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise InvalidInput(f"task file {path} not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise InvalidInput(f"task file {path} is unreadable: {error}") from None
    except tomllib.TOMLDecodeError as error:
        raise InvalidInput(f"task file {path} is not valid TOML: {error}") from None
    try:
        return task_from_dict(data, path.resolve().parent)
    except (InvalidInput, TypeError) as error:
        raise InvalidInput(f"task file {path}: {error}") from None


def shipped_tasks() -> dict[str, Path]:
    """The shipped task files by name (file stem)."""
    return {p.stem: p for p in sorted(SHIPPED.glob("*.toml"))}
