"""Legged plans with several 3-D frictional contacts: size, iterations and where the time
goes, one plan at a time in one run (issue 30, benchmarks/legged.md).

    python scripts/bench_legged.py --pyramid    # quadruped-jump-fesd's first NLP: cone
                                                # at eps_t 1e-7 and 1e-3, and the pyramid
    python scripts/bench_legged.py quadruped-jump-fesd --eps-t 1e-3 --nlps 0 \
        --out benchmarks/legged.md
    python scripts/bench_legged.py biped-walk --whole    # the whole plan, stage by stage
    python scripts/bench_legged.py quadruped-jump --whole

Per task, friction model (`Task.friction_model`) and, for the cone, stick speed eps_t
(`ContactEntry.eps_t`, set for every contact): DoF,
contacts, NLP variables, constraints, complementarity pairs and constraint-Jacobian
nonzeros; the NLPs solved (`--nlps K` stops the homotopy after K, 0: the task's whole
homotopy), their IPOPT iterations and statuses, milliseconds per iteration split into
CasADi's function evaluations and the rest (IPOPT's own work, mostly MUMPS), the NLP
build, solve and verification times (the multi-contact exact-impact replay, no FESD
fallback), the plan's status and its goals. A cut homotopy is reported as such and not
verified: its iterate is no plan.

`--whole` runs each named plan as `tfcontact plan NAME` does (every stage, its files
written to a temporary folder) and reports its status, goals, the IPOPT iterations of
the discovery and of the exact re-solve, each stage's seconds (summary.json's `stages`),
the process's CPU seconds for the plan (all its threads) and its peak resident memory
(the peak so far: run one plan per process for each plan's own).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling bench_tasks
from bench_tasks import markdown_table, report  # noqa: E402

COLUMNS = ("task", "friction", "eps_t [m/s]", "DoF", "contacts", "variables", "constraints",
           "compl. pairs", "Jacobian nnz", "NLPs", "iterations", "IPOPT statuses",
           "ms/iter eval", "ms/iter IPOPT+MUMPS", "NLP build [s]", "solve [s]",
           "verify [s]", "status", "goals met")


def measure(name: str, eps_t: float | None, nlps: int, friction: str | None = None) -> dict:
    """One task, solved once (module docstring); `eps_t`, `friction`: None keeps the
    task's own."""
    import casadi as ca

    from tfcontact.ocp import Transcription, solve
    from tfcontact.ocp.contact import solve_contact, transcribe
    from tfcontact.task import build_task, load_task, shipped_tasks
    from tfcontact.verify import MultiContactReplay, VerifyOptions

    task = load_task(shipped_tasks().get(name, name))
    if eps_t is not None:
        task = dataclasses.replace(task, contacts=tuple(
            dataclasses.replace(c, eps_t=eps_t) for c in task.contacts))
    if friction is not None:
        task = dataclasses.replace(task, friction_model=friction)
    setup = build_task(task)
    options = setup.options
    if nlps > 0:  # a cut homotopy: its plan is no plan, so it is not verified
        ocp_problem, _ = transcribe(setup.problem)
        ocp = solve(ocp_problem, discretization=Transcription(
            scheme=options.scheme, n_finite_elements=options.n_finite_elements,
            method=options.method), relaxation=options.relaxation,
            homotopy=dataclasses.replace(options.homotopy, max_nlps=nlps), nlp=options.nlp,
            verbose=True, throw=False)
        timings = {"build": ocp.build_time, "solve": ocp.solve_time, "verify": math.nan}
        status, goals = f"cut after {nlps} NLPs", "-"
    else:
        result = solve_contact(setup.problem, dataclasses.replace(
            options, attempts=1, verify=VerifyOptions(replay=MultiContactReplay())),
            verbose=True, throw=False)
        ocp, timings = result.ocp, result.timings
        status, goals = result.status, result.task.passed
    mpcc = ocp.build.mpcc
    steps = ocp.mpcc_result.history
    iterations = sum(s.iterations for s in steps)
    evaluation = sum(s.evaluation_seconds for s in steps)
    solving = sum(s.seconds for s in steps)
    per = max(iterations, 1)
    return {"task": task.name, "friction": task.friction_model,
            "eps_t [m/s]": "- (unused)" if task.friction_model == "pyramid" else
            ", ".join(sorted({f"{c.eps_t:g}" for c in task.contacts})),
            "DoF": setup.robot.nv,
            "contacts": len(task.contacts), "variables": mpcc.w.numel(),
            "constraints": mpcc.g.numel(), "compl. pairs": mpcc.n_comp,
            "Jacobian nnz": ca.jacobian(mpcc.g, mpcc.w).nnz(), "NLPs": len(steps),
            "iterations": " + ".join(str(s.iterations) for s in steps),
            "IPOPT statuses": ", ".join(s.ipopt_status for s in steps),
            "ms/iter eval": 1e3 * evaluation / per,
            "ms/iter IPOPT+MUMPS": 1e3 * (solving - evaluation) / per,
            "NLP build [s]": timings["build"], "solve [s]": timings["solve"],
            "verify [s]": timings["verify"], "status": status, "goals met": goals}


