"""Task checks: does a physical plan do what it was asked to?

The verification (`tfcontact.verify`) says whether a plan is *physical*; a plan can be
physical and still useless: a do-nothing plan of a problem with only a terminal cost, or a
hopper that stops 0.39 m short of its goal, both passed it. A `ContactProblem` therefore
states its task as goals, each a strategy object that checks the plan's motion in
physical time and reports a measured figure against its limit (`GoalCheck`). A plan is a
success only if it converged, passed the verification *and* met every goal; a missed goal
gives the status "goal_missed", a plan that did not move "no_motion".

Coordinates are named as in the CLS (`ComplementarityLagrangianSystem.q_names`, e.g.
"x", "z", "pitch"); contacts by their index.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tfcontact.errors import InvalidInput, positive_int

GOAL_MISSED = "goal_missed"
NO_MOTION = "no_motion"


@dataclass(frozen=True)
class Motion:
    """A plan's motion in physical time, as the goals read it.

    Attributes:
        t: physical times [s], (M,), non-decreasing (an impact repeats its time).
        q: configurations, (M, n_q); names: the coordinates' names, (n_q,).
        gaps: contact gaps [m], (M, n_contacts).
    """

    t: np.ndarray
    q: np.ndarray
    gaps: np.ndarray
    names: tuple[str, ...]

    def coordinate(self, name: str) -> int:
        if name not in self.names:
            raise InvalidInput(f"goal names the coordinate `{name}`; the system's "
                               f"coordinates are {', '.join(self.names)}")
        return self.names.index(name)


@dataclass(frozen=True)
class GoalCheck:
    """One goal measured on a plan: `value` against `limit` (`passed` when the goal's
    comparison holds), and the status the plan gets when it does not (`failure`)."""

    name: str
    description: str
    value: float
    limit: float
    passed: bool
    failure: str

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "description": self.description,
                "value": self.value if math.isfinite(self.value) else None,
                "limit": self.limit, "passed": self.passed, "failure": self.failure}

    def line(self) -> str:
        mark = "ok" if self.passed else self.failure.upper().replace("_", " ")
        return f"  {self.name}: {self.description}: {self.value:.4g} (limit {self.limit:g}) "\
               f"{mark}"


class Goal(abc.ABC):
    """A task check of a plan's physical motion."""

    @abc.abstractmethod
    def check(self, motion: Motion) -> GoalCheck:
        """The goal measured on `motion`."""

    @abc.abstractmethod
    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        """Raise `InvalidInput` if the goal names a coordinate or contact the system has
        not (called when the problem is stated, before any solving)."""


def _finite(value: float, name: str, positive: bool = False) -> float:
    value = float(value)
    if not math.isfinite(value) or (positive and value <= 0):
        kind = "a positive" if positive else "a finite"
        raise InvalidInput(f"`{name}` must be {kind} number, got {value!r}")
    return value


@dataclass(frozen=True)
class EndPosition(Goal):
    """The plan ends with coordinate `coordinate` within `tolerance` of `target`
    (|q_end - target| <= tolerance), e.g. the base x at the goal."""

    coordinate: str
    target: float
    tolerance: float

    def __post_init__(self) -> None:
        _finite(self.target, "target")
        _finite(self.tolerance, "tolerance", positive=True)

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        Motion(np.zeros(0), np.zeros((0, len(names))), np.zeros((0, 0)),
               tuple(names)).coordinate(self.coordinate)

    def check(self, motion: Motion) -> GoalCheck:
        end = motion.q[-1, motion.coordinate(self.coordinate)]
        miss = abs(end - self.target)
        return GoalCheck(f"end {self.coordinate}",
                         f"|{self.coordinate}(T) - {self.target:g}| (ends at {end:.4g})",
                         float(miss), self.tolerance, bool(miss <= self.tolerance),
                         GOAL_MISSED)


