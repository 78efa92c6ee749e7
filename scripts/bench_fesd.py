# /// script
# requires-python = ">=3.11,<3.12"
# dependencies = ["tfcontact", "matplotlib"]
# ///
"""Speed against accuracy of FESD and the standard discretisation (and nosnoc_py, if installed).

The test problem of [FESD] section 4.4 (Nurkanovic et al., Numer. Math. 2024):
x' = A1 x for |x|^2 < 1, A2 x otherwise, A1,2 = [[1, +-w], [-+w, 1]], w = 2 pi,
x(0) = (1/e, 0), a crossing of the unit circle at t_s = 1, T = pi/2, N_FE = 2 finite
elements per step, a varying number of steps. The reference x(T) is in closed form:
x(T) = e^(T - 1) (cos w(T - 1), sin w(T - 1)).

For each method and stage count: CPU time (process time, build included) against the
global error |x(T) - x_ref(T)|, one run per point. Writes benchmarks/fesd_speed_accuracy.png
and benchmarks/fesd_speed_accuracy.md.

    python scripts/bench_fesd.py            # about 2 minutes
"""

from __future__ import annotations

import argparse
import datetime
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from tfcontact.fesd import Fesd, RadauIIA, Standard, StewartSystem, simulate  # noqa: E402
from tfcontact.mpcc import Homotopy, Ipopt, L1Penalty, Scholtes  # noqa: E402

W = 2 * np.pi
T = np.pi / 2
X0 = np.array([np.exp(-1), 0.0])
X_REF = np.exp(T - 1) * np.array([np.cos(W * (T - 1)), np.sin(W * (T - 1))])
COMP_TOL = 1e-12


def circle_system() -> StewartSystem:
    x = ca.SX.sym("x", 2)
    a1 = ca.DM([[1, W], [-W, 1]])
    a2 = ca.DM([[1, -W], [W, 1]])
    return StewartSystem.from_sign_matrix(x, ca.SX(0, 1), ca.horzcat(a1 @ x, a2 @ x),
                                          ca.sumsqr(x) - 1, np.array([[-1], [1]]))


@dataclass
class Point:
    curve: str
    stages: int
    n_steps: int
    h: float
    error: float
    cpu: float
    n_nlps: int
    ok: bool


def run_tfcontact(curve: str, stages: int, n_steps: int, method, relaxation) -> Point:
    start = time.process_time()
    result = simulate(circle_system(), X0, horizon=T, n_steps=n_steps, scheme=RadauIIA(stages),
                      n_finite_elements=2, method=method, relaxation=relaxation,
                      homotopy=Homotopy(tolerance=COMP_TOL), nlp=Ipopt(tol=COMP_TOL),
                      throw=False)
    cpu = time.process_time() - start
    return Point(curve, stages, n_steps, T / (2 * n_steps),
                 float(np.linalg.norm(result.x[-1] - X_REF)), cpu, result.n_nlps, result.success)


def run_nosnoc(stages: int, n_steps: int) -> Point:
    import nosnoc

    x = ca.SX.sym("x", 2)
    a1 = ca.DM([[1, W], [-W, 1]])
    a2 = ca.DM([[1, -W], [W, 1]])
    start = time.process_time()
    model = nosnoc.NosnocModel(x=x, F=[ca.horzcat(a1 @ x, a2 @ x)], c=[ca.sumsqr(x) - 1],
                               S=[np.array([[-1], [1]])], x0=X0)
    opts = nosnoc.NosnocOpts()
    opts.n_s = stages
    opts.N_finite_elements = 2
    opts.N_stages = 1
    opts.terminal_time = T / n_steps
    opts.comp_tol = COMP_TOL
    opts.print_level = 0
    solver = nosnoc.NosnocSolver(opts, model)
    looper = nosnoc.NosnocSimLooper(solver, X0, n_steps, print_level=0)
    looper.run()
    res = looper.get_results()
    cpu = time.process_time() - start
    ok = all(s == nosnoc.Status.SUCCESS for s in res["status"])
    n_nlps = int(np.count_nonzero(res["cpu_nlp"]))
    return Point("nosnoc_py 0.2.0 FESD (Scholtes)", stages, n_steps, T / (2 * n_steps),
                 float(np.linalg.norm(res["X_sim"][-1] - X_REF)), cpu, n_nlps, ok)


