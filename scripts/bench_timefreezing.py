"""Time-freezing simulations: tfcontact against nosnoc_py 0.2.0, and FESD against Standard.

(a) A unit particle dropped from 1 m with horizontal speed 3 m/s onto ground with Coulomb
    friction mu = 0.2, inelastic (a_n = 10, as PROBLEMS.md TF-4), horizon 3.2 s of
    numerical time (1.61 s physical), 20 steps of 5 finite elements, Radau IIA with 2
    stages. It lands, slides and sticks (at 1.53 s). With a_n = 100 tfcontact's FESD step
    after the impact fails (IPOPT), see the report.
(b) A 1-D ball dropped from 1 m, restitution 0.8 (elastic time-freezing, k = 100), horizon
    3 s of numerical time (three impacts), 30 steps of 8 finite elements, Radau IIA with
    4 and with 2 stages.
(c) Convergence: (a) with a_n = 10 on [0, 1.6], FESD against the Standard discretisation,
    terminal error against step count and CPU time (benchmarks/timefreezing_convergence.png).

Error: max-norm of y(T) - y_exact(T), y = (q, v, t), against the exact time-freezing
solution (`tfcontact.scenes.particles.exact_sliding_particle`, `exact_bouncing_ball`);
the impact count is read from the clock (frozen pieces, `to_physical_time`).
nosnoc_py runs the same piecewise smooth systems through its public API
(`NosnocModel`, `NosnocSolver`, `NosnocSimLooper`; Heaviside step form for (a), Stewart for
(b)) with its defaults (Scholtes, sigma_0 = 1, kappa = 0.1) in the same process.

Usage:
    python scripts/bench_timefreezing.py             # everything, writes benchmarks/
    python scripts/bench_timefreezing.py --skip-nosnoc --out /tmp
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import platform
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tfcontact.fesd import RadauIIA, Standard, simulate  # noqa: E402
from tfcontact.mpcc import L1Penalty  # noqa: E402
from tfcontact.scenes.particles import (  # noqa: E402
    G,
    exact_bouncing_ball,
    exact_sliding_particle,
    point_mass,
)
from tfcontact.timefreezing import Elastic, time_freeze, to_physical_time  # noqa: E402

CASE_A = dict(height=1.0, vx0=3.0, mu=0.2, a_n=10.0, horizon=3.2, n_steps=20, n_fe=5)
CASE_B = dict(height=1.0, e=0.8, k=100.0, horizon=3.0, n_steps=30, n_fe=8)


def row(name, seconds, n_nlps, iterations, error, impacts, ok):
    return dict(name=name, seconds=seconds, n_nlps=n_nlps, iterations=iterations,
                error=error, impacts=impacts, ok=ok)


# ----------------------------------------------------------------------------- tfcontact


def tfcontact_a(relaxation=None, method=None, *, n_steps=None, n_fe=None, a_n=None,
                horizon=None):
    c = CASE_A | {k: v for k, v in dict(n_steps=n_steps, n_fe=n_fe, a_n=a_n,
                                           horizon=horizon).items() if v is not None}
    tf = time_freeze(point_mass(2, mu=c["mu"], a_n=c["a_n"]))
    y0 = tf.initial_state([0.0, c["height"]], [c["vx0"], 0.0])
    kwargs = {} if relaxation is None else {"relaxation": relaxation}
    if method is not None:
        kwargs["method"] = method
    start = time.perf_counter()
    res = simulate(tf.pss, y0, horizon=c["horizon"], n_steps=c["n_steps"],
                   n_finite_elements=c["n_fe"], scheme=RadauIIA(2), throw=False, **kwargs)
    seconds = time.perf_counter() - start
    exact = exact_sliding_particle(c["horizon"], height=c["height"], vx0=c["vx0"], mu=c["mu"],
                                   a_n=c["a_n"])
    impacts = len(to_physical_time(tf, res.t, res.x).impacts)
    return res, seconds, float(np.abs(res.x[-1] - exact).max()), impacts


def tfcontact_b(stages, relaxation=None):
    c = CASE_B
    tf = time_freeze(point_mass(1, restitution=c["e"]), method=Elastic(stiffness=c["k"]))
    y0 = tf.initial_state([c["height"]], [0.0])
    kwargs = {} if relaxation is None else {"relaxation": relaxation}
    start = time.perf_counter()
    res = simulate(tf.pss, y0, horizon=c["horizon"], n_steps=c["n_steps"],
                   n_finite_elements=c["n_fe"], scheme=RadauIIA(stages), throw=False, **kwargs)
    seconds = time.perf_counter() - start
    exact = exact_bouncing_ball(c["horizon"], height=c["height"], restitution=c["e"],
                                stiffness=c["k"])
    impacts = len(to_physical_time(tf, res.t, res.x).impacts)
    return res, seconds, float(np.abs(res.x[-1] - exact).max()), impacts


# ----------------------------------------------------------------------------- nosnoc_py


def nosnoc_run(model, x0, opts, n_steps):
    import nosnoc

    solver = nosnoc.NosnocSolver(opts, model)
    iterations = []
    solve = solver.solve

    def counting_solve():
        result = solve()
        iterations.append(sum(int(i) for i in result["nlp_iter"] if i is not None))
        return result

    solver.solve = counting_solve
    looper = nosnoc.NosnocSimLooper(solver, x0, n_steps)
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        looper.run()
    seconds = time.perf_counter() - start
    out = looper.get_results()
    n_nlps = int(np.count_nonzero(out["cpu_nlp"]))
    return out, seconds, n_nlps, sum(iterations)


def nosnoc_opts(stages, n_fe, step):
    import nosnoc

    opts = nosnoc.NosnocOpts()
    opts.n_s = stages
    opts.N_finite_elements = n_fe
    opts.N_stages = 1
    opts.terminal_time = step
    opts.irk_scheme = nosnoc.IrkSchemes.RADAU_IIA
    opts.print_level = 0
    opts.comp_tol = 1e-9
    return opts


def nosnoc_a():
    import nosnoc

    c = CASE_A
    q = ca.SX.sym("q", 2)
    v = ca.SX.sym("v", 2)
    t = ca.SX.sym("t")
    alpha = ca.SX.sym("alpha", 3)
    a1, a2, a3 = alpha[0], alpha[1], alpha[2]
    a_n, mu = c["a_n"], c["mu"]
    f_ode = ca.vertcat(v, 0, -G, 1)
    f_plus = ca.vertcat(0, 0, -mu * a_n, a_n, 0)
    f_minus = ca.vertcat(0, 0, mu * a_n, a_n, 0)
    inside = (1 - a1) * (1 - a2)
    rhs = (a1 + a2 - a1 * a2) * f_ode + inside * a3 * f_plus + inside * (1 - a3) * f_minus
    x0 = np.array([0.0, c["height"], c["vx0"], 0.0, 0.0])
    model = nosnoc.NosnocModel(x=ca.vertcat(q, v, t), x0=x0, c=[ca.vertcat(q[1], v[1], v[0])],
                               alpha=[alpha], f_x=[rhs], t_var=t)
    opts = nosnoc_opts(2, c["n_fe"], c["horizon"] / c["n_steps"])
    opts.pss_mode = nosnoc.PssMode.STEP
    opts.preprocess()
    out, seconds, n_nlps, iterations = nosnoc_run(model, x0, opts, c["n_steps"])
    x_end = out["X_sim"][-1]
    exact = exact_sliding_particle(c["horizon"], height=c["height"], vx0=c["vx0"], mu=mu,
                                   a_n=a_n)
    return out, seconds, n_nlps, iterations, float(np.abs(x_end - exact).max())


def nosnoc_b(stages):
    import nosnoc

    from tfcontact.timefreezing import elastic_damping

    c = CASE_B
    q, v, t = ca.SX.sym("q"), ca.SX.sym("v"), ca.SX.sym("t")
    damping = elastic_damping(c["e"], c["k"])
    modes = ca.horzcat(ca.vertcat(v, -G, 1), ca.vertcat(v, -c["k"] * q - damping * v, 0))
    x0 = np.array([c["height"], 0.0, 0.0])
    model = nosnoc.NosnocModel(x=ca.vertcat(q, v, t), x0=x0, F=[modes], c=[q],
                               S=[np.array([[1], [-1]])])
    opts = nosnoc_opts(stages, c["n_fe"], c["horizon"] / c["n_steps"])
    opts.preprocess()
    out, seconds, n_nlps, iterations = nosnoc_run(model, x0, opts, c["n_steps"])
    x_end = out["X_sim"][-1]
    exact = exact_bouncing_ball(c["horizon"], height=c["height"], restitution=c["e"],
                                stiffness=c["k"])
    return out, seconds, n_nlps, iterations, float(np.abs(x_end - exact).max())


def nosnoc_impacts(out, rate_tol=1e-3):
    """Frozen pieces from nosnoc's clock at its finite-element boundaries."""
    t = np.asarray(out["X_sim"])[:, -1]
    tau = np.asarray(out["t_grid"])
    frozen = (np.diff(t) <= rate_tol * np.diff(tau)) & (np.diff(tau) > 0)
    starts = np.flatnonzero(frozen[1:] & ~frozen[:-1]) + 1
    return int(starts.size + (1 if frozen[0] else 0))


