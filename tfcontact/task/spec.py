"""A planning task as data: robot, contacts, terrain, start, way points, goals, costs,
bounds, horizon and solver preset (`Task`), validated field by field.

Coordinates are named as a user reads them: the base's `tfcontact.robot.BASE_COORDINATES`
("x", "z", "pitch", ...) and each 1-DoF joint by its URDF name; velocities are "v_" and
controls "u_" followed by the coordinate's name. Every error names the field (as in the
TOML file: `contacts[1].radius`) and the fix.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from tfcontact.errors import InvalidInput, one_of, positive_int
from tfcontact.mpcc import BARRIERS
from tfcontact.ocp.stances import StanceOptions, sequence_changes
from tfcontact.robot.spec import BASES
from tfcontact.robot.terrain import Plane, Region, Terrain
from tfcontact.timefreezing import InscribedPyramid, SmoothedCone, SpatialFriction

GUESSES = ("start", "reference")
"""The initial guesses a task can ask for (`Task.guess`)."""
DISCRETIZATIONS = ("fesd", "standard")
"""The discovery's discretisations a task can ask for (`Task.discretization`): FESD's
switch detection (`tfcontact.fesd.Fesd`) or fixed equal steps (`tfcontact.fesd.Standard`)."""
FRICTION_MODELS: dict[str, type[SpatialFriction]] = {"cone": SmoothedCone,
                                                     "pyramid": InscribedPyramid}
"""`Task.friction_model` -> the `Inelastic(friction=...)` strategy it builds."""


def finite(value: object, where: str, *, low: float | None = None, strict: bool = False,
           unit: str = "") -> float:
    """`value` as a float, or `InvalidInput` naming the field `where`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidInput(f"`{where}` must be a number{unit and f' [{unit}]'}, got {value!r}")
    value = float(value)
    too_low = low is not None and (value <= low if strict else value < low)
    if not math.isfinite(value) or too_low:
        bound = "" if low is None else f" {'>' if strict else '>='} {low:g}"
        raise InvalidInput(f"`{where}` must be finite{bound}{unit and f' [{unit}]'}, "
                           f"got {value!r}")
    return value


def _names(mapping: Mapping[str, Any], where: str) -> dict[str, Any]:
    if not isinstance(mapping, Mapping) or not all(isinstance(k, str) and k for k in mapping):
        raise InvalidInput(f"`{where}` must be a table of names, got {mapping!r}")
    return dict(mapping)


RESOLVE_SETTINGS = frozenset({"cone_facets", "min_normal_force", "touchdown_speed",
                              "interior_rows", "contact_tolerance", "cone_margin",
                              "swing_middle", "discovery_residual", "lifted_forces",
                              "barrier", "flight_gap", "contact_gap", "end_standing",
                              "stall_iterations", "max_iter"})
"""The `tfcontact.ocp.StanceOptions` fields a task's `[resolve]` table may set."""


def _frozen(mapping: Mapping[str, Any]) -> Mapping[str, Any]:
    return MappingProxyType(dict(mapping))


def _ranges(mapping: Mapping[str, Any], where: str) -> Mapping[str, tuple[float, float]]:
    """{name: (low, high)} of a table of [low, high] pairs, each low < high."""
    checked = {}
    for k, pair in _names(mapping, where).items():
        if not isinstance(pair, tuple | list) or len(pair) != 2:
            raise InvalidInput(f"`{where}.{k}` must be [low, high], got {pair!r}")
        low, high = (finite(b, f"{where}.{k}") for b in pair)
        if low >= high:
            raise InvalidInput(f"`{where}.{k}` must have low < high, got {list(pair)}")
        checked[k] = (low, high)
    return _frozen(checked)


@dataclass(frozen=True)
class RobotEntry:
    """Which robot: a URDF path, a project robot ("hopper") or an example-robot-data name.

    Args:
        source: as `tfcontact.robot.load_robot`'s source.
        base: "fixed", "planar" (x, z, pitch), "planar_xz" (x, z), "vertical" (z: a
            rail) or "floating".
        locked: joints fixed and removed, with their positions {joint: rad or m}.
    """

    source: str
    base: str = "fixed"
    locked: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.source, str) or not self.source:
            raise InvalidInput(f"`robot.source` must be a URDF path or a robot name, got "
                               f"{self.source!r}")
        if self.base not in BASES:
            raise InvalidInput(f"`robot.base` must be one of {', '.join(BASES)}, got "
                               f"{self.base!r}")
        locked = {k: finite(v, f"robot.locked.{k}") for k, v in
                  _names(self.locked, "robot.locked").items()}
        object.__setattr__(self, "locked", _frozen(locked))