@dataclass(frozen=True)
class Progress(Goal):
    """Coordinate `coordinate` advances by at least `distance` from start to end
    (q_end - q_0 >= distance; a negative distance asks for a move the other way)."""

    coordinate: str
    distance: float

    def __post_init__(self) -> None:
        if _finite(self.distance, "distance") == 0:
            raise InvalidInput("`distance` of a Progress goal must not be 0")

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        EndPosition(self.coordinate, 0.0, 1.0).validate(names, n_contacts)

    def check(self, motion: Motion) -> GoalCheck:
        i = motion.coordinate(self.coordinate)
        moved = float(motion.q[-1, i] - motion.q[0, i])
        sign = 1.0 if self.distance > 0 else -1.0
        return GoalCheck(f"progress {self.coordinate}",
                         f"{self.coordinate}(T) - {self.coordinate}(0)", moved,
                         self.distance, bool(sign * moved >= sign * self.distance),
                         GOAL_MISSED)


@dataclass(frozen=True)
class Clearance(Goal):
    """Contact `contact` leaves the ground by at least `height` [m] at some time (a hop
    or a step happened): max_t gap(t) >= height."""

    contact: int
    height: float

    def __post_init__(self) -> None:
        _finite(self.height, "height", positive=True)

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        if not 0 <= self.contact < n_contacts:
            raise InvalidInput(f"Clearance names contact {self.contact}; the system has "
                               f"{n_contacts} (indices 0..{n_contacts - 1})")

    def check(self, motion: Motion) -> GoalCheck:
        highest = float(np.max(motion.gaps[:, self.contact]))
        return GoalCheck(f"clearance contact {self.contact}",
                         f"largest gap of contact {self.contact} [m]", highest, self.height,
                         bool(highest >= self.height), GOAL_MISSED)


@dataclass(frozen=True)
class LiftOffs(Goal):
    """Contact `contact` leaves the ground at least `count` separate times, each time
    rising above `height` [m] after touching it (gap <= `touch` [m]): hops or steps that
    happened, not a foot that skims or swings twice in one flight."""

    contact: int
    count: int
    height: float
    touch: float = 1e-3

    def __post_init__(self) -> None:
        positive_int(self.count, "count")
        _finite(self.height, "height", positive=True)
        if not 0 < _finite(self.touch, "touch", positive=True) < self.height:
            raise InvalidInput(f"`touch` ({self.touch} m) must lie below `height` "
                               f"({self.height} m)")

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        Clearance(self.contact, self.height).validate(names, n_contacts)

    def check(self, motion: Motion) -> GoalCheck:
        rises, grounded = 0, False
        for gap in motion.gaps[:, self.contact]:
            if gap <= self.touch:
                grounded = True
            elif gap >= self.height and grounded:
                rises, grounded = rises + 1, False
        return GoalCheck(f"lift-offs contact {self.contact}",
                         f"times contact {self.contact} rises above {self.height:g} m from "
                         "the ground", float(rises), float(self.count),
                         bool(rises >= self.count), GOAL_MISSED)


