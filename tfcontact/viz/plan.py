"""`save_plan`: a plan's trajectory files, standard figures and summary in one folder."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from tfcontact.plan_format.adapters import plan_summary
from tfcontact.plan_format.trajectory import Trajectory, save_trajectory


def save_plan(
    result: Any,
    trajectory: Trajectory,
    out_dir: str | Path,
    *,
    formats: tuple[str, ...] = ("png",),
) -> list[Path]:
    """Write a plan's files into `out_dir` (created): `trajectory.npz` + `trajectory.json`,
    the standard figures of `plot_trajectory` (frozen pieces detected with the
    time-freezing layer's `FROZEN_RATE_TOL`) and `summary.json` (`plan_summary`).

    Returns:
        The paths written.
    """
    from tfcontact.timefreezing import FROZEN_RATE_TOL
    from tfcontact.viz.figures import plot_trajectory

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = list(save_trajectory(out / "trajectory.npz", trajectory, rate_tol=FROZEN_RATE_TOL))
    files += plot_trajectory(trajectory, out, formats=formats, rate_tol=FROZEN_RATE_TOL)
    summary = out / "summary.json"
    summary.write_text(json.dumps(plan_summary(result), indent=2, allow_nan=False) + "\n")
    files.append(summary)
    return files
