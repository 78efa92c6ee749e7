"""Reference problems and robot plans: data, closed forms and runnable plans.

`PLANS` lists the robot plans of `tfcontact plan`; `run_plan` runs one.
"""

from tfcontact.scenes.plans import (
    PLANS,
    Plan,
    PlanReport,
    PlanSetup,
    plan_named,
    run_plan,
    task_plan,
)

__all__ = ["PLANS", "Plan", "PlanReport", "PlanSetup", "plan_named", "run_plan", "task_plan"]
