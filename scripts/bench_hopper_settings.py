"""The hopper's solver settings side by side: solve time against the plan's accuracy.

Each variant changes one setting of `hopper_options()` (the settings of the README's
main job, `tfcontact plan hopper`) or one field of the task (`TASK_VARIANTS`) and plans
the short task from the start-everywhere guess. Accuracy is the verification's end-state
deviation: the plan's controls replayed in physical time with exact impacts (no
time-freezing). One run per variant, in one process, one after the other. Writes
benchmarks/hopper_settings.md and benchmarks/hopper_settings.png.

    python scripts/bench_hopper_settings.py          # about 9 minutes on a quiet machine
"""

from __future__ import annotations

import argparse
import datetime
import math
import platform
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from tfcontact.fesd import GaussLegendre, NoEquilibration, RadauIIA  # noqa: E402
from tfcontact.ocp.contact import ContactSolverOptions, solve_contact  # noqa: E402
from tfcontact.scenes.hopper import (  # noqa: E402
    HopperTask,
    hopper_options,
    hopper_problem,
    hopper_task,
)

Variant = Callable[[ContactSolverOptions], ContactSolverOptions]


def _ipopt(options: ContactSolverOptions, **extra: object) -> ContactSolverOptions:
    nlp = replace(options.nlp, options={**options.nlp.options, **extra})
    return replace(options, nlp=nlp)


VARIANTS: dict[str, Variant] = {
    "default (hopper_options)": lambda o: o,
    "cross complementarity per element": lambda o: replace(
        o, method=replace(o.method, cross_complementarity="element")),
    "gamma_h = 1 (elements may collapse)": lambda o: replace(
        o, method=replace(o.method, gamma_h=1.0)),
    "no step equilibration": lambda o: replace(
        o, method=replace(o.method, step_equilibration=NoEquilibration())),
    "4 finite elements per interval": lambda o: replace(o, n_finite_elements=4),
    "Radau IIA, 3 stages": lambda o: replace(o, scheme=RadauIIA(3)),
    "Gauss-Legendre, 2 stages": lambda o: replace(o, scheme=GaussLegendre(2)),
    "sigma_0 = 0.1": lambda o: replace(o, homotopy=replace(o.homotopy, sigma_0=0.1)),
    "IPOPT adaptive barrier": lambda o: _ipopt(o, mu_strategy="adaptive"),
    "stepping stones to IPOPT tol 0.1": lambda o: replace(
        o, nlp=replace(o.nlp, intermediate_tol=0.1)),
    "stepping stones to 0.1, adaptive barrier": lambda o: _ipopt(
        replace(o, nlp=replace(o.nlp, intermediate_tol=0.1)), mu_strategy="adaptive"),
}


# One field of the problem's `HopperTask` changed (the solver settings stay the default).
TASK_VARIANTS: dict[str, Callable[[HopperTask], HopperTask]] = {
    "unscaled gap (gap_scale = 1)": lambda t: replace(t, gap_scale=1.0),
}


def _unchanged(value):
    return value


def run(name: str, variant: Variant,
        task_variant: Callable[[HopperTask], HopperTask] = _unchanged) -> dict:
    _, _, problem = hopper_problem(task_variant(hopper_task("short")))
    # One solve per variant: the chart compares settings, not restarts.
    options = replace(variant(hopper_options("short")), attempts=1)
    start = time.perf_counter()
    result = solve_contact(problem, options, verbose=False)
    wall = time.perf_counter() - start
    v = result.verification
    defects = [d for d in v.local_defects if d is not None and math.isfinite(d)]
    row = {
        "name": name, "status": result.status, "wall": wall,
        "solve": result.timings["solve"], "nlps": result.ocp.n_nlps,
        "iterations": result.ocp.total_iterations, "residual": result.ocp.residual,
        "deviation": v.end_state_deviation, "defect": max(defects) if defects else math.nan,
        "cost": result.ocp.cost, "gap_end": float(result.physical.gaps[-1, 0]),
    }
    print(f"{name}: {row['status']}, {row['iterations']} iterations, {row['solve']:.1f} s of "
          f"solves, deviation {row['deviation']:.2e}", flush=True)
    return row


def chart(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in rows:
        ok = r["status"] == "converged"
        dev = r["deviation"] if math.isfinite(r["deviation"]) else 1e3
        ax.scatter(r["solve"], dev, marker="o" if ok else "x", color="C0" if ok else "C3")
        ax.annotate(r["name"], (r["solve"], dev), fontsize=7, xytext=(4, 2),
                    textcoords="offset points")
    ax.axhline(5e-2, color="gray", lw=0.8, ls="--")
    ax.text(ax.get_xlim()[0], 5e-2, " verification tolerance", fontsize=7, va="bottom")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("NLP solves [s]")
    ax.set_ylabel("end-state deviation from the exact-impact replay")
    ax.set_title("Hopper, short task: one setting changed at a time (o verified, x failed)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def table(rows: list[dict]) -> str:
    lines = [
        f"# Hopper settings: solve time against accuracy ({datetime.date.today()}, "
        f"{platform.machine()}, 2 cores)", "",
        "Command: `python scripts/bench_hopper_settings.py` (short task of "
        "`tfcontact plan hopper`, start-everywhere guess, one setting of `hopper_options()` "
        "or of the task changed per row, one run each, in one process).", "",
        "| setting | status | NLPs | IPOPT iterations | NLP solves [s] | compl. residual "
        "| end-state deviation | largest local defect | cost | foot gap at T [mm] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['name']} | {r['status']} | {r['nlps']} | {r['iterations']} | "
            f"{r['solve']:.1f} | {r['residual']:.1e} | {r['deviation']:.1e} | "
            f"{r['defect']:.1e} | {r['cost']:.4g} | {1e3 * r['gap_end']:.1f} |")
    lines += ["", "![hopper settings](hopper_settings.png)", ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks", help="folder of the table and chart")
    parser.add_argument("--only", nargs="*", help="run only these variants (by name)")
    args = parser.parse_args()
    known = [*VARIANTS, *TASK_VARIANTS]
    names = args.only or known
    unknown = [n for n in names if n not in known]
    if unknown:
        parser.error(f"unknown variants {unknown}; known: {known}")
    rows = [run(name, VARIANTS.get(name, _unchanged), TASK_VARIANTS.get(name, _unchanged))
            for name in names]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    chart(rows, out / "hopper_settings.png")
    text = table(rows)
    (out / "hopper_settings.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