@dataclass(frozen=True)
class ContactEntry:
    """A contact candidate: a sphere on a frame, with its own friction and restitution.

    Args:
        frame: a frame of the robot model (a link or a fixed frame).
        radius: the sphere's radius [m].
        friction: Coulomb coefficient mu [-] (0: frictionless); None (omitted): the
            terrain's, that is the friction of the surfaces the contact can reach (0 on
            a `PlaneTerrain`).
        restitution: Newton's e [-]; e > 0 needs a single frictionless contact (elastic
            time-freezing).
        no_slip: while the sphere touches, it may not slide (v_t^2 <= K gap, with
            K = `no_slip_gain`): a foot that steps rather than skates.
        no_slip_gain: K [m/s^2]: the tangential speed allowed grows as sqrt(K gap) in
            flight (1 m/s at 1 cm for the default 100).
        eps_t: 3-D friction's stick speed [m/s] (`tfcontact.timefreezing.Contact.eps_t`;
            used where the contact has two tangents, e.g. a floating base): stick is a
            sliding mode on ||v_t|| = eps_t, so a standing foot creeps at most this fast,
            and the friction terms' derivatives grow as 1/eps_t. The default 1 mm/s
            keeps them bounded; the reference value 1e-7 made a solo12 jump's first NLP
            fail in IPOPT's restoration phase (benchmarks/legged.md).
        reach: the box the contact's centre keeps to relative to the base, {axis: [low,
            high]} [m] with axis x, y or z of the base's frame (a fixed base's: the
            world's), at every stage of the discovery: a leg's range of motion. It bounds
            the step length, so a walk must step more often to cover its distance. The
            stance re-solve of several contacts keeps these rows too
            (`resolve_path_rows`): without them its feet left the box, a foot 20 cm
            ahead of the base at T (benchmarks/legged.md).
        clearance: h [m] or None: a foot moving along the ground must be up, gap >=
            h v_t^2 / (v_t^2 + c^2) with c = `clearance_speed` (a row at every stage of
            the discovery): standing (v_t = 0) it may touch, moving at c it is h / 2 up,
            at 3 c 0.9 h. The no-slip row lets a foot shuffle (1 cm at 1 m/s); with this
            one a stepping foot rises near h. Near the ground it acts as a no-slip gain
            of c^2 / h (the foot lands and lifts almost vertically). Like `no_slip`, it
            steers the discovery only. On bolt's short walk it removed all but one of
            the sweep's lift-height failures but gained no plan: more of its discoveries
            began with a hop whose re-solve was infeasible (benchmarks/legged.md).
        clearance_speed: c [m/s].
    """

    frame: str
    radius: float
    friction: float | None = None
    restitution: float = 0.0
    no_slip: bool = False
    no_slip_gain: float = 100.0
    eps_t: float = 1e-3
    reach: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    clearance: float | None = None
    clearance_speed: float = 0.3

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str) or not self.frame:
            raise InvalidInput(f"`contacts[].frame` must be a frame name, got {self.frame!r}")
        where = f"contacts[{self.frame}]"
        object.__setattr__(self, "radius", finite(self.radius, f"{where}.radius", low=0.0,
                                                  strict=True, unit="m"))
        if self.friction is not None:
            object.__setattr__(self, "friction", finite(self.friction, f"{where}.friction",
                                                        low=0.0))
        e = finite(self.restitution, f"{where}.restitution", low=0.0)
        if e > 1.0:
            raise InvalidInput(f"`{where}.restitution` must lie in [0, 1], got {e!r}")
        object.__setattr__(self, "restitution", e)
        if not isinstance(self.no_slip, bool):
            raise InvalidInput(f"`{where}.no_slip` must be true or false, got "
                               f"{self.no_slip!r}")
        object.__setattr__(self, "no_slip_gain", finite(
            self.no_slip_gain, f"{where}.no_slip_gain", low=0.0, strict=True, unit="m/s^2"))
        object.__setattr__(self, "eps_t", finite(self.eps_t, f"{where}.eps_t", low=0.0,
                                                 strict=True, unit="m/s"))
        if self.clearance is not None:
            object.__setattr__(self, "clearance", finite(
                self.clearance, f"{where}.clearance", low=0.0, strict=True, unit="m"))
        object.__setattr__(self, "clearance_speed", finite(
            self.clearance_speed, f"{where}.clearance_speed", low=0.0, strict=True,
            unit="m/s"))
        reach = _ranges(self.reach, f"{where}.reach")
        unknown = sorted(set(reach) - {"x", "y", "z"})
        if unknown:
            raise InvalidInput(f"`{where}.reach` names axes {unknown}; its axes: x, y, z "
                               "(of the base's frame)")
        object.__setattr__(self, "reach", reach)


@dataclass(frozen=True)
class BodyEntry:
    """A point of the robot kept off the terrain: the sphere of `radius` on `frame` stays
    above it at every stage of the discovery and of the stance re-solve (a path row
    g(q) >= 0 with the contacts' gap function, `tfcontact.robot.Terrain.gap`). No force
    acts on it: a body that may touch the ground is a contact (`ContactEntry`).

    A knee or the base's underside that the collision check finds in the ground is kept
    out this way (solo12's jump discovered on fixed steps landed with its thighs 57 mm
    through the ground: benchmarks/legged.md).

    Args:
        frame: a frame of the robot model (e.g. a knee joint's frame).
        radius: the sphere's radius [m] (> 0): how far the body reaches around the frame's
            origin, e.g. half a thigh's width.
        discovery: False: only the stance re-solve keeps the row (its exact plan is the
            one the collision check judges; the discovery's relaxed plan only proposes
            stances). On solo12's jump discovered on fixed steps, knee rows in the
            discovery made its NLPs at sigma 1e-2 and 1e-3 stop at IPOPT's cap
            (benchmarks/legged.md).
    """

    frame: str
    radius: float
    discovery: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str) or not self.frame:
            raise InvalidInput(f"`bodies[].frame` must be a frame name, got {self.frame!r}")
        object.__setattr__(self, "radius", finite(self.radius, f"bodies[{self.frame}].radius",
                                                  low=0.0, strict=True, unit="m"))
        if not isinstance(self.discovery, bool):
            raise InvalidInput(f"`bodies[{self.frame}].discovery` must be true or false, got "
                               f"{self.discovery!r}")


