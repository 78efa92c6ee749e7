"""Seeded perturbations of a plan's start state that keep it feasible."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, TfcontactError, positive_int


class InfeasibleStart(TfcontactError, ValueError):
    """No feasible perturbed start was drawn within `Perturbation.max_tries`."""


@dataclass(frozen=True)
class CoordinateRange:
    """Add a uniform draw from [low, high] to one coordinate of the start state.

    Args:
        name: a configuration or velocity name of the plan's CLS (`q_names`, `v_names`).
        low, high: the range [coordinate units: m, rad, m/s], low <= high.
    """

    name: str
    low: float
    high: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise InvalidInput(f"`{self.name}` range must be finite with low <= high, got "
                               f"[{self.low}, {self.high}]")


# Defaults by coordinate name [m, rad]: the base moves a few centimetres and tilts a few
# hundredths of a radian; height only up, since the nominal start may rest on the ground.
DEFAULT_RANGES: dict[str, tuple[float, float]] = {
    "x": (-0.05, 0.05), "y": (-0.05, 0.05), "z": (0.0, 0.05),
    "roll": (-0.05, 0.05), "pitch": (-0.05, 0.05), "yaw": (-0.05, 0.05),
}


@dataclass(frozen=True)
class PerturbedStart:
    """A drawn start: (q0, v0), what was added to the nominal one, and the draws it took."""

    q0: np.ndarray
    v0: np.ndarray
    offsets: dict[str, float]
    tries: int


@dataclass(frozen=True)
class Perturbation:
    """Per-coordinate uniform offsets of the start state, redrawn until the start is feasible.

    Feasible: within the problem's state bounds, every contact gap f_c(q0) >= 0 (no foot
    below the ground) and, when the path constraint depends on the state only, that
    constraint at the start.

    Args:
        ranges: one `CoordinateRange` per perturbed coordinate (the others stay nominal).
        max_tries: draws before `InfeasibleStart` is raised.
    """

    ranges: tuple[CoordinateRange, ...]
    max_tries: int = 100

    def __post_init__(self) -> None:
        object.__setattr__(self, "ranges", tuple(self.ranges))
        if not self.ranges:
            raise InvalidInput("`ranges` is empty: a perturbation needs at least one "
                               "coordinate range")
        names = [r.name for r in self.ranges]
        if len(set(names)) != len(names):
            raise InvalidInput(f"`ranges` names a coordinate twice: {names}")
        positive_int(self.max_tries, "max_tries")

    @classmethod
    def from_names(cls, names: tuple[str, ...]) -> Perturbation:
        """`DEFAULT_RANGES` for the coordinates among `names` that it knows."""
        ranges = tuple(CoordinateRange(n, *DEFAULT_RANGES[n]) for n in names
                       if n in DEFAULT_RANGES)
        if not ranges:
            raise InvalidInput(f"no default perturbation for the coordinates {list(names)} "
                               f"(defaults exist for {', '.join(DEFAULT_RANGES)}); declare a "
                               "Perturbation in the plan's SweepTarget")
        return cls(ranges)

    def to_dict(self) -> dict:
        return {r.name: [r.low, r.high] for r in self.ranges}

    def sample(self, problem, rng: np.random.Generator) -> PerturbedStart:
        """A feasible perturbed start of the `ContactProblem` (rejection sampling)."""
        cls = problem.system.cls
        names = list(cls.q_names) + list(cls.v_names)
        missing = [r.name for r in self.ranges if r.name not in names]
        if missing:
            raise InvalidInput(f"the perturbation names coordinates {missing} that the plan "
                               f"does not have; its coordinates: {names}")
        index = [names.index(r.name) for r in self.ranges]
        low = np.array([r.low for r in self.ranges])
        high = np.array([r.high for r in self.ranges])
        nominal = np.concatenate([problem.q0, problem.v0])
        feasible = _feasibility(problem)
        for tries in range(1, self.max_tries + 1):
            offsets = rng.uniform(low, high)
            x0 = nominal.copy()
            x0[index] += offsets
            if feasible(x0):
                n_q = problem.q0.size
                return PerturbedStart(x0[:n_q], x0[n_q:],
                                      {r.name: float(d) for r, d in zip(self.ranges, offsets,
                                                                         strict=True)}, tries)
        raise InfeasibleStart(
            f"no feasible start in {self.max_tries} draws of {self.to_dict()} around "
            f"{dict(zip(names, nominal.round(4).tolist(), strict=True))}: every draw broke a "
            "state bound, put a contact below the ground or broke the path constraint; "
            "narrow the ranges (height offsets upwards only for a start on the ground)")


def _feasibility(problem):
    """x0 -> bool: the state bounds, the gaps and the state-only path constraint at x0."""
    cls = problem.system.cls
    n_q = problem.q0.size
    lower = np.concatenate([problem.q_lower, problem.v_lower])
    upper = np.concatenate([problem.q_upper, problem.v_upper])
    gaps = cls.function("gaps")
    tf = problem.system
    path = problem.path
    path_fn = None
    # A path constraint in the controls too holds for some control: checked only without.
    if path is not None and all(ca.depends_on(s, tf.y) for s in ca.symvar(path.expression)):
        path_fn = ca.Function("path", [tf.y], [path.expression])

    def feasible(x0: np.ndarray) -> bool:
        if np.any(x0 < lower) or np.any(x0 > upper):
            return False
        if np.any(np.asarray(gaps(x0[:n_q])).ravel() < 0.0):
            return False
        if path_fn is not None:
            value = np.asarray(path_fn(tf.initial_state(x0[:n_q], x0[n_q:]))).ravel()
            if np.any(value < path.lower - 1e-12) or np.any(value > path.upper + 1e-12):
                return False
        return True

    return feasible


def perturbed_problem(problem, start: PerturbedStart):
    """The `ContactProblem` from the perturbed start (its other data unchanged)."""
    return dataclasses.replace(problem, q0=start.q0, v0=start.v0)
