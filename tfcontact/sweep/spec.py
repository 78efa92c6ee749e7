"""What a sweep runs: the grid's parameters (one strategy object each), the `SweepSpec`
and the cases it expands to."""

from __future__ import annotations

import dataclasses
import itertools
import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput, one_of, positive_int

GridValue = float | str


class GridParameter(ABC):
    """One axis of a sweep's grid: how its values are checked, labelled and applied.

    `level` says who applies it: "problem" values go to the plan's `SweepTarget` (they
    change the model, e.g. the friction coefficient in the CLS contact data), "options"
    values change the `ContactSolverOptions` here, for every plan alike.
    """

    key: str
    level: str
    help: str

    @abstractmethod
    def check(self, value: object) -> GridValue:
        """`value` in its canonical form, or `InvalidInput` naming the key."""

    def label(self, value: GridValue) -> str:
        return f"{self.key}={value:g}" if isinstance(value, float) else f"{self.key}={value}"

    def apply(self, options: Any, value: GridValue) -> Any:
        """The solver options with this value (options-level parameters only)."""
        raise NotImplementedError(f"`{self.key}` changes the problem, not the options")


@dataclass(frozen=True)
class NumberParameter(GridParameter):
    """A number the plan's target puts into its model (`level` "problem")."""

    key: str
    help: str
    minimum: float
    strict: bool
    level: str = "problem"

    def check(self, value: object) -> GridValue:
        if isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise InvalidInput(f"`{self.key}` values must be numbers, got {value!r}") from None
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise InvalidInput(f"`{self.key}` values must be numbers, got {value!r}")
        value = float(value)
        low_ok = value > self.minimum if self.strict else value >= self.minimum
        if not (math.isfinite(value) and low_ok):
            bound = ">" if self.strict else ">="
            raise InvalidInput(f"`{self.key}` values must be finite and {bound} "
                               f"{self.minimum:g} ({self.help}), got {value!r}")
        return value


class ChoiceParameter(GridParameter):
    """A setting chosen by name: its values are `names()`."""

    @abstractmethod
    def names(self) -> tuple[str, ...]:
        """The names a value may take."""

    def check(self, value: object) -> GridValue:
        return one_of(value, self.names(), self.key)


# The solver layers (CasADi) are imported where a value is checked or applied, so that
# the command line's parser (`tfcontact --help`) stays light.

RELAXATION_NAMES = ("scholtes", "l1", "linf")
"""The keys of `tfcontact.mpcc.RELAXATIONS` (a test keeps them equal)."""


@dataclass(frozen=True)
class RelaxationParameter(ChoiceParameter):
    """The MPCC relaxation by its short name (`tfcontact.mpcc.RELAXATIONS`)."""

    key: str = "relaxation"
    level: str = "options"
    help: str = "MPCC relaxation: " + ", ".join(RELAXATION_NAMES)

    def names(self) -> tuple[str, ...]:
        from tfcontact.mpcc import RELAXATIONS

        return tuple(RELAXATIONS)

    def apply(self, options: Any, value: GridValue) -> Any:
        from tfcontact.mpcc import RELAXATIONS

        return dataclasses.replace(options, relaxation=RELAXATIONS[str(value)]())


SCHEMES = ("fesd", "standard")


@dataclass(frozen=True)
class SchemeParameter(ChoiceParameter):
    """FESD (the plan's own `Fesd` settings, else the defaults) or the standard
    discretisation with fixed equal steps (`tfcontact.fesd.Standard`)."""

    key: str = "scheme"
    level: str = "options"
    help: str = "discretisation: fesd (switch detection) or standard (fixed steps)"

    def names(self) -> tuple[str, ...]:
        return SCHEMES

    def apply(self, options: Any, value: GridValue) -> Any:
        from tfcontact.fesd import Fesd, Standard

        if value == "standard":
            return dataclasses.replace(options, method=Standard())
        method = options.method if isinstance(options.method, Fesd) else Fesd()
        return dataclasses.replace(options, method=method)


