"""The node file of an exact re-solve (`plan.npz` beside a plan's trajectory).

A trajectory file keeps a plan's samples for figures and replays; an exact re-solve
(`tfcontact.ocp.polish`) also has what its own checks need to run again from disk: the
controls per interval, the states at the interval boundaries, the contact sequence with
its switch times and the mesh. `verify_polished(problem, file.phases, file.t, file.x,
file.u, file.boundary_states)` re-verifies a plan read back with `load_resolved_plan`.

Arrays (numpy, no pickles): `t` (n,) node times [s] (a touchdown has two nodes at its
time), `x` (n, 2 n_q) node states (q, v), `u` (N, n_u) controls per interval, `boundary`
(N + 1, 2 n_q) states at the interval boundaries, `phase_modes` and `phase_starts` the
contact sequence ("stick", "slip+", "slip-", "flight") and its switch times [s],
`local_defects` (N,) the verification's replay defects, `integrator` ("rk4" or "radau")
and `substeps` (N,) nodes or elements per interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tfcontact.errors import TrajectoryFileError
from tfcontact.ocp.polish import Phase, PolishedPlan

ARRAYS = ("t", "x", "u", "boundary", "phase_modes", "phase_starts", "local_defects",
          "integrator", "substeps")


@dataclass(frozen=True, eq=False)
class ResolvedPlanFile:
    """An exact re-solve read back from its node file (module docstring)."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    boundary_states: np.ndarray
    phases: tuple[Phase, ...]
    local_defects: np.ndarray
    integrator: str
    substeps: tuple[int, ...]


def save_resolved_plan(plan: PolishedPlan, path: str | Path) -> Path:
    """Write an exact re-solve's node file (module docstring) to `path`; returns it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, t=plan.t, x=plan.x, u=plan.u, boundary=plan.boundary_states,
             phase_modes=np.array([p.mode for p in plan.phases]),
             phase_starts=np.array([p.start for p in plan.phases]),
             local_defects=np.asarray(plan.verification.local_defects),
             integrator=plan.integrator, substeps=np.asarray(plan.substeps, dtype=int))
    return path


def load_resolved_plan(path: str | Path) -> ResolvedPlanFile:
    """Read a node file written by `save_resolved_plan`.

    Raises:
        TrajectoryFileError: not a readable npz, an array missing, or arrays that do not
            fit together (named, with the fix).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError) as err:
        raise TrajectoryFileError(f"{path}: not a readable node file of an exact re-solve "
                                  f"({err}); write it with save_resolved_plan") from err
    missing = [name for name in ARRAYS if name not in arrays]
    if missing:
        raise TrajectoryFileError(f"{path}: the node file lacks {', '.join(missing)}; is it a "
                                  "trajectory (load it with load_trajectory) or damaged?")
    t, x = np.asarray(arrays["t"], dtype=float), np.asarray(arrays["x"], dtype=float)
    u, boundary = np.asarray(arrays["u"], dtype=float), np.asarray(arrays["boundary"], float)
    starts = [float(s) for s in arrays["phase_starts"]]
    modes = [str(m) for m in arrays["phase_modes"]]
    if (x.ndim != 2 or len(x) != len(t) or boundary.shape != (len(u) + 1, x.shape[1])
            or len(modes) != len(starts) or not modes or len(t) == 0):
        raise TrajectoryFileError(
            f"{path}: arrays that do not fit together (t {t.shape}, x {x.shape}, u "
            f"{u.shape}, boundary {boundary.shape}, {len(modes)} modes, {len(starts)} "
            "switch times); write the file again with save_resolved_plan")
    ends = starts[1:] + [float(t[-1])]
    return ResolvedPlanFile(
        t=t, x=x, u=u, boundary_states=boundary,
        phases=tuple(Phase(m, a, b) for m, a, b in zip(modes, starts, ends, strict=True)),
        local_defects=np.asarray(arrays["local_defects"], dtype=float),
        integrator=str(arrays["integrator"]),
        substeps=tuple(int(n) for n in np.atleast_1d(arrays["substeps"])))
