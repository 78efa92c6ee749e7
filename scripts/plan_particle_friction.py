"""TF-3: an inelastic particle with friction lands and is pushed to x = 3 (time-freezing OCP).

Solves PROBLEMS.md TF-3 (Radau IIA order 5, N_FE = 3, l_inf penalty homotopy), verifies
the plan by re-simulation and writes `trajectory.npz/.json`, figures and `summary.json`
into the output folder (default `out/particle_friction`).

    python scripts/plan_particle_friction.py [--out DIR] [--n-intervals N] [--relaxation linf]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from tfcontact.fesd import RadauIIA
from tfcontact.mpcc import RELAXATIONS
from tfcontact.ocp.contact import ContactSolverOptions, solve_contact
from tfcontact.plan_format.adapters import trajectory_from_result
from tfcontact.scenes.particle_ocps import BALL_GROUND, BALL_ROBOT, particle_friction_problem
from tfcontact.viz.plan import save_plan


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/particle_friction", help="output folder")
    parser.add_argument("--n-intervals", type=int, default=20, help="control intervals N")
    parser.add_argument("--relaxation", choices=sorted(RELAXATIONS), default="linf")
    parser.add_argument("--quiet", action="store_true", help="no homotopy progress lines")
    args = parser.parse_args(argv)
    problem = particle_friction_problem(n_intervals=args.n_intervals)
    options = ContactSolverOptions(
        scheme=RadauIIA(3), n_finite_elements=3,
        relaxation=RELAXATIONS[args.relaxation]())
    result = solve_contact(problem, options, verbose=not args.quiet)
    if args.quiet:
        print(result.summary())
    end = result.y[-1]
    tf = result.system
    state = np.concatenate([end[tf.q_index], end[tf.v_index]])
    print(f"x(T) = {np.round(state, 6).tolist()} (target [3, 0, 0, 0])")
    traj = trajectory_from_result(result, BALL_ROBOT, BALL_GROUND)
    files = save_plan(result, traj, args.out)
    print(f"wrote {len(files)} files to {args.out}/")
    return 0 if result.success else 1


if __name__ == "__main__":
    sys.exit(main())
