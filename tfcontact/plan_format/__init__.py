"""The plan format: one package owns how a plan is stored and read back.

* `trajectory`: the trajectory file (`.npz` arrays + `.json` sidecar, checksums, format
  versions), physical-time recovery from the stored samples, the one frozen-rate
  tolerance (`tfcontact.timefreezing.FROZEN_RATE_TOL`).
* `adapters`: results to trajectories (`trajectory_from_result`, `trajectory_from_polished`,
  `trajectory_from_stances`;
  `terrain_directions`: world normals and tangents along a terrain),
  the sidecar's robot and solver records, and the file's physics check (`check_plan`).

`tfcontact.viz` (figures, replay) reads plans through this package only.
"""

from tfcontact.plan_format.adapters import (
    CheckTolerances,
    PlanCheck,
    check_plan,
    describe_robot,
    find_impacts,
    plan_summary,
    solver_record,
    stance_clock,
    terrain_directions,
    trajectory_from_polished,
    trajectory_from_result,
    trajectory_from_stances,
)
from tfcontact.plan_format.trajectory import (
    FORMAT_VERSION,
    STANCE_GAP,
    PhysicalSamples,
    Trajectory,
    frozen_intervals,
    load_trajectory,
    physical_time,
    save_trajectory,
    stance_intervals,
)

__all__ = [
    "FORMAT_VERSION",
    "STANCE_GAP",
    "CheckTolerances",
    "PhysicalSamples",
    "PlanCheck",
    "Trajectory",
    "check_plan",
    "describe_robot",
    "find_impacts",
    "frozen_intervals",
    "load_trajectory",
    "physical_time",
    "plan_summary",
    "save_trajectory",
    "stance_intervals",
    "solver_record",
    "terrain_directions",
    "stance_clock",
    "trajectory_from_polished",
    "trajectory_from_stances",
    "trajectory_from_result",
]