@dataclass(frozen=True)
class FiniteElementsParameter(GridParameter):
    """Finite elements per control interval, N_FE (`ContactSolverOptions.n_finite_elements`):
    the integration step, h = T / (N N_FE) in numerical time, for every plan alike."""

    key: str = "n_fe"
    level: str = "options"
    help: str = "finite elements per control interval N_FE (the step h = T / (N N_FE))"

    def check(self, value: object) -> GridValue:
        if isinstance(value, str):
            try:
                value = int(value)
            except ValueError:
                raise InvalidInput(f"`n_fe` values must be whole numbers >= 1, got {value!r}") \
                    from None
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise InvalidInput(f"`n_fe` values must be whole numbers >= 1, got {value!r}")
        return str(int(value))

    def apply(self, options: Any, value: GridValue) -> Any:
        return dataclasses.replace(options, n_finite_elements=int(value))


MUMPS_ORDERS = {"auto": 7, "amd": 0, "pord": 4, "metis": 5}
"""MUMPS's fill-reducing orders by name -> IPOPT's `mumps_pivot_order` (7: MUMPS chooses;
here it picks PORD, benchmarks/linear_solvers.md)."""


@dataclass(frozen=True)
class OrderingParameter(ChoiceParameter):
    """The order MUMPS factorises the discovery's KKT matrices in (IPOPT's
    `mumps_pivot_order`, `MUMPS_ORDERS`): it sets the cost of an iteration and, through
    round-off, IPOPT's path (benchmarks/legged.md). A later stage's own IPOPT (the stance
    re-solve's) keeps its order."""

    key: str = "ordering"
    level: str = "options"
    help: str = "MUMPS's order in the discovery's NLPs: " + ", ".join(MUMPS_ORDERS)

    def names(self) -> tuple[str, ...]:
        return tuple(MUMPS_ORDERS)

    def apply(self, options: Any, value: GridValue) -> Any:
        nlp = options.nlp
        return dataclasses.replace(options, nlp=dataclasses.replace(nlp, options={
            **nlp.options, "mumps_pivot_order": MUMPS_ORDERS[str(value)]}))


GRID_PARAMETERS: dict[str, GridParameter] = {p.key: p for p in (
    NumberParameter("friction", "Coulomb friction coefficient mu of every contact [-]",
                    minimum=0.0, strict=False),
    NumberParameter("a_n", "time-freezing auxiliary normal gain of every contact [m/s^2]",
                    minimum=0.0, strict=True),
    RelaxationParameter(),
    SchemeParameter(),
    FiniteElementsParameter(),
    OrderingParameter(),
)}
"""The grid's keys, in the order cases and tables list them."""


@dataclass(frozen=True)
class SweepCase:
    """One solve of a sweep: a grid point and a perturbed start.

    Attributes:
        params: the grid point, ((key, value), ...) in `GRID_PARAMETERS` order.
        start: the start's number k (0 .. starts - 1).
        seed: the sweep's seed; the start's perturbation draws from the generator
            `numpy.random.default_rng([seed, start])`, so every grid point sees the same
            starts (paired comparisons).
    """

    params: tuple[tuple[str, GridValue], ...]
    start: int
    seed: int

    @property
    def case_id(self) -> str:
        """A file-name-safe, stable name: its case file is `cases/<case_id>.json`."""
        parts = [GRID_PARAMETERS[k].label(v) for k, v in self.params]
        return "_".join([*parts, f"start={self.start:03d}"])

    @property
    def group(self) -> str:
        """The grid point's label ("all" without a grid)."""
        return ", ".join(GRID_PARAMETERS[k].label(v) for k, v in self.params) or "all"

    def value(self, key: str) -> GridValue:
        return dict(self.params)[key]


