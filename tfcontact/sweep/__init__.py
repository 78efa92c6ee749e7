"""Stability sweeps: a plan solved from many seeded perturbed starts, over a parameter grid
(friction, a_n, relaxation, discretisation), as Dask tasks (`tfcontact sweep PLAN`).

    spec = SweepSpec("hopper", starts=20, grid={"relaxation": ("scholtes", "l1")})
    result = run_sweep(spec, "out/sweeps/hopper")   # a LocalCluster of 2 processes
    print(result.table())

Each case is saved as its own JSON file as it finishes, so a rerun resumes; the sweep
folder ends with `table.md` and `chart.png`. The names below are imported on first use,
so that the command line's parser (`tfcontact.sweep.cli`) does not load the solver.
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> module
_EXPORTS: dict[str, str] = {
    "add_sweep_parser": "tfcontact.sweep.cli",
    "sweep_command": "tfcontact.sweep.cli",
    "DEFAULT_RANGES": "tfcontact.sweep.perturbation",
    "CoordinateRange": "tfcontact.sweep.perturbation",
    "InfeasibleStart": "tfcontact.sweep.perturbation",
    "Perturbation": "tfcontact.sweep.perturbation",
    "PerturbedStart": "tfcontact.sweep.perturbation",
    "CaseFileError": "tfcontact.sweep.results",
    "CaseResult": "tfcontact.sweep.results",
    "SweepResult": "tfcontact.sweep.results",
    "Progress": "tfcontact.sweep.run",
    "ProgressLines": "tfcontact.sweep.run",
    "Silent": "tfcontact.sweep.run",
    "run_sweep": "tfcontact.sweep.run",
    "solve_case": "tfcontact.sweep.run",
    "GRID_PARAMETERS": "tfcontact.sweep.spec",
    "GridParameter": "tfcontact.sweep.spec",
    "SweepCase": "tfcontact.sweep.spec",
    "SweepSpec": "tfcontact.sweep.spec",
    "HOPPER_PERTURBATION": "tfcontact.sweep.targets",
    "PARTICLE_PERTURBATION": "tfcontact.sweep.targets",
    "SWEEP_TARGETS": "tfcontact.sweep.targets",
    "HopperTarget": "tfcontact.sweep.targets",
    "ParticleTarget": "tfcontact.sweep.targets",
    "PlanTarget": "tfcontact.sweep.targets",
    "SweepTarget": "tfcontact.sweep.targets",
    "sweep_target": "tfcontact.sweep.targets",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'tfcontact.sweep' has no attribute '{name}'")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
