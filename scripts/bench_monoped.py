"""TF-9's monoped planned stage by stage: where the time and the memory go, for each route
of differentiating the exact re-solves, side by side in one run (benchmarks/monoped_bench.md).

    python scripts/bench_monoped.py --task reduced --out benchmarks/monoped_bench_reduced.md
    python scripts/bench_monoped.py --task full --routes element

Each route runs `tfcontact plan monoped --task TASK` in a child process of its own, one
after the other: "element" (the shipped `monoped_exact.RESOLVE_DERIVATIVES`: the
re-solves' shooting steps or collocation elements, contact and path rows differentiated
once, evaluated on two threads) and "plain" (CasADi differentiates each whole NLP, the route before
2026-11-28). Per step of the plan (the discovery, each re-solve level, each schedule
candidate): IPOPT iterations, seconds, of which the build (the NLP and its derivatives)
and IPOPT (of which CasADi's evaluations; the rest is IPOPT's own, mostly MUMPS), the NLP's
variables, the process's peak memory during the step, objective and status. Per route:
the plan's status, wall time and the child's peak memory; then the routes' ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling bench_tasks
from bench_tasks import markdown_table, report  # noqa: E402

ROUTES = {"element": None, "plain": {}}  # None: the shipped RESOLVE_DERIVATIVES
STEP_COLUMNS = ("route", "step", "iterations", "seconds", "build [s]", "IPOPT [s]",
                "evaluations [s]", "variables", "peak [GB]", "objective", "status")
PLAN_COLUMNS = ("route", "status", "objective", "wall [s]", "peak memory [GB]")


def child(route: str, task: str, out: Path) -> int:
    """Run the plan with `route`'s derivatives (in this process)."""
    import tfcontact.scenes.monoped_exact as monoped_exact
    from tfcontact.cli import main

    if ROUTES[route] is not None:
        monoped_exact.RESOLVE_DERIVATIVES = ROUTES[route]
    return main(["plan", "monoped", "--task", task, "--out", str(out), "--force"])


def measure(route: str, task: str) -> tuple[dict, list[dict]]:
    """One route's plan in a child process: (the plan's row, its steps' rows)."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "plan"
        begin = time.perf_counter()
        process = subprocess.Popen([sys.executable, __file__, "--child", route, "--task", task,
                                    "--out", str(out)])
        _, _, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - begin
        summary = json.loads((out / "summary.json").read_text())
        trajectory = out / "trajectory.json"
        solver = json.loads(trajectory.read_text()).get("solver", {}) \
            if trajectory.exists() else {}
    return rows(route, summary, solver, wall, usage.ru_maxrss / 2**20)  # KiB on Linux


def rows(route: str, summary: dict, solver: dict, wall: float, peak: float
         ) -> tuple[dict, list[dict]]:
    """The plan's row and its steps' rows from its summary.json and its trajectory's
    `solver` entry (the chain's steps), its wall time [s] and the child's maxrss [GB]."""
    plan = {"route": route, "status": summary["status"],
            "objective": solver.get("objective", "-"), "wall [s]": wall,
            "peak memory [GB]": peak}

    def value(entries: dict | None, key: str) -> str | float | int:
        return "-" if not entries or entries.get(key) is None else entries[key]

    steps = [{"route": route, "step": step["name"], "iterations": step["iterations"],
              "seconds": float(step["seconds"]), "build [s]": value(step["timing"], "build"),
              "IPOPT [s]": value(step["timing"], "ipopt"),
              "evaluations [s]": value(step["timing"], "evaluations"),
              "variables": value(step["timing"], "n_variables"),
              "peak [GB]": value(step, "peak_memory"),
              "objective": f"{step['objective']:.6g}", "status": step["status"]}
             for step in solver.get("steps", [])]
    # the chain resets the process's high-water mark before each step (and the child's
    # maxrss with it): the plan's peak is the largest of the steps' and what came after
    plan["peak memory [GB]"] = max([peak] + [s["peak [GB]"] for s in steps
                                             if isinstance(s["peak [GB]"], float)])
    return plan, steps


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=("reduced", "full", "hand-set"), default="reduced")
    parser.add_argument("--routes", default="element,plain",
                        help=f"comma-separated, of {', '.join(ROUTES)}")
    parser.add_argument("--out", type=Path, default=None, help="write the tables here")
    parser.add_argument("--child", choices=tuple(ROUTES), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return child(args.child, args.task, args.out)
    routes = args.routes.split(",")
    unknown = sorted(set(routes) - set(ROUTES))
    if unknown:
        parser.error(f"unknown routes {unknown}: choose from {', '.join(ROUTES)}")
    plans, steps = [], []
    for route in routes:
        plan, route_steps = measure(route, args.task)
        plans.append(plan)
        steps += route_steps
        print(markdown_table(PLAN_COLUMNS, plans[-1:]).splitlines()[-1], flush=True)
    text = (f"`tfcontact plan monoped --task {args.task}`, per route:\n\n"
            + markdown_table(PLAN_COLUMNS, plans) + "\n\nPer step:\n\n"
            + markdown_table(STEP_COLUMNS, steps))
    if len(plans) > 1:
        first = plans[0]
        text += "\n\nRatios to the first route: " + "; ".join(
            f"{p['route']}: wall {p['wall [s]'] / first['wall [s]']:.2f}, peak memory "
            f"{p['peak memory [GB]'] / first['peak memory [GB]']:.2f}" for p in plans[1:])
    report(text, "route", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