@dataclass(frozen=True)
class SweepSpec:
    """A stability sweep: `starts` perturbed starts of a plan at every grid point.

    Main args:
        plan: a sweepable plan (`tfcontact.sweep.SWEEP_TARGETS`, e.g. "hopper").
        starts: perturbed starts per grid point.

    Other args:
        task: the plan's task (default: its first, e.g. the hopper's "short").
        seed: seed of the start perturbations (see `SweepCase.seed`).
        grid: {key: values} over `GRID_PARAMETERS` ("friction", "a_n", "relaxation",
            "scheme"); every combination is run. Empty: the plan as it is.
        threads_per_case: IPOPT's threads in each case, replacing the plan's: the
            element derivatives' (`Ipopt.threads`) and the BLAS's, no more than the task
            states (`tfcontact.sweep.run.with_case_threads`). Default 1: a worker runs one
            case on one core, so the plan's own 2 threads would have the cases contend
            for the cores. The BLAS count changes the rounding and with it IPOPT's path
            (`tfcontact.native.blas_threads`): one worker with 2 threads runs the cases as
            `tfcontact plan` runs them on 2 cores.
    """

    plan: str
    starts: int = 20
    task: str | None = None
    seed: int = 0
    grid: Mapping[str, Any] | tuple[tuple[str, tuple[GridValue, ...]], ...] = ()
    threads_per_case: int = 1

    def __post_init__(self) -> None:
        from tfcontact.sweep.targets import sweep_target

        target = sweep_target(self.plan)
        positive_int(self.starts, "starts")
        positive_int(self.threads_per_case, "threads_per_case")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer) \
                or self.seed < 0:
            raise InvalidInput(f"`seed` must be a non-negative integer, got {self.seed!r}")
        task = target.tasks[0] if self.task is None else self.task
        if task not in target.tasks:
            raise InvalidInput(f"plan `{self.plan}` has no task `{task}`; tasks: "
                               f"{', '.join(target.tasks)}")
        object.__setattr__(self, "task", task)
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "grid", _checked_grid(self.grid, target))
        if self.grid and target.given_sequence(task) is not None:
            raise InvalidInput(f"plan `{self.plan}` solves along a contact sequence given as "
                               f"data: the grid keys ({', '.join(k for k, _ in self.grid)}) "
                               "set a discovery, which it does not run; sweep its starts only")

    @property
    def target(self):
        """The plan's `SweepTarget`."""
        from tfcontact.sweep.targets import sweep_target

        return sweep_target(self.plan)

    def cases(self) -> tuple[SweepCase, ...]:
        """Every grid point x every start, grid points outermost."""
        keys = [k for k, _ in self.grid]
        points = itertools.product(*[values for _, values in self.grid])
        return tuple(SweepCase(tuple(zip(keys, point, strict=True)), k, self.seed)
                     for point in points for k in range(self.starts))

    def to_dict(self) -> dict:
        return {"plan": self.plan, "task": self.task, "starts": self.starts, "seed": self.seed,
                "grid": {k: list(v) for k, v in self.grid},
                "threads_per_case": self.threads_per_case}


def _checked_grid(grid: object, target: Any) -> tuple[tuple[str, tuple[GridValue, ...]], ...]:
    items = dict(grid) if isinstance(grid, Mapping) else dict(tuple(grid))
    for key in items:
        if key not in GRID_PARAMETERS:
            raise InvalidInput(f"unknown grid key `{key}`; grid keys: "
                               f"{', '.join(GRID_PARAMETERS)}")
        if GRID_PARAMETERS[key].level == "problem" and key not in target.problem_parameters:
            supported = ", ".join(sorted(target.problem_parameters)) or "none"
            raise InvalidInput(f"plan `{target.name}` cannot vary `{key}` (its problem-level "
                               f"grid keys: {supported})")
    checked = []
    for key, parameter in GRID_PARAMETERS.items():
        if key not in items:
            continue
        raw = items[key]
        values = (raw,) if isinstance(raw, str | float | int) else tuple(raw)
        if not values:
            raise InvalidInput(f"grid key `{key}` has no values")
        values = tuple(parameter.check(v) for v in values)
        if len(set(values)) != len(values):
            raise InvalidInput(f"grid key `{key}` repeats a value: {list(values)}")
        checked.append((key, values))
    return tuple(checked)
