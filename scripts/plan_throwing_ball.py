"""TF-1: a ball thrown with a force weaker than gravity must bounce to reach its target.

Solves PROBLEMS.md TF-1 (elastic time-freezing, e = 0.9, k_aux = 10; ||u|| <= 9 N < m g;
q(T) = (4, 0.5) at T = 4 s; the repository's discretisation N = 20, N_FE = 5, Radau IIA
with 4 stages, l_inf penalty homotopy; fewer stages under-resolve the auxiliary spring and
the optimiser profits from the integration error), verifies the plan against the
event-detecting simulation with exact Newton impacts and writes `trajectory.npz/.json`,
figures (numerical and physical time, the path in the x-z plane) and `summary.json` into
the output folder (default `out/throwing_ball`).

    python scripts/plan_throwing_ball.py [--out DIR] [--n-intervals N] [--relaxation linf]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tfcontact.fesd import RadauIIA
from tfcontact.mpcc import RELAXATIONS
from tfcontact.ocp.contact import ContactSolverOptions, solve_contact
from tfcontact.plan_format.adapters import trajectory_from_result
from tfcontact.scenes.particle_ocps import BALL_GROUND, BALL_ROBOT, throwing_ball_problem
from tfcontact.viz.plan import save_plan

TARGET = (4.0, 0.5)


def plot_path(result, out: Path) -> Path:
    """The ball's centre in the x-z plane, impacts marked."""
    fig = Figure(figsize=(6.0, 3.0))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    q = result.physical.q
    ax.plot(q[:, 0], q[:, 1], "-", lw=1.5, label="plan")
    for imp in result.physical.impacts:
        qi = imp.pre[result.system.q_index]
        ax.plot(qi[0], qi[1], "kv", ms=6)
    ax.plot(*TARGET, "r*", ms=12, label="target")
    ax.axhline(0.0, color="0.4", lw=1)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize="small")
    ax.set_title(f"throwing ball: {len(result.physical.impacts)} impact(s)")
    fig.tight_layout()
    path = out / "path.png"
    fig.savefig(path, dpi=120)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/throwing_ball", help="output folder")
    parser.add_argument("--n-intervals", type=int, default=20, help="control intervals N")
    parser.add_argument("--relaxation", choices=sorted(RELAXATIONS), default="linf")
    parser.add_argument("--quiet", action="store_true", help="no homotopy progress lines")
    args = parser.parse_args(argv)
    problem = throwing_ball_problem(TARGET, n_intervals=args.n_intervals)
    options = ContactSolverOptions(
        scheme=RadauIIA(4), n_finite_elements=5,
        relaxation=RELAXATIONS[args.relaxation]())
    result = solve_contact(problem, options, verbose=not args.quiet)
    if args.quiet:
        print(result.summary())
    q_end = result.y[-1, result.system.q_index]
    print(f"q(T) = {np.round(q_end, 6).tolist()} (target {list(TARGET)}), "
          f"{len(result.physical.impacts)} impact(s)")
    traj = trajectory_from_result(result, BALL_ROBOT, BALL_GROUND)
    files = save_plan(result, traj, args.out)
    files.append(plot_path(result, Path(args.out)))
    print(f"wrote {len(files)} files to {args.out}/")
    return 0 if result.success else 1


if __name__ == "__main__":
    sys.exit(main())