@dataclass(frozen=True)
class ApartEntry:
    """Two points of the robot kept apart: the origins of `frames` stay at least
    `distance` from each other at every stage of the discovery and of the stance re-solve
    (a path row |p_a - p_b| - distance >= 0), e.g. two legs that must not swing through
    each other in a flight. Spheres about two frames, `distance` the sum of their radii:
    a body-to-body row that works for any robot, where bounds on a joint would keep the
    legs apart only for the motions they were set for.

    Args:
        frames: two different frames of the robot model (knees, feet).
        distance: the least distance between their origins [m] (> 0).
        discovery: False: only the stance re-solve keeps the row (as `BodyEntry`'s).
    """

    frames: tuple[str, str]
    distance: float
    discovery: bool = True

    def __post_init__(self) -> None:
        frames = self.frames
        if (not isinstance(frames, list | tuple) or len(frames) != 2
                or not all(isinstance(f, str) and f for f in frames)):
            raise InvalidInput(f"`apart[].frames` must be two frame names, got {frames!r}")
        frames = tuple(frames)
        if frames[0] == frames[1]:
            raise InvalidInput(f"`apart[].frames` names {frames[0]!r} twice; name two frames")
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "distance", finite(
            self.distance, f"apart[{self.name}].distance", low=0.0, strict=True, unit="m"))
        if not isinstance(self.discovery, bool):
            raise InvalidInput(f"`apart[{self.name}].discovery` must be true or false, got "
                               f"{self.discovery!r}")

    @property
    def name(self) -> str:
        """The pair as one name, "a-b" (its row's name)."""
        return "-".join(self.frames)


@dataclass(frozen=True)
class PlaneTerrain:
    """Flat ground: the half-space above a plane through height `height` (along `normal`).

    Args:
        height: the plane's offset along `normal` [m].
        normal: its unit normal (normalised; default z up). A slope: e.g. (-sin a, 0, cos a).
    """

    height: float = 0.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "height", finite(self.height, "terrain.height", unit="m"))
        if not isinstance(self.normal, tuple | list) or len(self.normal) != 3:
            raise InvalidInput(f"`terrain.normal` must be 3 numbers, got {self.normal!r}")
        normal = tuple(finite(c, "terrain.normal[]") for c in self.normal)
        size = math.sqrt(sum(c * c for c in normal))
        if size == 0.0:
            raise InvalidInput("`terrain.normal` must not be zero; e.g. [0, 0, 1]")
        object.__setattr__(self, "normal", tuple(c / size for c in normal))

    def to_dict(self) -> dict:
        return {"type": "flat", "height": self.height, "normal": list(self.normal)}


@dataclass(frozen=True)
class PrimitiveTerrain:
    """Terrain of primitives: sloped planes, steps and platforms (boxes), holes, each with
    its own friction (`tfcontact.robot.Terrain`), and where the contacts stay.

    The contacts' gaps model only the primitives a contact can reach
    (`Terrain.relevant_to(region)`); the sidecar's scene, its drawing and the collision
    check of the whole robot keep the whole terrain (a knee can hit a step the foot
    never reaches).

    Args:
        terrain: the `tfcontact.robot.Terrain`.
        region: the box where the contact spheres' centres stay (`tfcontact.robot.Region`
            [m]); None: derived from the task by `build_task` (`task_region`: the base's
            range, from its finite `bounds` or else from its start, way points and end
            goals, widened by each contact's reach from the base).
    """

    terrain: Terrain
    region: Region | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.terrain, Terrain):
            raise InvalidInput("`terrain` must be a tfcontact.robot.Terrain, e.g. "
                               "Terrain((Plane(), Box(x=(0.6, inf), top=0.05)))")
        if self.region is not None and not isinstance(self.region, Region):
            raise InvalidInput("`terrain.region` must be a tfcontact.robot.Region: "
                               "region = { lower = [x, y, z], upper = [x, y, z] }")

    @property
    def flat(self) -> bool:
        """One plane and nothing else: saved in the flat scene form, as a PlaneTerrain."""
        return len(self.terrain.primitives) == 1 and isinstance(self.terrain.primitives[0],
                                                                 Plane)

    def to_dict(self) -> dict:
        """The scene's terrain: `Terrain.to_dict()` ("kind": "terrain"), or the flat form
        {"type": "flat", "height": offset along the normal, "normal"} of one plane."""
        if self.flat:
            plane = self.terrain.primitives[0]
            return {"type": "flat", "height": plane.normal[2] * plane.height,
                    "normal": list(plane.normal)}
        return self.terrain.to_dict()


@dataclass(frozen=True)
class Waypoint:
    """Where the plan should be at physical time `time`: some named coordinates or
    velocities ({name: value}); the others are free there."""

    time: float
    values: Mapping[str, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", finite(self.time, "waypoints[].t", low=0.0,
                                                strict=True, unit="s"))
        values = {k: finite(v, f"waypoints[t={self.time:g}].{k}") for k, v in
                  _names(self.values, "waypoints[]").items()}
        if not values:
            raise InvalidInput(f"the way point at t = {self.time:g} s names no coordinate; "
                               "give e.g. x = 0.4")
        object.__setattr__(self, "values", _frozen(values))


