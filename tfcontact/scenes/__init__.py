"""Reference problems and robot plans: data, closed forms and runnable plans.

`PLANS` lists the robot plans of `tfcontact plan`; `run_plan` runs one. The names are
imported on first use: a scene module (`python -m tfcontact.scenes.monoped_exact`) loads
without the plans of the others.
"""

from __future__ import annotations

import importlib
from typing import Any

_PLANS = "tfcontact.scenes.plans"
__all__ = ["PLANS", "Plan", "PlanReport", "PlanSetup", "check_collisions", "plan_named", "run_plan",
           "task_plan"]


def __getattr__(name: str) -> Any:
    if name not in __all__:
        raise AttributeError(f"module 'tfcontact.scenes' has no attribute '{name}'")
    value = getattr(importlib.import_module(_PLANS), name)
    globals()[name] = value  # later look-ups skip this function
    return value
