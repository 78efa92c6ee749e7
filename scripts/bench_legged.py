"""Legged plans with several 3-D frictional contacts: size, iterations and where the time
goes, one plan at a time in one run (issue 30, benchmarks/legged.md).

    python scripts/bench_legged.py                         # quadruped-jump, eps_t 1e-7 and 1e-3
    python scripts/bench_legged.py quadruped-jump --eps-t 1e-3 --nlps 0 --out benchmarks/legged.md

Per task and stick speed eps_t (`ContactEntry.eps_t`, set for every contact): DoF,
contacts, NLP variables, constraints, complementarity pairs and constraint-Jacobian
nonzeros; the NLPs solved (`--nlps K` stops the homotopy after K, 0: the task's whole
homotopy), their IPOPT iterations and statuses, milliseconds per iteration split into
CasADi's function evaluations and the rest (IPOPT's own work, mostly MUMPS), the NLP
build, solve and verification times (the multi-contact exact-impact replay, no FESD
fallback), the plan's status and its goals. A cut homotopy is reported as such: its status
says nothing about the plan.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import platform
import time
from pathlib import Path

COLUMNS = ("task", "eps_t [m/s]", "DoF", "contacts", "variables", "constraints",
           "compl. pairs", "Jacobian nnz", "NLPs", "iterations", "IPOPT statuses",
           "ms/iter eval", "ms/iter IPOPT+MUMPS", "NLP build [s]", "solve [s]",
           "verify [s]", "status", "goals met")


def measure(name: str, eps_t: float, nlps: int) -> dict:
    """One task with every contact's eps_t set, solved once (module docstring)."""
    import casadi as ca

    from tfcontact.ocp.contact import solve_contact
    from tfcontact.task import build_task, load_task, shipped_tasks
    from tfcontact.verify import MultiContactReplay, VerifyOptions

    task = load_task(shipped_tasks().get(name, name))
    task = dataclasses.replace(task, contacts=tuple(
        dataclasses.replace(c, eps_t=eps_t) for c in task.contacts))
    setup = build_task(task)
    options = setup.options
    homotopy = options.homotopy
    if nlps > 0:
        homotopy = dataclasses.replace(homotopy, max_nlps=nlps)
    options = dataclasses.replace(options, attempts=1, homotopy=homotopy,
                                  verify=VerifyOptions(replay=MultiContactReplay()))
    start = time.perf_counter()
    result = solve_contact(setup.problem, options, verbose=True, throw=False)
    wall = time.perf_counter() - start
    mpcc = result.ocp.build.mpcc
    steps = result.ocp.mpcc_result.history
    iterations = sum(s.iterations for s in steps)
    evaluation = sum(s.evaluation_seconds for s in steps)
    solving = sum(s.seconds for s in steps)
    per = max(iterations, 1)
    cut = nlps > 0 and len(steps) >= nlps
    return {"task": task.name, "eps_t [m/s]": f"{eps_t:g}", "DoF": setup.robot.nv,
            "contacts": len(task.contacts), "variables": mpcc.w.numel(),
            "constraints": mpcc.g.numel(), "compl. pairs": mpcc.n_comp,
            "Jacobian nnz": ca.jacobian(mpcc.g, mpcc.w).nnz(), "NLPs": len(steps),
            "iterations": iterations,
            "IPOPT statuses": ", ".join(s.ipopt_status for s in steps),
            "ms/iter eval": 1e3 * evaluation / per,
            "ms/iter IPOPT+MUMPS": 1e3 * (solving - evaluation) / per,
            "NLP build [s]": result.timings["build"], "solve [s]": result.timings["solve"],
            "verify [s]": result.timings["verify"],
            "status": f"cut after {nlps} NLPs" if cut else result.status,
            "goals met": "-" if cut else result.task.passed, "wall [s]": wall}


def table(rows: list[dict]) -> str:
    def cell(value: object) -> str:
        return f"{value:.2f}" if isinstance(value, float) else str(value)

    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    lines += ["| " + " | ".join(cell(row[c]) for c in COLUMNS) + " |" for row in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=["quadruped-jump"],
                        help="shipped task names or task files")
    parser.add_argument("--eps-t", type=float, nargs="+", default=[1e-7, 1e-3],
                        help="stick speeds to compare [m/s]")
    parser.add_argument("--nlps", type=int, default=1,
                        help="NLPs of the homotopy to solve (0: all)")
    parser.add_argument("--out", type=Path, default=None, help="write the table here")
    args = parser.parse_args(argv)
    rows = []
    for name in args.names:
        for eps_t in args.eps_t:
            rows.append(measure(name, eps_t, args.nlps))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    text = (f"Measured {datetime.date.today()} on {platform.node()} "
            f"({platform.processor() or platform.machine()}), one plan at a time:\n\n"
            + table(rows) + "\n")
    print(text)
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