def slope(points: list[Point]) -> float:
    h = np.array([p.h for p in points])
    e = np.array([p.error for p in points])
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="benchmarks", help="output directory")
    parser.add_argument("--quick", action="store_true", help="fewer points (smoke run)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    sweeps = {  # stages -> numbers of steps (a decade of h where affordable)
        1: (160, 320, 640, 1600),
        2: (10, 20, 40, 100),
        3: (5, 10, 20, 50),
    }
    if args.quick:
        sweeps = {2: (10, 20), 3: (5, 10)}
    configs = []
    for s, ns in sweeps.items():
        configs.append(("tfcontact FESD (l1 penalty)", s, ns, Fesd(), L1Penalty()))
    configs.append(("tfcontact FESD (Scholtes)", 2, sweeps[2], Fesd(), Scholtes()))
    for s in (2, 3):
        if s in sweeps:
            configs.append(("tfcontact Standard (l1 penalty)", s,
                            (10, 20, 40, 100, 200)[: 2 if args.quick else 5],
                            Standard(), L1Penalty()))

    points: list[Point] = []
    for curve, s, ns, method, relaxation in configs:
        for n in ns:
            p = run_tfcontact(curve, s, n, method, relaxation)
            points.append(p)
            print(f"{curve:34s} s={s} n={n:5d} h={p.h:.2e} err={p.error:.3e} "
                  f"cpu={p.cpu:.2f}s nlps={p.n_nlps} ok={p.ok}", flush=True)
    nosnoc_note = ""
    try:
        import nosnoc  # noqa: F401

        for s, ns in ((2, sweeps[2]),):
            for n in ns:
                p = run_nosnoc(s, n)
                points.append(p)
                print(f"{p.curve:34s} s={s} n={n:5d} h={p.h:.2e} err={p.error:.3e} "
                      f"cpu={p.cpu:.2f}s nlps={p.n_nlps} ok={p.ok}", flush=True)
    except ImportError as exc:
        nosnoc_note = f"nosnoc_py could not be imported ({exc}); its curve is missing."

    # chart
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    keys = sorted({(p.curve, p.stages) for p in points})
    markers = {"FESD (l1": "o", "FESD (Sch": "s", "Standard": "x", "nosnoc": "^"}
    for curve, s in keys:
        pts = sorted([p for p in points if (p.curve, p.stages) == (curve, s)], key=lambda p: p.h,
                     reverse=True)
        marker = next((m for k, m in markers.items() if k in curve), ".")
        ls = "--" if "Standard" in curve else (":" if "nosnoc" in curve else "-")
        ax.loglog([p.cpu for p in pts], [p.error for p in pts], ls, marker=marker,
                  label=f"{curve}, Radau IIA s={s}")
    ax.set_xlabel("CPU time [s] (build + all steps)")
    ax.set_ylabel("global error |x(T) - x_ref(T)|")
    ax.set_title("FESD order test problem [FESD 4.4], N_FE = 2, varying number of steps")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    png = out / "fesd_speed_accuracy.png"
    fig.savefig(png, dpi=120)

    # table
    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# FESD speed against accuracy",
        "",
        f"Command: `python scripts/bench_fesd.py{' --quick' if args.quick else ''}`  ",
        f"Date: {date}; {platform.machine()}, Python {platform.python_version()}, "
        f"CasADi {ca.__version__} (IPOPT + MUMPS); machine shared with other jobs, "
        "times are process CPU times of one run.",
        "",
        "Problem: [FESD] section 4.4 (x' = A1 x inside the unit circle, A2 x outside, "
        "w = 2 pi, x(0) = (1/e, 0), switch at t = 1, T = pi/2), N_FE = 2 per step, "
        f"complementarity and IPOPT tolerance {COMP_TOL:g}, reference in closed form.",
        "",
        "![chart](fesd_speed_accuracy.png)",
        "",
        "## Fitted orders (slope of log error against log h)",
        "",
        "| curve | stages | expected | fitted slope |",
        "|---|---|---|---|",
    ]
    for curve, s in keys:
        pts = [p for p in points if (p.curve, p.stages) == (curve, s)]
        expected = "1" if "Standard" in curve else str(2 * s - 1)
        lines.append(f"| {curve} | {s} | {expected} | {slope(pts):.2f} |")
    lines += ["", "## Points", "",
              "| curve | stages | steps | h [s] | error | CPU [s] | NLPs | converged |",
              "|---|---|---|---|---|---|---|---|"]
    for p in points:
        lines.append(f"| {p.curve} | {p.stages} | {p.n_steps} | {p.h:.3e} | {p.error:.3e} | "
                     f"{p.cpu:.2f} | {p.n_nlps} | {p.ok} |")
    if nosnoc_note:
        lines += ["", nosnoc_note]
    else:
        lines += ["", "nosnoc_py 0.2.0 (`pip install nosnoc==0.2.0`): default options "
                  "(Radau IIA, Scholtes relaxation, sigma_0 = 1, kappa = 0.1, heuristic step "
                  f"equilibration) with comp_tol = {COMP_TOL:g}, NosnocSimLooper; NLP count from "
                  "its per-NLP CPU times."]
    (out / "fesd_speed_accuracy.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {png} and {out / 'fesd_speed_accuracy.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