def sample_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of consecutive True samples of `mask`, as (first, last) index pairs."""
    runs, start = [], None
    for k, value in enumerate(np.asarray(mask, dtype=bool)):
        if value and start is None:
            start = k
        if start is not None and (not value or k == len(mask) - 1):
            runs.append((start, k if value else k - 1))
            start = None
    return runs


@dataclass(frozen=True)
class Flight(Goal):
    """Contacts `contacts` are all off the ground together, each gap above `height` [m],
    for at least `duration` [s] in one stretch: a jump's flight phase, not feet that lift
    one after another. The stretch is measured between the first and last samples of the
    motion in which every gap is above `height`, so it never overstates the flight."""

    contacts: tuple[int, ...]
    duration: float
    height: float = 1e-2

    def __post_init__(self) -> None:
        object.__setattr__(self, "contacts", tuple(self.contacts))
        if not self.contacts:
            raise InvalidInput("a Flight goal needs at least one contact")
        _finite(self.duration, "duration", positive=True)
        _finite(self.height, "height", positive=True)

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        for contact in self.contacts:
            Clearance(contact, self.height).validate(names, n_contacts)

    def check(self, motion: Motion) -> GoalCheck:
        airborne = np.all(motion.gaps[:, list(self.contacts)] > self.height, axis=1)
        longest = max((float(motion.t[b] - motion.t[a]) for a, b in sample_runs(airborne)),
                      default=0.0)
        return GoalCheck("flight", f"longest time contacts {list(self.contacts)} are all "
                         f"above {self.height:g} m [s]", longest, self.duration,
                         bool(longest >= self.duration), GOAL_MISSED)


@dataclass(frozen=True, eq=False)
class EndHeight(Goal):
    """Contact `contact` ends resting on a surface at height `height` [m]: its gap at T at
    most `touch` [m] and the lowest point of its sphere within `tolerance` of `height`
    (|z_low(T) - height| <= tolerance). A foot on a step's top, not on the ground before
    the step nor against its face, whose gaps are as small.

    Args:
        contact: the contact's index.
        height: the surface's height [m] (a horizontal top: a step, a platform).
        tolerance: [m].
        lowest: q -> z_low(q), the height of the contact sphere's lowest point [m] (its
            centre's z minus its radius), e.g. a CasADi Function of q.
        touch: the largest gap at T that counts as resting [m].
    """

    contact: int
    height: float
    tolerance: float
    lowest: Callable[[np.ndarray], object]
    touch: float = 1e-3

    def __post_init__(self) -> None:
        _finite(self.height, "height")
        _finite(self.tolerance, "tolerance", positive=True)
        _finite(self.touch, "touch", positive=True)
        if not callable(self.lowest):
            raise InvalidInput("`lowest` must be a function q -> height of the contact's "
                               f"lowest point [m], got {self.lowest!r}")

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        Clearance(self.contact, 1.0).validate(names, n_contacts)

    def check(self, motion: Motion) -> GoalCheck:
        z_low = float(self.lowest(motion.q[-1]))
        gap = float(motion.gaps[-1, self.contact])
        miss = abs(z_low - self.height)
        resting = gap <= self.touch
        return GoalCheck(f"end height contact {self.contact}",
                         f"|z_low(T) - {self.height:g}| of contact {self.contact} (ends at "
                         f"{z_low:.4g} m, gap {gap:.2g} m, resting if <= {self.touch:g})",
                         float(miss), self.tolerance,
                         bool(miss <= self.tolerance and resting), GOAL_MISSED)


@dataclass(frozen=True)
class Moves(Goal):
    """The plan moves: some coordinate leaves its start value by at least `distance`
    (max_t max_i |q_i(t) - q_i(0)| >= distance). Catches the do-nothing plan."""

    distance: float = 1e-2

    def __post_init__(self) -> None:
        _finite(self.distance, "distance", positive=True)

    def validate(self, names: Sequence[str], n_contacts: int) -> None:
        """Any system moves or not: nothing to check."""

    def check(self, motion: Motion) -> GoalCheck:
        moved = float(np.max(np.abs(motion.q - motion.q[0]))) if motion.q.size else 0.0
        return GoalCheck("motion", "largest change of a coordinate from its start", moved,
                         self.distance, bool(moved >= self.distance), NO_MOTION)


@dataclass(frozen=True)
class TaskReport:
    """The goals of a plan, measured. No goals: `passed`, with `stated` False."""

    checks: tuple[GoalCheck, ...]

    @property
    def stated(self) -> bool:
        return bool(self.checks)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    @property
    def status(self) -> str:
        """"done", or the failure of the first missed goal ("no_motion" before any other:
        a plan that did not move missed everything for that reason)."""
        missed = [c for c in self.checks if not c.passed]
        if not missed:
            return "done"
        if any(c.failure == NO_MOTION for c in missed):
            return NO_MOTION
        return missed[0].failure

    def summary(self) -> str:
        if not self.checks:
            return "task: no goals stated (only the physical checks were made)"
        head = "task: done" if self.passed else f"task: {self.status.replace('_', ' ')}"
        return "\n".join([head, *(c.line() for c in self.checks)])

    def to_dict(self) -> dict[str, object]:
        return {"status": self.status, "passed": self.passed,
                "checks": [c.to_dict() for c in self.checks]}


def check_goals(goals: Sequence[Goal], motion: Motion) -> TaskReport:
    """Measure every goal on `motion`."""
    return TaskReport(tuple(goal.check(motion) for goal in goals))
