"""Speed of the 2-D ball's circle plan (`scripts/plan_ball_in_box.py`): settings side by side.

Solves `box_circle_problem(w)` (default w = 3 pi, N = 25) once per variant of the solver
settings, one solve at a time, and prints a markdown table: NLPs, IPOPT iterations, wall
time of `solve_contact` (build, solve and verification), CPU time, time per iteration,
the end-state deviation of the exact four-wall replay, the bounces, and the wall time's
ratio to the seed's settings measured in the same run (the machine's load changes from
run to run; the ratios and the iteration counts are the figures to compare). Results:
benchmarks/ball_in_box_speed.md.

    python scripts/bench_ball_in_box.py [--omega 3] [--variants NAME ...]
    python scripts/bench_ball_in_box.py --perturb 1e-9 --seed 1   # a start moved by 1e-9
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Callable

import numpy as np

from tfcontact.fesd import GaussLegendre
from tfcontact.mpcc import Homotopy, LinfPenalty
from tfcontact.ocp.contact import ContactProblem, ContactSolverOptions, solve_contact
from tfcontact.scenes.particle_ocps import box_circle_options, box_circle_problem


def seed_options() -> ContactSolverOptions:
    """The plan's settings before issue 31: Gauss-Legendre 2, N_FE = 3, l_inf penalty
    from sigma_0 = 0.1 with kappa = 0.1, IPOPT's own MUMPS workspace, cold starts."""
    return ContactSolverOptions(scheme=GaussLegendre(2), n_finite_elements=3,
                                relaxation=LinfPenalty(),
                                homotopy=Homotopy(sigma_0=0.1, tolerance=1e-7))


def _with(base: ContactSolverOptions, kappa: float | None = None,
          **nlp: object) -> ContactSolverOptions:
    """`base` with another kappa and/or other `Ipopt` fields."""
    options = base
    if kappa is not None:
        options = dataclasses.replace(
            options, homotopy=dataclasses.replace(options.homotopy, kappa=kappa))
    if nlp:
        options = dataclasses.replace(options, nlp=dataclasses.replace(options.nlp, **nlp))
    return options


MEM = {"mumps_mem_percent": 50}
VARIANTS: dict[str, Callable[[], ContactSolverOptions]] = {
    "seed": seed_options,
    "mumps_mem_percent=50": lambda: _with(seed_options(), options=MEM),
    "chosen: mem50, kappa=0.05": box_circle_options,
    "chosen + AMD ordering": lambda: _with(
        box_circle_options(), options={**MEM, "mumps_pivot_order": 0}),
    "chosen + warm_start_push=1e-9": lambda: _with(box_circle_options(),
                                                   warm_start_push=1e-9),
    "chosen + warm start + alpha_for_y=min": lambda: _with(
        box_circle_options(), warm_start_push=1e-9, options={**MEM, "alpha_for_y": "min"}),
    "chosen + element derivatives": lambda: _with(box_circle_options(),
                                                  element_derivatives=True, threads=1),
    "chosen + element derivatives, 2 threads": lambda: _with(
        box_circle_options(), element_derivatives=True, threads=2),
}
"""The seed's settings, then one change at a time ("chosen" is `box_circle_options()`, the
plan's; the last five were tried and left out: benchmarks/ball_in_box_speed.md)."""


def perturbed(problem: ContactProblem, noise: float, seed: int) -> ContactProblem:
    """The problem with its reference guess moved by Gaussian noise of standard
    deviation `noise` [m, m/s] (not the start state): round-off decides which local
    solution, in how many iterations, a homotopy reaches, and this shows the spread."""
    if noise == 0:
        return problem
    rng = np.random.default_rng(seed)
    guess = problem.guess.copy()
    guess[1:] += noise * rng.standard_normal(guess[1:].shape)
    return dataclasses.replace(problem, guess=guess)


def measure(problem: ContactProblem, options: ContactSolverOptions) -> dict:
    """One solve: the table's figures."""
    wall, cpu = time.perf_counter(), time.process_time()
    result = solve_contact(problem, options, verbose=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    ocp = result.ocp
    return {"status": result.status, "nlps": ocp.n_nlps, "iterations": ocp.total_iterations,
            "per_nlp": ocp.iterations, "wall": wall, "cpu": cpu,
            "solve": result.timings["solve"], "cost": ocp.cost,
            "deviation": result.verification.end_state_deviation,
            "impacts": len(result.physical.impacts)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--omega", type=float, default=3.0, help="w / pi [-]")
    parser.add_argument("--n-intervals", type=int, default=25, help="control intervals N")
    parser.add_argument("--variants", nargs="+", choices=sorted(VARIANTS),
                        default=list(VARIANTS), metavar="NAME",
                        help=f"settings to compare (default all: {', '.join(VARIANTS)})")
    parser.add_argument("--perturb", type=float, default=0.0,
                        help="move the reference guess by this noise [m, m/s] (default 0)")
    parser.add_argument("--seed", type=int, default=1, help="the perturbation's seed")
    parser.add_argument("--repeat", type=int, default=1,
                        help="solve the variants round-robin this often; the table gives "
                             "the median times (default 1)")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    problem = perturbed(box_circle_problem(args.omega * math.pi, radius=1.0,
                                           n_intervals=args.n_intervals),
                        args.perturb, args.seed)
    names = args.variants if "seed" in args.variants else ["seed", *args.variants]
    start = f", guess moved by {args.perturb:g} (seed {args.seed})" if args.perturb else ""
    print(f"w = {args.omega:g} pi, N = {args.n_intervals}{start}; one solve at a time"
          + (f", {args.repeat} rounds, median times" if args.repeat > 1 else "") + "\n")
    print("| settings | status | NLPs | IPOPT iterations | wall [s] | CPU [s] | ms/iteration "
          "| end-state deviation | bounces | cost | wall / seed's |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    seed_wall = math.nan
    failed = False
    runs: dict[str, list[dict]] = {name: [] for name in names}
    for _ in range(max(args.repeat, 1)):
        for name in names:
            runs[name].append(measure(problem, VARIANTS[name]()))
    for name in names:
        m = dict(runs[name][-1])
        for key in ("wall", "cpu", "solve"):
            m[key] = float(np.median([run[key] for run in runs[name]]))
        if name == "seed":
            seed_wall = m["wall"]
        failed |= m["status"] != "converged"
        per_nlp = "+".join(map(str, m["per_nlp"]))
        print(f"| {name} | {m['status']} | {m['nlps']} | {m['iterations']} ({per_nlp}) | "
              f"{m['wall']:.2f} | {m['cpu']:.2f} | {1e3 * m['solve'] / m['iterations']:.1f} | "
              f"{m['deviation']:.1e} | {m['impacts']} | {m['cost']:.4f} | "
              f"{m['wall'] / seed_wall:.2f} |", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