# ----------------------------------------------------------------------------- convergence


def convergence(out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import ScalarFormatter

    steps = [4, 8, 16, 32]
    lines = ["| method | N | error | seconds | NLPs | converged |", "|---|---|---|---|---|---|"]
    series = (("FESD", None, None), ("Standard", Standard(), None),
              ("FESD, l1 penalty", None, L1Penalty()), ("Standard, l1 penalty", Standard(),
                                                        L1Penalty()))
    data = {}
    for name, method, relaxation in series:
        points = []
        for n in steps:
            res, seconds, err, _ = tfcontact_a(relaxation, method=method, n_steps=n, n_fe=2,
                                               a_n=10.0, horizon=1.6)
            lines.append(f"| {name} | {n} | {err:.2e} | {seconds:.2f} | {res.n_nlps} | "
                         f"{'yes' if res.success else 'NO (' + res.status.name + ')'} |")
            points.append((1.6 / n, seconds, err, res.success))
        data[name] = np.array(points)
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 3.8))
    for (name, *_), color in zip(series, ("C0", "C1", "C2", "C3"), strict=True):
        pts = data[name]
        ok = pts[:, 3] > 0
        style = "--" if "l1" in name else "-"
        axes[0].loglog(pts[ok, 0], pts[ok, 2], "o" + style, color=color, label=name)
        axes[1].loglog(pts[ok, 1], pts[ok, 2], "o" + style, color=color, label=name)
        if np.any(~ok):
            axes[0].loglog(pts[~ok, 0], pts[~ok, 2], "x", color=color, ms=9)
            axes[1].loglog(pts[~ok, 1], pts[~ok, 2], "x", color=color, ms=9)
    axes[0].set_xlabel("step h [s of numerical time] (x: step failed)")
    axes[1].set_xlabel("CPU time [s]")
    for ax in axes:
        ax.set_ylabel("terminal error (max norm)")
        ax.grid(True, which="both", alpha=0.3)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
    axes[0].legend(fontsize=7)
    fig.suptitle("Particle dropped with friction (mu = 0.2, a_n = 10, T = 1.6): FESD vs "
                 "Standard, Radau IIA(2), 2 FE per step", fontsize=9)
    fig.tight_layout()
    path = out_dir / "timefreezing_convergence.png"
    fig.savefig(path, dpi=120)
    lines.append("")
    lines.append(f"Chart: `{path.name}`. FESD's error stops at a floor set by the "
                 "complementarity tolerance (the clock creeps while frozen, see "
                 "`physical.FROZEN_RATE_TOL`), lower with the l1 penalty; the Standard "
                 "discretisation stalls at 5e-3 (its switch times are bound to the fixed grid).")
    return lines


