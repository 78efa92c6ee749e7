"""`plan`: solve, verify and check the goals of a contact problem or of a task."""

from __future__ import annotations

import os
from typing import Any

from tfcontact.errors import InvalidInput
from tfcontact.task.build import build_task
from tfcontact.task.files import load_task
from tfcontact.task.spec import Task


def plan(problem: Any, options: Any = None, *, verbose: bool = True) -> Any:
    """Solve a contact plan with time-freezing + FESD + the MPCC homotopy, verify it
    against the original rigid-body system and check its task goals.

    Main args:
        problem: a `tfcontact.ocp.ContactProblem`, a `Task`, or the path of a task file
            (`load_task`).
        options: `ContactSolverOptions`; default: the task's preset (a problem's default:
            `ContactSolverOptions()`).

    Returns:
        The `ContactResult` (status, plan, verification, task checks). Files are written
        by `tfcontact.run_plan` / `tfcontact plan`, not here.
    """
    from tfcontact.ocp.contact import ContactProblem, solve_contact

    if isinstance(problem, str | os.PathLike):
        problem = load_task(problem)
    if isinstance(problem, Task):
        setup = build_task(problem)
        problem, options = setup.problem, setup.options if options is None else options
    if not isinstance(problem, ContactProblem):
        raise InvalidInput(f"`problem` must be a ContactProblem, a Task or a task file's path, "
                        f"got {type(problem).__name__}")
    return solve_contact(problem, options, verbose=verbose)
