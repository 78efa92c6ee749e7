"""tfcontact: contact-rich motion planning for URDF robots.

The entry points a robotics user needs, from a URDF to a verified plan and its replay::

    import tfcontact
    robot = tfcontact.load_robot("hopper", base="planar", ...)   # Pinocchio + CasADi twin
    result = tfcontact.plan(problem, options)     # time-freezing + FESD + MPCC homotopy,
                                                  # verified, task goals checked
    result = tfcontact.plan("task.toml")          # a task file (tfcontact.task), or a Task
    tfcontact.replay(tfcontact.trajectory(result, robot), html="plan.html")
    tfcontact.run_plan("hopper", "out/hopper")    # a named plan of `tfcontact plan`
    tfcontact.simulate(system, x0, horizon=tfcontact.Physical(1.0), n_steps=20)

Layers, data flowing down the list (ARCHITECTURE.md):

* `tfcontact.robot`: Pinocchio models and their CasADi symbolic twin, contact candidates.
* `tfcontact.timefreezing`: complementarity Lagrangian systems -> piecewise smooth systems.
* `tfcontact.fesd`: piecewise smooth systems -> FESD discretisation, simulator.
* `tfcontact.mpcc`: relaxations and homotopy for MPCCs, solved with IPOPT.
* `tfcontact.ocp`: optimal control problems, results, task goals, the exact re-solve.
* `tfcontact.verify`: independent checks against the original system (beside `ocp`).
* `tfcontact.plan_format`: the plan format (trajectory files, adapters from results).
* `tfcontact.task`: planning tasks as data (TOML task files) -> contact problems.
* `tfcontact.scenes`: reference problems and the named plans of the command line.
* `tfcontact.sweep`: stability sweeps on Dask.
* `tfcontact.viz`: meshcat replay and figures of plans.

The names below are imported on first use, so `import tfcontact` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# public name -> (module, attribute)
_EXPORTS: dict[str, tuple[str, str]] = {
    "load_robot": ("tfcontact.robot", "load_robot"),
    "ContactSpec": ("tfcontact.robot", "ContactSpec"),
    "Ground": ("tfcontact.robot", "Ground"),
    "Terrain": ("tfcontact.robot", "Terrain"),
    "contact_system": ("tfcontact.timefreezing.from_robot", "from_robot"),
    "time_freeze": ("tfcontact.timefreezing", "time_freeze"),
    "Inelastic": ("tfcontact.timefreezing", "Inelastic"),
    "simulate": ("tfcontact.fesd", "simulate"),
    "Physical": ("tfcontact.fesd", "Physical"),
    "ContactProblem": ("tfcontact.ocp", "ContactProblem"),
    "ContactSolverOptions": ("tfcontact.ocp", "ContactSolverOptions"),
    "ContactResult": ("tfcontact.ocp", "ContactResult"),
    "plan": ("tfcontact.task", "plan"),
    "Task": ("tfcontact.task", "Task"),
    "load_task": ("tfcontact.task", "load_task"),
    "build_task": ("tfcontact.task", "build_task"),
    "run_plan": ("tfcontact.scenes", "run_plan"),
    "trajectory": ("tfcontact.plan_format.adapters", "trajectory_from_result"),
    "replay": ("tfcontact.viz", "replay"),
    "load_trajectory": ("tfcontact.plan_format", "load_trajectory"),
    "Interrupted": ("tfcontact.errors", "Interrupted"),
    "TfcontactError": ("tfcontact.errors", "TfcontactError"),
    "TimeLimitReached": ("tfcontact.errors", "TimeLimitReached"),
    "time_limit": ("tfcontact.interrupt", "time_limit"),
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'tfcontact' has no attribute '{name}'")
    module, attribute = _EXPORTS[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
