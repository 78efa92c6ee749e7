"""Run the three ball/particle plans and tabulate them in benchmarks/plans_particles.md.

Each plan script writes its trajectory, figures and `summary.json` into
benchmarks/plans_particles/<name>/; this script runs them one after the other (each
prints its own summary) and writes the table from the `summary.json` files. With
`--table-only` it only rebuilds the table from the existing files.

    python scripts/bench_plans_particles.py [--table-only]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "plans_particles"
RUNS = {
    "ball_in_box_w1": ("TF-2 box, w = pi (no wall expected)",
                       ["scripts/plan_ball_in_box.py", "--omega", "1"]),
    "ball_in_box_w3": ("TF-2 box, w = 3 pi (bounces expected)",
                       ["scripts/plan_ball_in_box.py", "--omega", "3"]),
    "throwing_ball": ("TF-1 throwing ball, e = 0.9", ["scripts/plan_throwing_ball.py"]),
    "particle_friction": ("TF-3 inelastic particle, mu = 0.6",
                          ["scripts/plan_particle_friction.py"]),
}


def table() -> str:
    rows = ["| plan | status | objective | NLPs | IPOPT iter. | compl. residual | build [s] "
            "| solve [s] | impacts | end-state dev. | min gap [m] | cone viol. [N s] "
            "| dissip. viol. [N s] | largest local defect |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, (label, _) in RUNS.items():
        path = OUT / name / "summary.json"
        if not path.exists():
            rows.append(f"| {label} | not run | | | | | | | | | | | | |")
            continue
        s = json.loads(path.read_text())
        v = s["verification"]
        dev = v["end_state_deviation"]
        dissipation = v.get("dissipation_violation")  # absent from older summaries
        defects = [d for d in v.get("local_defects", []) if d is not None and math.isfinite(d)]
        defect = f"{max(defects):.1e}" if defects else "not computed"
        rows.append(
            f"| {label} | {s['status']} | {s['objective']:.4g} | {s['nlp_count']} | "
            f"{s['iterations']} | {s['complementarity_residual']:.1e} | "
            f"{s['timings']['build']:.1f} | {s['timings']['solve']:.1f} | "
            f"{len(s['impact_times'])} | {'failed' if dev is None else f'{dev:.1e}'} | "
            f"{v['min_gap']:.1e} | {v['friction_cone_violation']:.1e} | "
            f"{'not checked' if dissipation is None else f'{dissipation:.1e}'} | {defect} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table-only", action="store_true")
    args = parser.parse_args(argv)
    if not args.table_only:
        for name, (_, cmd) in RUNS.items():
            subprocess.run([sys.executable, *cmd, "--quiet", "--out", str(OUT / name)],
                           cwd=ROOT, check=False)
    text = (OUT.parent / "plans_particles.md")
    body = text.read_text() if text.exists() else ""
    marker = "<!-- table -->"
    head, _, tail = body.partition(marker)
    tail = tail.split("<!-- /table -->", 1)[-1] if tail else ""
    text.write_text(f"{head}{marker}\n{table()}\n<!-- /table -->{tail}")
    print(table())
    return 0


if __name__ == "__main__":
    sys.exit(main())