# ----------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-nosnoc", action="store_true")
    parser.add_argument("--skip-convergence", action="store_true")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1]
                        / "benchmarks")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    have_nosnoc = False
    if not args.skip_nosnoc:
        try:
            import nosnoc  # noqa: F401

            have_nosnoc = True
        except ImportError:
            print("nosnoc not installed: `pip install nosnoc==0.2.0` to compare")

    rows = []
    for label, relaxation in (("Scholtes", None), ("l1 penalty", L1Penalty())):
        res, seconds, err, impacts = tfcontact_a(relaxation)
        rows.append(("a", row(f"tfcontact ({label})", seconds, res.n_nlps,
                              res.total_iterations, err, impacts, res.success)))
    if have_nosnoc:
        out, seconds, n_nlps, iterations, err = nosnoc_a()
        rows.append(("a", row("nosnoc_py 0.2.0", seconds, n_nlps, iterations, err,
                              nosnoc_impacts(out), True)))
    for stages in (4, 2):
        for label, relaxation in (("Scholtes", None), ("l1 penalty", L1Penalty())):
            res, seconds, err, impacts = tfcontact_b(stages, relaxation)
            rows.append((f"b, {stages} stages", row(f"tfcontact ({label})", seconds,
                                                    res.n_nlps, res.total_iterations, err,
                                                    impacts, res.success)))
        if have_nosnoc:
            out, seconds, n_nlps, iterations, err = nosnoc_b(stages)
            rows.append((f"b, {stages} stages", row("nosnoc_py 0.2.0", seconds, n_nlps,
                                                    iterations, err, nosnoc_impacts(out),
                                                    True)))

    lines = [
        "# Time-freezing simulation benchmark",
        "",
        f"`python scripts/bench_timefreezing.py` on {platform.node() or 'this machine'} "
        f"({platform.machine()}, {os.cpu_count()} cores shared with other jobs), "
        f"Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Same process, same machine: "
        "compare the ratios, not the absolute seconds.",
        "",
        "(a) particle, 1 m drop, v_x = 3, mu = 0.2, a_n = 10, T = 3.2, 20 steps x 5 FE, "
        "Radau IIA(2). "
        "(b) ball, e = 0.8, k = 100, 3 impacts, 30 steps x 8 FE.",
        "Error: max |y(T) - y_exact(T)| over (q, v, t). Impacts: frozen pieces found from the "
        "clock (expected: 1 in (a), 3 in (b)).",
        "",
        "| case | code | seconds | NLPs | IPOPT iterations | error | impacts | converged |",
        "|---|---|---|---|---|---|---|---|",
    ]
    reference = {}
    for case, r in rows:
        if r["name"].startswith("nosnoc"):
            reference[case] = r["seconds"]
    for case, r in rows:
        iters = "-" if r["iterations"] is None else str(r["iterations"])
        lines.append(f"| {case} | {r['name']} | {r['seconds']:.2f} | {r['n_nlps']} | {iters} | "
                     f"{r['error']:.1e} | {r['impacts']} | {'yes' if r['ok'] else 'NO'} |")
    if reference:
        lines.append("")
        lines.append("Speed-up (nosnoc_py seconds / tfcontact seconds):")
        for case, r in rows:
            if case in reference and not r["name"].startswith("nosnoc"):
                lines.append(f"- {case}, {r['name']}: {reference[case] / r['seconds']:.1f}x")
    if not args.skip_convergence:
        lines += ["", "## (c) FESD vs Standard (particle with friction, a_n = 10, T = 1.6)", ""]
        lines += convergence(args.out)
    text = "\n".join(lines) + "\n"
    print(text)
    (args.out / "timefreezing.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