WHOLE_COLUMNS = ("plan", "status", "goals met", "discovery iterations",
                 "re-solve iterations", "discover [s]", "re-solve [s]", "collisions [s]",
                 "files [s]", "total [s]", "CPU [s]", "peak memory [GB]")


def measure_whole(name: str) -> dict:
    """The whole plan `name`, run once as the command line runs it (module docstring)."""
    import json
    import resource
    import tempfile
    import time

    from tfcontact.scenes.plans import run_plan

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "plan"
        cpu = time.process_time()
        run_plan(name, out, verbose=True)
        cpu = time.process_time() - cpu
        summary = json.loads((out / "summary.json").read_text())
        sidecar = out / "trajectory.json"
        solver = json.loads(sidecar.read_text()).get("solver", {}) if sidecar.exists() else {}
    seconds = {s["stage"]: s["seconds"] for s in summary["stages"]}
    resolved = "discovery" in solver  # an exact re-solve's sidecar names its discovery
    discovery = solver["discovery"] if resolved else solver
    checks = summary.get("task_checks") or {}
    return {"plan": name, "status": summary["status"],
            "goals met": checks.get("passed", "-"),
            "discovery iterations": discovery.get("iterations", "-"),
            "re-solve iterations": solver.get("iterations", "-") if resolved else "-",
            "discover [s]": seconds.get("discover", math.nan),
            "re-solve [s]": next((v for k, v in seconds.items() if "re-solve" in k),
                                 math.nan),
            "collisions [s]": seconds.get("collision check", math.nan),
            "files [s]": next((v for k, v in seconds.items() if k.startswith("files")),
                              math.nan),
            "total [s]": summary["wall_time"],
            # all the process's threads (CasADi's, the BLAS's): the figure to compare when
            # other jobs share the cores
            "CPU [s]": cpu,
            # ru_maxrss is in KiB on Linux: the process's peak so far
            "peak memory [GB]": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def table(rows: list[dict]) -> str:
    return markdown_table(COLUMNS, rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=["quadruped-jump-fesd"],
                        help="shipped task names or task files")
    parser.add_argument("--eps-t", type=float, nargs="+", default=[1e-7, 1e-3],
                        help="stick speeds of the cone to compare [m/s]")
    parser.add_argument("--pyramid", action="store_true",
                        help="also the inscribed pyramid (`friction_model = pyramid`)")
    parser.add_argument("--nlps", type=int, default=1,
                        help="NLPs of the homotopy to solve (0: all)")
    parser.add_argument("--whole", action="store_true",
                        help="run each plan whole, stage by stage (no variants)")
    parser.add_argument("--out", type=Path, default=None, help="write the table here")
    args = parser.parse_args(argv)
    if args.whole:
        rows = [measure_whole(name) for name in args.names]
        report(markdown_table(WHOLE_COLUMNS, rows), "plan", args.out)
        return 0
    rows = []
    for name in args.names:
        variants = [(eps_t, "cone") for eps_t in args.eps_t]
        variants += [(None, "pyramid")] if args.pyramid else []
        for eps_t, friction in variants:
            rows.append(measure(name, eps_t, args.nlps, friction))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    report(table(rows), "plan", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
