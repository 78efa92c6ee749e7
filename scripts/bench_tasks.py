"""Build and solve times of the shipped task files, one after another in one run.

    python scripts/bench_tasks.py                        # every shipped task
    python scripts/bench_tasks.py hopper-step hopper-platform --out benchmarks/tasks.md

Per task: the task build (URDF load, symbolic twin, terrain, contact problem:
`build_task`), the NLP build and the solve (`solve_contact`, one attempt, the task's own
preset; a task with `[continuation]` first solves the task it continues and starts from
that plan, both counted), the verification and the coal collision check of the URDF's
bodies against the terrain; the status, whether the plan is verified and meets its
goals, and the build's share of the solve (issue 29 asks for below 20 %). Prints a
markdown table and writes it.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import platform
import time
from pathlib import Path

COLUMNS = ("task", "continues", "DoF", "contacts", "task build [s]", "NLP build [s]",
           "solve [s]", "build / solve", "IPOPT iterations", "verify [s]",
           "collision check [s]", "status", "verified", "goals met", "bodies clear")


def measure(name: str) -> dict:
    """One task, built and solved once (module docstring)."""
    from tfcontact.ocp.contact import solve_contact
    from tfcontact.scenes.pipeline import solve_continued
    from tfcontact.task import build_task, load_task, shipped_tasks
    from tfcontact.task.spec import PrimitiveTerrain
    from tfcontact.verify.collision import check_robot_collisions, terrain_obstacles

    task = load_task(shipped_tasks().get(name, name))
    start = time.perf_counter()
    setup = build_task(task)
    task_build = time.perf_counter() - start
    options = dataclasses.replace(setup.options, attempts=1)
    earlier_iterations = 0
    earlier = {"build": 0.0, "solve": 0.0, "verify": 0.0}
    if task.continuation is not None:  # the task it continues first, then from its plan
        start = time.perf_counter()
        other = build_task(task.continuation.task)
        task_build += time.perf_counter() - start
        before = solve_contact(other.problem, dataclasses.replace(other.options, attempts=1),
                               verbose=False, throw=False)
        earlier, earlier_iterations = before.timings, before.ocp.total_iterations
        result = solve_continued(setup.problem, options, before, task.continuation.sigma)
    else:
        result = solve_contact(setup.problem, options, verbose=False, throw=False)
    clear, collision_time = None, float("nan")
    if isinstance(task.terrain, PrimitiveTerrain):
        start = time.perf_counter()
        report = check_robot_collisions(setup.robot, result.physical.t, result.physical.q,
                                        terrain_obstacles(task.terrain.terrain))
        collision_time, clear = time.perf_counter() - start, report.passed
    nlp_build = earlier["build"] + result.timings["build"]
    solve = earlier["solve"] + result.timings["solve"]
    build = task_build + nlp_build
    return {"task": task.name,
            "continues": "-" if task.continuation is None else task.continuation.task.name,
            "DoF": setup.robot.nq, "contacts": len(task.contacts),
            "task build [s]": task_build, "NLP build [s]": nlp_build, "solve [s]": solve,
            "build / solve": f"{100 * build / solve:.0f} %",
            "IPOPT iterations": earlier_iterations + result.ocp.total_iterations,
            "verify [s]": earlier["verify"] + result.timings["verify"],
            "collision check [s]": collision_time,
            "status": result.status, "verified": result.verification.passed,
            "goals met": result.task.passed,
            "bodies clear": "flat ground" if clear is None else clear}


def markdown_table(columns: tuple[str, ...], rows: list[dict]) -> str:
    """A markdown table of `rows` (dicts by column), floats to 0.01 (bench_legged's too)."""
    def cell(value: object) -> str:
        return f"{value:.2f}" if isinstance(value, float) else str(value)

    lines = ["| " + " | ".join(columns) + " |", "|" + " --- |" * len(columns)]
    lines += ["| " + " | ".join(cell(row[c]) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def report(table: str, what: str, out: Path | None) -> None:
    """Print the measured `table` under the date and the machine, and write it to `out`."""
    text = (f"Measured {datetime.date.today()} on {platform.node()} "
            f"({platform.processor() or platform.machine()}), one {what} at a time:\n\n"
            + table + "\n")
    print(text)
    if out is not None:
        out.write_text(text)


def table(rows: list[dict]) -> str:
    return markdown_table(COLUMNS, rows)


def main(argv: list[str] | None = None) -> int:
    from tfcontact.task import shipped_tasks

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="shipped task names or task files "
                        "(default: every shipped task)")
    parser.add_argument("--out", type=Path, default=None, help="write the table here")
    args = parser.parse_args(argv)
    rows = []
    for name in args.names or sorted(shipped_tasks()):
        rows.append(measure(name))
        print(table(rows[-1:]).splitlines()[-1], flush=True)
    report(table(rows), "task", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
