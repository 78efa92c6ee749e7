"""Planning tasks as data: a `Task` (or a TOML task file with the same fields) states the
robot, its contacts, the terrain, the start, way points, goals, costs, bounds, horizon and
solver preset; `build_task` turns it into the contact problem that `solve_contact` solves.

    tfcontact plan path/to/task.toml --out DIR
"""

from tfcontact.task.build import (
    PathRow,
    TaskSetup,
    build_task,
    contact_reach,
    coordinate_names,
    discovery_path_rows,
    path_row_layout,
    resolve_path_rows,
    solver_options,
    task_region,
    task_stances,
)
from tfcontact.task.files import (
    SHIPPED,
    load_task,
    shipped_tasks,
    task_from_dict,
    terrain_from_dict,
)
from tfcontact.task.presets import SOLVER_PRESETS
from tfcontact.task.solve import plan
from tfcontact.task.spec import (
    ApartEntry,
    BodyEntry,
    ContactEntry,
    Continuation,
    Costs,
    Goals,
    PlaneTerrain,
    PrimitiveTerrain,
    RobotEntry,
    StanceEntry,
    Task,
    Waypoint,
)

__all__ = [
    "SHIPPED",
    "SOLVER_PRESETS",
    "ApartEntry",
    "BodyEntry",
    "ContactEntry",
    "Continuation",
    "Costs",
    "Goals",
    "PathRow",
    "PlaneTerrain",
    "PrimitiveTerrain",
    "RobotEntry",
    "StanceEntry",
    "Task",
    "TaskSetup",
    "Waypoint",
    "build_task",
    "contact_reach",
    "coordinate_names",
    "discovery_path_rows",
    "load_task",
    "path_row_layout",
    "plan",
    "resolve_path_rows",
    "solver_options",
    "shipped_tasks",
    "task_from_dict",
    "task_region",
    "task_stances",
    "terrain_from_dict",
]
