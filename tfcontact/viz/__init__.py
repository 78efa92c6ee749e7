"""tfcontact.viz: meshcat replay and figures of plans, read through `tfcontact.plan_format`.

* `Trajectory`, `save_trajectory`, `load_trajectory`, `physical_time`: re-exported from
  `tfcontact.plan_format`, the package that owns the plan format.
* `replay`: live meshcat viewer or standalone HTML, in physical time.
* `plot_trajectory`: matplotlib figures (PNG and SVG).
* `cli_replay`, `cli_check`: the `tfcontact replay` and `tfcontact check` subcommands.
"""

from tfcontact.plan_format.trajectory import (
    FORMAT_VERSION,
    PhysicalSamples,
    Trajectory,
    frozen_intervals,
    load_trajectory,
    physical_time,
    save_trajectory,
)
from tfcontact.viz.cli import cli_check, cli_replay
from tfcontact.viz.figures import plot_trajectory
from tfcontact.viz.meshcat_replay import ReplayResult, replay

__all__ = [
    "FORMAT_VERSION",
    "PhysicalSamples",
    "ReplayResult",
    "Trajectory",
    "cli_check",
    "cli_replay",
    "frozen_intervals",
    "load_trajectory",
    "physical_time",
    "plot_trajectory",
    "replay",
    "save_trajectory",
]
