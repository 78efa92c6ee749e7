"""IPOPT's linear algebra side by side: MUMPS orderings and scalings, and SPRAL, on the
project's plans, one solve at a time in one run (issues 30 and 31,
benchmarks/linear_solvers.md).

    python scripts/bench_linear_solvers.py                       # every plan, every solver
    python scripts/bench_linear_solvers.py --plans hopper ball --solvers mumps spral

Plans: the hopper's bench task (`hopper_problem("bench")`, TF-8, one contact, planar
friction), the 2-D ball tracking a circle at w = 3 pi (`box_circle_problem`, four walls,
elastic) and the first NLP of the solo12 jump (`quadruped-jump-fesd` with the inscribed
pyramid's friction, four feet; one NLP only: its homotopy does not converge,
benchmarks/legged.md). Each plan
keeps its own settings; only the linear solver changes:

* `mumps`: IPOPT's default (MUMPS chooses its ordering, `mumps_pivot_order` 7);
* `mumps AMD`, `mumps PORD`, `mumps METIS`: the fill-reducing ordering fixed
  (`mumps_pivot_order` 0, 4, 5);
* `mumps no scaling`: `mumps_scaling` 0 instead of IPOPT's 77 (automatic);
* `spral`: STFC's SSIDS (`linear_solver = "spral"`, with the OpenMP settings it asks for).

Per row: status, NLPs, IPOPT iterations, wall time of `solve_contact`, milliseconds per
iteration split into CasADi's evaluations and IPOPT's own work (the factorisations), the
verification's end-state deviation, and the wall time's ratio to `mumps` in the same run.
"""

from __future__ import annotations

import os

# SPRAL runs on OpenMP and refuses to start without these (set before IPOPT loads).
if __name__ == "__main__":
    os.environ.setdefault("OMP_CANCELLATION", "TRUE")
    os.environ.setdefault("OMP_PROC_BIND", "TRUE")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

SOLVERS: dict[str, dict[str, Any]] = {
    "mumps": {},
    "mumps AMD": {"options": {"mumps_pivot_order": 0}},
    "mumps PORD": {"options": {"mumps_pivot_order": 4}},
    "mumps METIS": {"options": {"mumps_pivot_order": 5}},
    "mumps no scaling": {"options": {"mumps_scaling": 0}},
    "spral": {"linear_solver": "spral"},
}
"""Solver name -> changes to the plan's `Ipopt` (options are added to its own)."""


def _hopper() -> tuple[Any, Any]:
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    _, _, problem = hopper_problem("bench")
    return problem, hopper_options("bench")


def _ball() -> tuple[Any, Any]:
    from tfcontact.scenes.particle_ocps import box_circle_options, box_circle_problem

    return box_circle_problem(3.0 * math.pi, radius=1.0, n_intervals=25), box_circle_options()


def _jump_first_nlp() -> tuple[Any, Any]:
    from tfcontact.task import build_task, load_task, shipped_tasks

    task = load_task(shipped_tasks()["quadruped-jump-fesd"])
    setup = build_task(dataclasses.replace(task, friction_model="pyramid"))
    options = setup.options
    return setup.problem, dataclasses.replace(
        options, attempts=1, homotopy=dataclasses.replace(options.homotopy, max_nlps=1))


PLANS: dict[str, Callable[[], tuple[Any, Any]]] = {
    "hopper": _hopper, "ball": _ball, "jump": _jump_first_nlp}
"""Plan name -> (problem, its own options)."""
UNVERIFIED = {"jump"}
"""Plans whose homotopy is cut: solved without the verification (their iterate is no plan)."""


def with_solver(options: Any, change: dict[str, Any]) -> Any:
    """`options` whose `Ipopt` has `change` applied (its `options` merged)."""
    nlp = options.nlp
    fields = dict(change)
    if "options" in fields:
        fields["options"] = {**nlp.options, **fields["options"]}
    return dataclasses.replace(options, nlp=dataclasses.replace(nlp, **fields))


def measure(plan: str, solver: str) -> dict:
    from tfcontact.ocp import Transcription, solve
    from tfcontact.ocp.contact import solve_contact, transcribe

    problem, options = PLANS[plan]()
    options = with_solver(options, SOLVERS[solver])
    start = time.perf_counter()
    if plan in UNVERIFIED:
        ocp_problem, _ = transcribe(problem)
        ocp = solve(ocp_problem, discretization=Transcription(
            scheme=options.scheme, n_finite_elements=options.n_finite_elements,
            method=options.method), relaxation=options.relaxation, homotopy=options.homotopy,
            nlp=options.nlp, verbose=False, throw=False)
        status, deviation = f"cut ({ocp.status.name.lower()})", math.nan
    else:
        result = solve_contact(problem, options, verbose=False, throw=False)
        ocp, status = result.ocp, result.status
        deviation = result.verification.end_state_deviation
    wall = time.perf_counter() - start
    steps = ocp.mpcc_result.history
    iterations = sum(s.iterations for s in steps)
    evaluation = sum(s.evaluation_seconds for s in steps)
    solving = sum(s.seconds for s in steps)
    per = max(iterations, 1)
    return {"plan": plan, "solver": solver, "status": status, "NLPs": len(steps),
            "iterations": iterations, "wall [s]": wall,
            "ms/iter eval": 1e3 * evaluation / per,
            "ms/iter IPOPT": 1e3 * (solving - evaluation) / per,
            "deviation": deviation}


COLUMNS = ("plan", "solver", "status", "NLPs", "iterations", "wall [s]", "ms/iter eval",
           "ms/iter IPOPT", "deviation", "wall / mumps")


def row(m: dict) -> str:
    def cell(key: str) -> str:
        value = m[key]
        if key == "deviation":
            return f"{value:.1e}"
        return f"{value:.2f}" if isinstance(value, float) else str(value)

    return "| " + " | ".join(cell(c) for c in COLUMNS) + " |"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", nargs="+", choices=sorted(PLANS), default=list(PLANS),
                        metavar="PLAN", help=f"default: {', '.join(PLANS)}")
    parser.add_argument("--solvers", nargs="+", choices=sorted(SOLVERS),
                        default=list(SOLVERS), metavar="SOLVER",
                        help=f"default: {', '.join(SOLVERS)}")
    parser.add_argument("--out", type=Path, default=None, help="write the table here")
    args = parser.parse_args(argv)
    solvers = args.solvers if "mumps" in args.solvers else ["mumps", *args.solvers]
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    print("\n".join(lines), flush=True)
    for plan in args.plans:
        reference = math.nan
        for solver in solvers:
            m = measure(plan, solver)
            if solver == "mumps":
                reference = m["wall [s]"]
            m["wall / mumps"] = m["wall [s]"] / reference
            lines.append(row(m))
            print(lines[-1], flush=True)
    text = (f"Measured {datetime.date.today()} on {platform.node()} "
            f"({platform.processor() or platform.machine()}), one solve at a time:\n\n"
            + "\n".join(lines) + "\n")
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