@dataclass(frozen=True)
class StanceEntry:
    """One stance of a contact sequence given as data (`Task.stances`): the contacts
    `closed` from `start` [s] (their frames; empty: flight) until the next stance's start
    or the horizon."""

    closed: tuple[str, ...]
    start: float

    def __post_init__(self) -> None:
        closed = self.closed
        if isinstance(closed, str) or not isinstance(closed, list | tuple) or not all(
                isinstance(f, str) and f for f in closed) or len(set(closed)) != len(closed):
            raise InvalidInput(f"`stances[].closed` must list distinct contact frames, e.g. "
                               f"[\"FL_FOOT\", \"FR_FOOT\"] ([] for flight), got {closed!r}")
        object.__setattr__(self, "closed", tuple(closed))
        object.__setattr__(self, "start", finite(self.start, "stances[].start", low=0.0,
                                                 unit="s"))


@dataclass(frozen=True)
class Continuation:
    """Where a task's discovery starts (`Task.continuation`, `[continuation]` in a file):
    from another task's discovered plan, a homotopy in the task itself. The other task
    (`task`: the same robot, contacts, horizon and control grid, e.g. the same walk on
    flat ground) is discovered first from its own guess; its whole iterate is then the
    guess of this task's homotopy, which starts at `sigma` (a relaxation near the one it
    was solved at, so that the plan found is kept and moved, not forgotten).

    Args:
        task: the task discovered first (a `Task` with no continuation of its own).
        sigma: the first relaxation of this task's homotopy from that plan.
    """

    task: Task
    sigma: float = 1e-2

    def __post_init__(self) -> None:
        if not isinstance(self.task, Task):
            raise InvalidInput(f"`continuation.task` must be a Task (a task file or a "
                               f"shipped task's name), got {type(self.task).__name__}")
        if self.task.continuation is not None:
            raise InvalidInput(f"`continuation.task` ({self.task.name}) has a continuation "
                               "of its own; continue from the task it starts from instead")
        if self.task.stances:
            raise InvalidInput(f"`continuation.task` ({self.task.name}) gives its contact "
                               "sequence (`stances`): it has no discovery to continue from")
        object.__setattr__(self, "sigma", finite(self.sigma, "continuation.sigma", low=0.0,
                                                 strict=True))


@dataclass(frozen=True)
class Goals:
    """What the plan must do, checked on its physical motion (`tfcontact.ocp.goals`).

    Args:
        end: coordinates to end at, {name: value}, each within `tolerance`.
        tolerance: of the end values [m or rad].
        progress: coordinates to advance by at least a distance, {name: distance}.
        lift_offs: contacts to lift off a number of times, {frame: count}, each rising
            above `lift_height`.
        lift_height: [m].
        moves: the plan must move (a do-nothing plan fails).
        end_height: contacts that must end resting on a surface at a height, {frame:
            height [m]}: the gap at T below 1 mm and the sphere's lowest point within
            `height_tolerance` of the height (a foot on a step, not on the ground before
            it or against its face).
        height_tolerance: of the end heights [m].
        flight: a duration [s] for which every contact must be off the ground at once
            (each gap above `flight_height`): a jump, not feet lifted in turn; None: no
            such goal.
        flight_height: [m].
    """

    end: Mapping[str, float] = field(default_factory=dict)
    tolerance: float = 0.05
    progress: Mapping[str, float] = field(default_factory=dict)
    lift_offs: Mapping[str, int] = field(default_factory=dict)
    lift_height: float = 0.05
    moves: bool = True
    end_height: Mapping[str, float] = field(default_factory=dict)
    height_tolerance: float = 0.01
    flight: float | None = None
    flight_height: float = 0.01

    def __post_init__(self) -> None:
        object.__setattr__(self, "end", _frozen(
            {k: finite(v, f"goals.end.{k}") for k, v in _names(self.end, "goals.end").items()}))
        object.__setattr__(self, "tolerance", finite(self.tolerance, "goals.tolerance",
                                                     low=0.0, strict=True))
        progress = {k: finite(v, f"goals.progress.{k}") for k, v in
                    _names(self.progress, "goals.progress").items()}
        if any(v == 0.0 for v in progress.values()):
            raise InvalidInput("`goals.progress` distances must not be 0")
        object.__setattr__(self, "progress", _frozen(progress))
        object.__setattr__(self, "lift_offs", _frozen(
            {k: positive_int(v, f"goals.lift_offs.{k}") for k, v in
             _names(self.lift_offs, "goals.lift_offs").items()}))
        object.__setattr__(self, "lift_height", finite(self.lift_height, "goals.lift_height",
                                                       low=0.0, strict=True, unit="m"))
        if not isinstance(self.moves, bool):
            raise InvalidInput(f"`goals.moves` must be true or false, got {self.moves!r}")
        object.__setattr__(self, "end_height", _frozen(
            {k: finite(v, f"goals.end_height.{k}", unit="m") for k, v in
             _names(self.end_height, "goals.end_height").items()}))
        object.__setattr__(self, "height_tolerance", finite(
            self.height_tolerance, "goals.height_tolerance", low=0.0, strict=True, unit="m"))
        if self.flight is not None:
            object.__setattr__(self, "flight", finite(self.flight, "goals.flight", low=0.0,
                                                      strict=True, unit="s"))
        object.__setattr__(self, "flight_height", finite(
            self.flight_height, "goals.flight_height", low=0.0, strict=True, unit="m"))


