"""Stability sweeps: a plan solved from many seeded perturbed starts, over a parameter grid
(friction, a_n, relaxation, discretisation), as Dask tasks (`tfcontact sweep PLAN`).

    spec = SweepSpec("hopper", starts=20, grid={"relaxation": ("scholtes", "l1")})
    result = run_sweep(spec, "out/sweeps/hopper")   # a LocalCluster of 2 processes
    print(result.table())

Each case is saved as its own JSON file as it finishes, so a rerun resumes; the sweep
folder ends with `table.md` and `chart.png`.
"""

from tfcontact.sweep.cli import add_sweep_parser, sweep_command
from tfcontact.sweep.perturbation import (
    DEFAULT_RANGES,
    CoordinateRange,
    InfeasibleStart,
    Perturbation,
    PerturbedStart,
)
from tfcontact.sweep.results import CaseFileError, CaseResult, SweepResult
from tfcontact.sweep.run import Progress, ProgressLines, Silent, run_sweep, solve_case
from tfcontact.sweep.spec import GRID_PARAMETERS, GridParameter, SweepCase, SweepSpec
from tfcontact.sweep.targets import (
    HOPPER_PERTURBATION,
    PARTICLE_PERTURBATION,
    SWEEP_TARGETS,
    HopperTarget,
    ParticleTarget,
    PlanTarget,
    SweepTarget,
    sweep_target,
)

__all__ = [
    "DEFAULT_RANGES",
    "GRID_PARAMETERS",
    "HOPPER_PERTURBATION",
    "SWEEP_TARGETS",
    "CaseFileError",
    "CaseResult",
    "CoordinateRange",
    "GridParameter",
    "HopperTarget",
    "PARTICLE_PERTURBATION",
    "ParticleTarget",
    "InfeasibleStart",
    "Perturbation",
    "PerturbedStart",
    "PlanTarget",
    "Progress",
    "ProgressLines",
    "Silent",
    "SweepCase",
    "SweepResult",
    "SweepSpec",
    "SweepTarget",
    "add_sweep_parser",
    "run_sweep",
    "solve_case",
    "sweep_command",
    "sweep_target",
]
