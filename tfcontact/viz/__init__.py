"""tfcontact.viz: meshcat replay and figures of plans, read through `tfcontact.plan_format`.

* Plans are read and written through `tfcontact.plan_format` (`Trajectory`,
  `load_trajectory`, `save_trajectory`, ...), the package that owns the plan format.
* `replay`: live meshcat viewer or standalone HTML, in physical time.
* `plot_trajectory`: matplotlib figures (PNG and SVG).
* `cli_replay`, `cli_check`: the `tfcontact replay` and `tfcontact check` subcommands.
"""

from tfcontact.viz.cli import cli_check, cli_replay
from tfcontact.viz.figures import plot_trajectory
from tfcontact.viz.meshcat_replay import ReplayResult, replay

__all__ = [
    "ReplayResult",
    "cli_check",
    "cli_replay",
    "plot_trajectory",
    "replay",
]