@dataclass(frozen=True)
class Costs:
    """Least-squares weights.

    Args:
        tracking: per coordinate or velocity name, on the distance to the reference that
            runs from the start through the way points naming it (integrated over time).
        terminal: per name, on the distance of the end state to its last way point (or
            its `goals.end` value).
        control: on the squared controls (integrated over time).
    """

    tracking: Mapping[str, float] = field(default_factory=dict)
    terminal: Mapping[str, float] = field(default_factory=dict)
    control: float = 0.01

    def __post_init__(self) -> None:
        for name in ("tracking", "terminal"):
            weights = {k: finite(v, f"costs.{name}.{k}", low=0.0) for k, v in
                       _names(getattr(self, name), f"costs.{name}").items()}
            object.__setattr__(self, name, _frozen(weights))
        object.__setattr__(self, "control", finite(self.control, "costs.control", low=0.0))


@dataclass(frozen=True)
class Task:
    """A planning task: everything `tfcontact plan task.toml` needs.

    Main args:
        name: the task's name (output folder, summaries).
        robot: the `RobotEntry`.
        contacts: the `ContactEntry`s (at least one).
        horizon: the physical horizon T [s].
        n_intervals: control intervals N.

    Other args:
        start: the start state {name: value}; unnamed coordinates at the model's neutral
            configuration (0), unnamed velocities 0.
        actuated: the actuated joints (default: every joint of the model).
        effort: control bounds {joint: N or N m}, replacing the URDF's effort limits
            (needed where the URDF gives none).
        bounds: {name: [low, high]} for coordinates and velocities, replacing the URDF's
            joint position limits.
        start_ranges: {name: [low, high]}: the offsets a stability sweep (`tfcontact
            sweep`) adds to the start's coordinates and velocities, drawn uniformly (default:
            the library's base ranges, `tfcontact.sweep.DEFAULT_RANGES`). A walk that
            starts on its feet states ranges that keep it there.
        terrain: the ground: a `PlaneTerrain` (one plane) or a `PrimitiveTerrain` (planes,
            boxes, holes).
        waypoints: `Waypoint`s, in increasing time within the horizon.
        goals, costs: `Goals`, `Costs`.
        solver: a preset of `tfcontact.task.SOLVER_PRESETS`.
        guess: the solver's initial guess of the states: "start" (the start state
            everywhere: no contact schedule, no motion assumed) or "reference" (each
            coordinate named by a way point along its reference, the others at the start).
        a_n: the time-freezing auxiliary gain [m/s^2] of every contact.
        gap_scale: K [1/s] of the gap's switching function (about the inverse of a finite
            element's duration; `tfcontact.timefreezing.Inelastic.gap_scale`).
        periodic: coordinates and velocities that end where they start, x(T) = x(0) as a
            terminal constraint (a gait's period: name every state but the base's forward
            position, so that the gait repeats while it progresses).
        period: with `periodic`, the gait's period P [s] within the horizon instead:
            x(t + P) = x(t) for the named states at every control-interval boundary t
            from `period_from` [s] while t + P <= T (both multiples of T / N). A walk
            that must step several times per foot repeats one cycle: each foot steps in
            every period. It steers the discovery; the stance re-solve keeps the stances
            found and not the period.
        complementarity_tolerance: the residual at which the preset's MPCC homotopy stops
            (`Homotopy.tolerance`; default: the preset's). A plan whose relaxed contacts
            still act a millimetre above the surface fails its exact-impact replay; a
            smaller residual costs more NLPs.
        friction_model: how contacts with two tangents (a floating base's feet) rub:
            "cone" (Coulomb's circular cone, smoothed with each contact's `eps_t`:
            `tfcontact.timefreezing.SmoothedCone`) or "pyramid" (planar friction along
            each tangent with mu / sqrt(2), the square inscribed in the cone:
            `InscribedPyramid`; derivatives bounded, stick exact, slip along the square's
            diagonals).
        finite_elements: FESD's finite elements per control interval (default: the
            preset's), the resolution at which lift-offs and touch-downs are located.
        discretization: the discovery's, "fesd" (default: each finite element's step a
            variable, switches located inside the elements) or "standard" (fixed equal
            steps: a switch only at an element's end, first order there). With
            `exact_resolve` the discovery only proposes the contact sequence, and the
            stance re-solve places the touchdowns itself; measured on biped-walk
            (benchmarks/legged.md): the standard discretisation's NLPs took fewer
            iterations (NLP 1: 168 against 246) and its stepping stones proposed stances
            the re-solve converged on in 85 iterations.
        stop_residual: the discovery's homotopy ends at the first solved NLP whose
            complementarity residual is at most this (`Homotopy.stop_residual`), a
            stepping stone solved loosely included; needs `exact_resolve` and `[resolve]
            discovery_residual` at least this, so that the stance re-solve follows that
            iterate's stances. None (default): the homotopy goes on to
            `complementarity_tolerance`.
        barrier: IPOPT's update of the barrier parameter in every NLP, "adaptive" or
            "monotone" (`mu_strategy`; default: the preset's). Which one converges
            depends on the problem, measured: the two-foot bolt walk's last NLP reached
            IPOPT's cap with the fast preset's adaptive update and converged with the
            monotone one, while hopper-step and hopper-platform then failed
            (benchmarks/legged.md).
        blas_threads: threads of IPOPT's BLAS in the discovery's NLPs
            (`tfcontact.mpcc.Ipopt.blas_threads`; None: the library's 2). The homotopy's
            path depends on the rounding and the rounding on this count: a discovery
            measured on another count is stated with it, so that the plan follows the
            path it was measured on whatever the machine (solo12's 3-D jump: with 1
            thread 493 + 868 iterations and a verified plan; with 2 its NLPs at sigma
            1e-2 and 1e-3 stopped at IPOPT's cap and the plan failed).
        exact_resolve: after the discovery, re-solve the plan exactly along the contact
            sequence it found (no relaxation, impacts at the found times), so that the
            written plan is the exact one and is verified as such: one planar frictional
            contact along its stick, slip and flight phases (`tfcontact.ocp.polish`);
            several contacts along the stances found, each closed contact sticking
            (`tfcontact.ocp.stances`, verified with the multi-contact reference).
            Measured: bolt's walk converges and is verified this way (`biped-walk`); on
            hopper-step's terrain the one-contact re-solve is not usable yet (its
            expanded NLP passed 6 GB; unexpanded, 0.47 s per iteration, unconverged
            after 1000; benchmarks/legged.md).
        resolve_elements: Radau IIA elements per control interval of the stance re-solve
            (several contacts; default `StanceOptions.nodes`, 3). Fewer elements make a
            cheaper NLP and larger local defects (order 5: about (3/2)^5 = 7.6 times
            larger with 2 than with 3), which the verification checks.
        resolve: settings of the stance re-solve (several contacts), a `[resolve]` table
            of `RESOLVE_SETTINGS`, each the `tfcontact.ocp.StanceOptions` field of its
            name: `cone_facets`, `min_normal_force`, `touchdown_speed`, `interior_rows`,
            `contact_tolerance`, `cone_margin`, `swing_middle`, `discovery_residual`,
            `lifted_forces`, `barrier`, and `flight_gap`, `contact_gap` (the gaps [m]
            at which the discovery's relaxed plan opens and closes a contact when its
            stances are read), `end_standing` (the contacts down after their last
            touchdown stay down to T), `stall_iterations`, `max_iter` (IPOPT's cap on
            the re-solve: what a failed perturbed start costs in a sweep).
            What a plan of four 3-D feet needed is in benchmarks/legged.md.
        attempts: solves of the plan at most (default: the preset's): a plan that fails
            is solved again from its guess perturbed (`ContactSolverOptions.attempts`).
            With `exact_resolve` the whole plan runs again, discovery and re-solve
            (`tfcontact.scenes.Plan.whole_attempts`), when the re-solved plan fails its
            checks: the discovery's relaxed plan is not the plan, and its own verdict
            cannot decide. Measured on biped-walk-short's perturbed starts
            (benchmarks/sweeps).
        stances: a contact sequence given as data (`StanceEntry`s, `[[stances]]` in a
            file): no discovery; the plan is solved exactly along it
            (`tfcontact.ocp.stances`, each closed contact sticking, verified with the
            multi-contact reference) from the task's `guess`, with the `[resolve]`
            settings. The first stance starts at 0; each next one either closes contacts
            (a touchdown, at a free time inside the control interval its start lies in)
            or opens them (a lift-off, at its start, a control jump k T / N). For a robot
            whose gait is known, and to measure what a discovery costs against the same
            plan with its sequence fixed.
        ties: {coordinate: other}: the coordinate follows the other one at every stage of
            the discovery, position and velocity ("-other": mirrored, the negative), e.g.
            a quadruped's right legs tied to its left ones for a symmetric gait. They
            steer the discovery only (like no-slip): the stance re-solve keeps the
            stances found, not the ties (a closed foot's contact rows would repeat its
            twin's).
        continuation: a `Continuation`: the discovery starts from another task's
            discovered plan (the same robot, contacts and grid), e.g. a walk up a step
            from the same walk on flat ground, which the discovery from the standing
            guess did not find (benchmarks/legged.md).
        bodies: `BodyEntry`s, points of the robot kept off the terrain (knees, the base)
            in the discovery and the stance re-solve (`[[bodies]]` in a task file).
        apart: `ApartEntry`s, pairs of points of the robot kept apart (two legs' knees
            and feet) in the discovery and the stance re-solve (`[[apart]]`).
        description: a line for `tfcontact plan --list`.
    """

    name: str
    robot: RobotEntry
    contacts: tuple[ContactEntry, ...]
    horizon: float
    n_intervals: int
    start: Mapping[str, float] = field(default_factory=dict)
    actuated: tuple[str, ...] | None = None
    effort: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    start_ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    terrain: PlaneTerrain | PrimitiveTerrain = field(default_factory=PlaneTerrain)
    waypoints: tuple[Waypoint, ...] = ()
    goals: Goals = field(default_factory=Goals)
    costs: Costs = field(default_factory=Costs)
    solver: str = "default"
    guess: str = "start"
    a_n: float = 100.0
    gap_scale: float = 30.0
    periodic: tuple[str, ...] = ()
    period: float | None = None
    period_from: float = 0.0
    complementarity_tolerance: float | None = None
    finite_elements: int | None = None
    discretization: str = "fesd"
    stop_residual: float | None = None
    friction_model: str = "cone"
    barrier: str | None = None
    blas_threads: int | None = None
    exact_resolve: bool = False
    resolve_elements: int | None = None
    resolve: Mapping[str, Any] = field(default_factory=dict)
    attempts: int | None = None
    stances: tuple[StanceEntry, ...] = ()
    ties: Mapping[str, str] = field(default_factory=dict)
    continuation: Continuation | None = None
    bodies: tuple[BodyEntry, ...] = ()
    apart: tuple[ApartEntry, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        from tfcontact.task.presets import SOLVER_PRESETS

        if not isinstance(self.name, str) or not self.name:
            raise InvalidInput(f"`name` must be a non-empty string, got {self.name!r}")
        if not isinstance(self.robot, RobotEntry):
            raise InvalidInput("`robot` must be a RobotEntry (a [robot] table)")
        contacts = tuple(self.contacts)
        if not contacts or not all(isinstance(c, ContactEntry) for c in contacts):
            raise InvalidInput("`contacts` needs at least one contact: [[contacts]] with "
                               "frame and radius")
        frames = [c.frame for c in contacts]
        if len(set(frames)) != len(frames):
            raise InvalidInput(f"`contacts` names a frame twice: {frames}")
        object.__setattr__(self, "contacts", contacts)
        bodies = tuple(self.bodies)
        if not all(isinstance(b, BodyEntry) for b in bodies):
            raise InvalidInput("`bodies` must be BodyEntry's: [[bodies]] with frame and radius")
        named = [b.frame for b in bodies]
        if len(set(named)) != len(named) or set(named) & set(frames):
            raise InvalidInput(f"`bodies` names a frame twice or a contact's frame: {named} "
                               f"(contacts: {frames}); a body is kept off the terrain, a "
                               "contact may touch it: name each frame once")
        object.__setattr__(self, "bodies", bodies)
        apart = tuple(self.apart)
        if not all(isinstance(a, ApartEntry) for a in apart):
            raise InvalidInput("`apart` must be ApartEntry's: [[apart]] with frames and "
                               "distance")
        pairs = [frozenset(a.frames) for a in apart]
        if len(set(pairs)) != len(pairs):
            raise InvalidInput(f"`apart` names a pair twice: {[a.name for a in apart]}")
        object.__setattr__(self, "apart", apart)
        object.__setattr__(self, "horizon", finite(self.horizon, "horizon", low=0.0,
                                                   strict=True, unit="s"))
        object.__setattr__(self, "n_intervals", positive_int(self.n_intervals, "n_intervals"))
        object.__setattr__(self, "start", _frozen(
            {k: finite(v, f"start.{k}") for k, v in _names(self.start, "start").items()}))
        if self.actuated is not None:
            actuated = tuple(self.actuated)
            if not actuated or not all(isinstance(a, str) and a for a in actuated):
                raise InvalidInput(f"`actuated` must list joint names, got {self.actuated!r}")
            object.__setattr__(self, "actuated", actuated)
        object.__setattr__(self, "effort", _frozen(
            {k: finite(v, f"effort.{k}", low=0.0, strict=True) for k, v in
             _names(self.effort, "effort").items()}))
        object.__setattr__(self, "bounds", _ranges(self.bounds, "bounds"))
        object.__setattr__(self, "start_ranges", _ranges(self.start_ranges, "start_ranges"))
        if not isinstance(self.terrain, PlaneTerrain | PrimitiveTerrain):
            raise InvalidInput("`terrain` must be a PlaneTerrain ([terrain] height, normal) "
                               "or a PrimitiveTerrain ([[terrain.primitives]])")
        waypoints = tuple(self.waypoints)
        times = [w.time for w in waypoints]
        if times != sorted(set(times)) or (times and times[-1] > self.horizon):
            raise InvalidInput(f"`waypoints` times must increase within the horizon "
                               f"(0, {self.horizon:g}] s, got {times}")
        object.__setattr__(self, "waypoints", waypoints)
        if not isinstance(self.goals, Goals) or not isinstance(self.costs, Costs):
            raise InvalidInput("`goals` and `costs` must be Goals and Costs")
        one_of(self.solver, SOLVER_PRESETS, "solver")
        one_of(self.guess, GUESSES, "guess")
        object.__setattr__(self, "a_n", finite(self.a_n, "a_n", low=0.0, strict=True,
                                               unit="m/s^2"))
        object.__setattr__(self, "gap_scale", finite(self.gap_scale, "gap_scale", low=0.0,
                                                     strict=True, unit="1/s"))
        periodic = tuple(self.periodic)
        if not all(isinstance(n, str) and n for n in periodic) or \
                len(set(periodic)) != len(periodic):
            raise InvalidInput(f"`periodic` must list distinct state names, got "
                               f"{self.periodic!r}")
        object.__setattr__(self, "periodic", periodic)
        if self.period is not None:
            period = finite(self.period, "period", low=0.0, strict=True, unit="s")
            start = finite(self.period_from, "period_from", low=0.0, unit="s")
            if start + period > self.horizon * (1 + 1e-12):
                raise InvalidInput(f"`period_from` + `period` = {start + period:g} s passes "
                                   f"the horizon {self.horizon:g} s")
            if not periodic:
                raise InvalidInput("`period` needs `periodic`: the states that repeat")
            object.__setattr__(self, "period", period)
            object.__setattr__(self, "period_from", start)
        elif self.period_from != 0.0:
            raise InvalidInput("`period_from` needs `period`: the gait's period [s]")
        if self.complementarity_tolerance is not None:
            object.__setattr__(self, "complementarity_tolerance", finite(
                self.complementarity_tolerance, "complementarity_tolerance", low=0.0,
                strict=True))
        one_of(self.friction_model, FRICTION_MODELS, "friction_model")
        if self.finite_elements is not None:
            object.__setattr__(self, "finite_elements",
                               positive_int(self.finite_elements, "finite_elements"))
        if self.barrier is not None:
            one_of(self.barrier, BARRIERS, "barrier")
        if self.blas_threads is not None:
            positive_int(self.blas_threads, "blas_threads")
        one_of(self.discretization, DISCRETIZATIONS, "discretization")
        if not isinstance(self.exact_resolve, bool):
            raise InvalidInput(f"`exact_resolve` must be true or false, got "
                               f"{self.exact_resolve!r}")
        if self.resolve_elements is not None:
            object.__setattr__(self, "resolve_elements",
                               positive_int(self.resolve_elements, "resolve_elements"))
        if not isinstance(self.resolve, Mapping):
            raise InvalidInput(f"`resolve` must be a table, got {self.resolve!r}")
        unknown = sorted(set(self.resolve) - RESOLVE_SETTINGS)
        if unknown:
            raise InvalidInput(f"`resolve` has unknown keys {unknown}; its keys: "
                               f"{', '.join(sorted(RESOLVE_SETTINGS))}")
        StanceOptions(**self.resolve)  # its checks name the setting
        self._check_stances(frames)
        ties = _names(self.ties, "ties")
        for name, other in ties.items():
            if not isinstance(other, str) or other.removeprefix("-") in ("", name):
                raise InvalidInput(f"`ties.{name}` must name another coordinate (\"-name\" "
                                   f"mirrored), got {other!r}")
        object.__setattr__(self, "ties", _frozen(ties))
        self._check_continuation(frames)
        # the stance re-solve runs along given stances, or after a discovery of several
        # contacts with `exact_resolve` (one contact: `polish`, not the stance re-solve)
        stance_resolve = bool(self.stances) or (self.exact_resolve
                                                and len(self.contacts) >= 2)
        for key, resolve_only in (
                ("bodies", [b.frame for b in self.bodies if not b.discovery]),
                ("apart", [a.name for a in self.apart if not a.discovery])):
            if resolve_only and not stance_resolve:
                raise InvalidInput(
                    f"`{key}` {resolve_only} have `discovery = false`: only the stance "
                    "re-solve would keep them, which runs with `exact_resolve = true` and "
                    "several contacts, or along given `stances`; set those or drop "
                    "`discovery = false`")
        for name in ("resolve_elements", "resolve"):
            if getattr(self, name) and not stance_resolve:
                raise InvalidInput(
                    f"`{name}` sets the stance re-solve, which runs with "
                    "`exact_resolve = true` and several contacts, or along given "
                    "`stances`; remove it or set those")
        object.__setattr__(self, "resolve", _frozen(dict(self.resolve)))
        self._check_stop_residual()
        if self.attempts is not None:
            object.__setattr__(self, "attempts", positive_int(self.attempts, "attempts"))
        if not isinstance(self.description, str):
            raise InvalidInput("`description` must be a string")

    def _check_stop_residual(self) -> None:
        if self.stop_residual is None:
            return
        stop = finite(self.stop_residual, "stop_residual", low=0.0, strict=True)
        accepted = self.resolve.get("discovery_residual")
        if not self.exact_resolve or accepted is None or accepted < stop:
            raise InvalidInput(
                f"`stop_residual` = {stop:g} ends the discovery short of its tolerance for "
                "the stance re-solve to follow: set `exact_resolve = true` and `[resolve] "
                f"discovery_residual` to at least {stop:g}")
        object.__setattr__(self, "stop_residual", stop)

    def _check_continuation(self, frames: list[str]) -> None:
        before = self.continuation
        if before is None:
            return
        if not isinstance(before, Continuation):
            raise InvalidInput(f"`continuation` must be a Continuation ([continuation] with "
                               f"task and sigma), got {before!r}")
        if self.stances:
            raise InvalidInput("`continuation` starts a discovery, and `stances` replace it; "
                               "give one of them")
        other = before.task
        differs = [what for what, mine, theirs in (
            ("robot", self.robot, other.robot),
            ("contact frames", tuple(frames), tuple(c.frame for c in other.contacts)),
            ("actuated joints", self.actuated, other.actuated),
            ("horizon", self.horizon, other.horizon),
            ("n_intervals", self.n_intervals, other.n_intervals)) if mine != theirs]
        if differs:
            raise InvalidInput(f"`continuation.task` ({other.name}) must plan the same robot "
                               f"and contacts on the same grid, node by node; its "
                               f"{', '.join(differs)} differ from this task's")

    def _check_stances(self, frames: list[str]) -> None:
        stances = tuple(self.stances)
        if not all(isinstance(s, StanceEntry) for s in stances):
            raise InvalidInput("`stances` must be StanceEntry's ([[stances]] with closed and "
                               "start)")
        object.__setattr__(self, "stances", stances)
        if not stances:
            return
        if self.exact_resolve:
            raise InvalidInput("`stances` gives the contact sequence, so there is no "
                               "discovery to re-solve: remove `exact_resolve`")
        starts = [s.start for s in stances]
        if starts[0] != 0.0 or starts != sorted(set(starts)) or starts[-1] >= self.horizon:
            raise InvalidInput(f"`stances` must start at 0 s and their starts increase "
                               f"within the horizon [0, {self.horizon:g}) s, got {starts}")
        for s in stances:
            unknown = sorted(set(s.closed) - set(frames))
            if unknown:
                raise InvalidInput(f"the stance at {s.start:g} s closes {unknown}, which are "
                                   f"not contacts; the contacts: {frames}")
        sequence_changes(stances, self.horizon, self.n_intervals)
