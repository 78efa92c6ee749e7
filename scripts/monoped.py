"""TF-9: the Capler monoped hops over three holes ([AUTO23] section 6).

Loads the project's URDF `robots/monoped.urdf` on a planar x-z base, builds the
time-freezing OCP of `tfcontact.scenes.monoped` (T = 2.5 s, N = 20, q0 = (0, 0.4, 0, 0),
q(T) = (3, 0.4, 0, 0), cost int u^T u, |u| <= 60, three elliptic holes), discretises it
with FESD (Radau IIA, 3 stages, N_FE = 3), solves the MPCC homotopy from the
start-everywhere initial guess (zero controls, every state at y0: no contact schedule)
and checks the plan independently. On the full task this stage alone ends nlp_failed;
`tfcontact plan monoped` adds the exact re-solve along a found contact sequence
(`tfcontact.scenes.monoped_exact`) and gives the verified plan.

Writes to `out/monoped/` (or `--out`): `trajectory.npz` + `trajectory.json`, `summary.json`,
`replay.html` (standalone meshcat page), the standard figures and `path.png` (the foot
and hip paths over the holes). With `--bench` it also writes `benchmarks/monoped.md`
(results table) and `benchmarks/monoped.png`.

Usage:
    python scripts/monoped.py                       # the [AUTO23] task
    python scripts/monoped.py --bench               # and the committed benchmark files
    python scripts/monoped.py --quick               # the reduced test task (one hole)
    python scripts/monoped.py --relaxation linf --sigma0 1 --kappa 0.1 --mu-strategy monotone
    python scripts/monoped.py --profile 50          # time 50 IPOPT iterations of NLP 1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from tfcontact.fesd import RadauIIA
from tfcontact.mpcc import LINEAR_SOLVERS, RELAXATIONS, Homotopy, Ipopt
from tfcontact.ocp.contact import ContactResult, ContactSolverOptions, solve_contact
from tfcontact.robot import RobotSpec
from tfcontact.scenes.monoped import (
    FOOT_RADIUS,
    FULL_TASK,
    MonopedProblem,
    monoped_options,
    monoped_problem,
    monoped_task,
)
from tfcontact.verify import AutoReplay, FesdReplay, VerifyOptions

ROOT = Path(__file__).resolve().parents[1]



def solver_options(args: argparse.Namespace) -> ContactSolverOptions:
    relaxation = RELAXATIONS[args.relaxation]()
    ipopt = {"mu_strategy": args.mu_strategy}
    return ContactSolverOptions(
        scheme=RadauIIA(args.stages), n_finite_elements=args.n_fe, relaxation=relaxation,
        homotopy=Homotopy(sigma_0=args.sigma0, kappa=args.kappa, tolerance=args.comp_tol,
                          max_nlps=args.max_nlps, max_refinements=args.refinements),
        nlp=Ipopt(tol=1e-8, max_iter=args.max_iter, options=ipopt,
                  intermediate_tol=args.stepping_stones,
                  element_derivatives=args.element_derivatives,
                  linear_solver=args.linear_solver),
        verify=VerifyOptions(replay=AutoReplay(FesdReplay(refinement=args.verify_refinement))),
    )


def start_to_goal_guess(task) -> np.ndarray:
    """(q, v) at the interval boundaries with q_x and v_x linear from start to goal, the
    rest at the start: an interpolation, not a contact schedule."""
    n, n_q = task.n_intervals, len(task.q0)
    guess = np.zeros((n + 1, 2 * n_q))
    guess[:, :n_q] = task.q0
    guess[:, 0] = np.linspace(task.q0[0], task.q_goal[0], n + 1)
    guess[:, n_q] = (task.q_goal[0] - task.q0[0]) / task.horizon
    return guess


def robot_spec() -> RobotSpec:
    from tfcontact.robot import ContactSpec

    return RobotSpec("robots/monoped.urdf", base="planar_xz",
                     contacts=(ContactSpec("foot", FOOT_RADIUS),))


def plan_checks(mp: MonopedProblem, result: ContactResult) -> dict:
    """Task-level numbers of a plan: flights, goal error, hole clearance."""
    ocp = result.ocp
    q_all = np.concatenate([result.y[:, :4], ocp.x_stages.reshape(-1, result.y.shape[1])[:, :4]])
    gaps = np.asarray(mp.system.cls.function("gaps")(q_all.T)).T[:, 0]
    holes = mp.hole_values(q_all)
    phys = result.physical
    gap_t = phys.gaps[:, 0]
    airborne = gap_t > 1e-3
    take_offs = int(np.sum(airborne[1:] & ~airborne[:-1]))
    return {
        "goal_error": float(np.max(np.abs(result.y[-1, :4] - np.asarray(mp.task.q_goal)))),
        "max_gap": float(gaps.max()),
        "take_offs": take_offs,
        "min_hole_value": float(holes.min()) if holes.size else float("inf"),
        "impacts": len(phys.impact_times),
        "impact_times": [round(float(t), 4) for t in phys.impact_times],
    }


def to_trajectory(mp: MonopedProblem, result: ContactResult):
    from tfcontact.plan_format.adapters import trajectory_from_result

    return trajectory_from_result(result, robot_spec(), mp.scene())


def path_figure(mp: MonopedProblem, result: ContactResult, path: Path) -> None:
    """Foot and hip paths in the x-z plane over the holes, with stick figures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phys = result.physical
    q = phys.q
    foot = np.asarray(mp.foot(q.T)).T
    knee = np.asarray(mp.knee(q.T)).T
    task = mp.task
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9, 5.5), height_ratios=(2, 1))
    x_min, x_max = -0.3, max(task.q_goal[0], foot[:, 0].max()) + 0.3
    ax.axhline(0.0, color="k", lw=0.8)
    for c in task.holes:
        s = np.linspace(-1, 1, 101)
        ax.fill_between(c + task.hole_half_width * s, -task.hole_depth * np.sqrt(1 - s**2), 0,
                        color="0.8", label="hole" if c == task.holes[0] else None)
    ax.plot(q[:, 0], q[:, 1], color="tab:blue", lw=1.2, label="hip")
    ax.plot(foot[:, 0], foot[:, 1], color="tab:orange", lw=1.2, label="foot")
    picks = np.unique(np.linspace(0, len(q) - 1, 25).astype(int))
    for k in picks:
        ax.plot([q[k, 0], knee[k, 0], foot[k, 0]], [q[k, 1], knee[k, 1], foot[k, 1]],
                color="0.4", lw=0.6, alpha=0.7)
    ax.set_xlim(x_min, x_max)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.legend(loc="upper right", fontsize=8, ncols=3)
    ax.set_title(f"TF-9 monoped: {result.status}, objective {result.ocp.cost:.4g}, "
                 f"{len(phys.impact_times)} impacts")
    t_u = np.linspace(0, task.horizon, task.n_intervals + 1)
    for i, name in enumerate(("hip", "knee")):
        bx.stairs(result.u[:, i], t_u, label=f"u_{name} [N m]")
    bx.set_xlabel("physical time t [s]")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def profile(mp: MonopedProblem, options: ContactSolverOptions, iterations: int) -> dict:
    """Where the time of `iterations` IPOPT iterations of the first NLP goes."""
    from tfcontact.mpcc import MpccSolver
    from tfcontact.ocp import Transcription, build
    from tfcontact.ocp.contact import transcribe

    ocp, _ = transcribe(mp.problem)
    start = time.perf_counter()
    built = build(ocp, discretization=Transcription(
        scheme=options.scheme, n_finite_elements=options.n_finite_elements,
        method=options.method))
    t_build = time.perf_counter() - start
    nlp = dataclasses.replace(options.nlp, max_iter=iterations)
    solver = MpccSolver(built.mpcc, relaxation=options.relaxation, nlp=nlp)
    result = solver.solve(built.p, homotopy=dataclasses.replace(options.homotopy, max_nlps=1))
    stats = solver.ipopt_stats()
    evals = {k[len("t_wall_nlp_"):]: stats[k] for k in stats if k.startswith("t_wall_nlp_")}
    total = result.history[0].seconds
    return {"build_ocp": t_build, "build_nlp": solver.build_time, "iterations":
            result.history[0].iterations, "solve": total, "evaluations": evals,
            "ipopt_rest": total - sum(evals.values())}


def bench_markdown(mp: MonopedProblem, result: ContactResult, checks: dict, args) -> str:
    o = result.ocp
    t = result.timings
    v = result.verification
    cmd = "python scripts/monoped.py --bench" + (" " + " ".join(args.extra_cmd)
                                                  if args.extra_cmd else "")
    lines = [
        "# TF-9 monoped over three holes ([AUTO23] section 6)",
        "",
        f"Regenerate: `{cmd}` (figures and the plan in `out/monoped/`).",
        "",
        "Task: T = 2.5 s, N = 20, q0 = (0, 0.4, 0, 0), q(T) = (3, 0.4, 0, 0), cost int u^T u, "
        "|u| <= 60, holes ((p_x - x_c)/0.5)^2 + (p_z/0.1)^2 >= 1 at x_c = 0.5, 1.5, 2.5, "
        "mu = 0.8, a_n = 200; "
        + ("start-everywhere initial guess (zero controls, y0 at every node). "
           if args.guess == "start" else "initial guess: zero controls, q_x and v_x linear "
           "from start to goal, the rest at y0. ")
        + "Robot: `robots/monoped.urdf`, `planar_xz` base, foot sphere r = 0.028 on "
        "ground at -r (TF-9's point-foot gap).",
        "",
        f"Solver: {options_text(args)}.",
        "",
        "| status | objective | NLPs | IPOPT iterations | comp. residual | build [s] | "
        "NLP solves [s] | verify [s] | impacts | goal error | min hole value | verification |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
        f"| {result.status} | {o.cost:.5g} | {o.n_nlps} | {o.total_iterations} | "
        f"{o.residual:.1e} | {t['build']:.1f} | {t['solve']:.1f} | {t['verify']:.1f} | "
        f"{checks['impacts']} | {checks['goal_error']:.1e} | {checks['min_hole_value']:.2e} | "
        f"{'passed' if v.passed else 'FAILED'} |",
        "",
        "Homotopy (sigma, iterations, residual, seconds, IPOPT status): "
        + "; ".join(f"({h.sigma:.0e}, {h.iterations}, {h.residual:.1e}, {h.seconds:.1f}, "
                    f"{h.ipopt_status})" for h in o.mpcc_result.history),
        "",
        f"Verification: {v.summary()}",
        "",
        "This is the time-freezing stage alone. The verified plan (`tfcontact plan monoped`: "
        "this stage on the reduced task, then the exact re-solve along the contact sequence "
        "it finds): [monoped_exact.md](monoped_exact.md).",
        "",
        "Times are wall-clock on a 2-core machine shared with other jobs: compare them "
        "only as ratios measured side by side.",
        "",
        "Settings tried (relaxations, IPOPT barrier strategy, hole forms) and where the time "
        "goes: [monoped_settings.md](monoped_settings.md).",
        "",
        "![monoped](monoped.png)",
        "",
    ]
    return "\n".join(lines)


def options_text(args: argparse.Namespace) -> str:
    return (f"holes as {args.hole_form}, gap scale {args.gap_scale:g}/s, speed of time in "
            f"[1, {args.s_max}], clock constraint {args.clock}, verification refinement "
            f"{args.verify_refinement}; "
            f"FESD Radau IIA {args.stages} stages, N_FE = {args.n_fe}, {args.relaxation}, "
            f"sigma_0 = {args.sigma0}, kappa = {args.kappa}, comp. tol {args.comp_tol:g}, "
            f"IPOPT ({args.linear_solver.upper()}) tol 1e-8, mu_strategy {args.mu_strategy}"
            + (f", stepping stones to {args.stepping_stones:g}" if args.stepping_stones else "")
            + (f", {args.refinements} step refinements" if args.refinements else "")
            + (", start-to-goal guess" if args.guess == "linear" else ""))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the reduced one-hole task")
    # Defaults: the settings of `tfcontact plan monoped` (monoped_options("full")).
    plan = monoped_options("full")
    parser.add_argument("--n-intervals", type=int, default=None)
    parser.add_argument("--stages", type=int, default=None)
    parser.add_argument("--n-fe", type=int, default=plan.n_finite_elements)
    parser.add_argument("--relaxation", choices=sorted(RELAXATIONS), default="scholtes")
    parser.add_argument("--sigma0", type=float, default=plan.homotopy.sigma_0)
    parser.add_argument("--kappa", type=float, default=plan.homotopy.kappa)
    parser.add_argument("--comp-tol", type=float, default=plan.homotopy.tolerance)
    parser.add_argument("--max-nlps", type=int, default=plan.homotopy.max_nlps)
    parser.add_argument("--mu-strategy", choices=("adaptive", "monotone"),
                        default=plan.nlp.options["mu_strategy"])
    parser.add_argument("--max-iter", type=int, default=plan.nlp.max_iter)
    parser.add_argument("--linear-solver", choices=LINEAR_SOLVERS,
                        default=plan.nlp.linear_solver, help="IPOPT's linear solver")
    parser.add_argument("--stepping-stones", type=float, default=plan.nlp.intermediate_tol,
                        metavar="TOL", help="solve the NLPs above the final sigma to TOL "
                                            "(Ipopt.intermediate_tol)")
    parser.add_argument("--refinements", type=int, default=plan.homotopy.max_refinements,
                        help="Homotopy.max_refinements")
    parser.add_argument("--element-derivatives", action="store_true",
                        default=plan.nlp.element_derivatives,
                        help="Ipopt.element_derivatives")
    parser.add_argument("--guess", choices=("start", "linear"), default="start",
                        help="start: the start state everywhere (TF-9); linear: q_x and v_x "
                             "from start to goal (`start_to_goal_guess`)")
    parser.add_argument("--hole-form", choices=("ellipse", "bump"), default=FULL_TASK.hole_form,
                        help="hole constraint (see MonopedTask.hole_form)")
    parser.add_argument("--s-max", type=float, default=FULL_TASK.speed_of_time[1],
                        help="speed of time in [1, s_max] (authors' robot_ocp.m: 5)")
    parser.add_argument("--clock", choices=("stagewise", "end"),
                        default="stagewise" if FULL_TASK.stagewise_clock else "end",
                        help="clock constraint at every interval or only at T "
                             "(authors' robot_ocp.m: only at T)")
    parser.add_argument("--hole-half-width", type=float, default=None)
    parser.add_argument("--verify-refinement", type=int, default=FesdReplay().refinement)
    parser.add_argument("--gap-scale", type=float, default=FULL_TASK.gap_scale,
                        help="K [1/s] of the gap's switching function K f_c")
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "monoped")
    parser.add_argument("--bench", action="store_true",
                        help="also write benchmarks/monoped.md and benchmarks/monoped.png")
    parser.add_argument("--profile", type=int, default=0, metavar="ITERATIONS",
                        help="only time this many IPOPT iterations of the first NLP")
    args = parser.parse_args(argv)
    given = list(argv if argv is not None else sys.argv[1:])
    if "--out" in given:  # where the plan goes is not part of the benchmark's command
        del given[given.index("--out"):given.index("--out") + 2]
    args.extra_cmd = [a for a in given if a != "--bench" and not a.startswith("--out=")]
    name = "reduced" if args.quick else "full"
    task = monoped_task(name)
    if args.n_intervals is not None:
        task = dataclasses.replace(task, n_intervals=args.n_intervals)
    task = dataclasses.replace(task, hole_form=args.hole_form, speed_of_time=(1.0, args.s_max),
                               stagewise_clock=args.clock == "stagewise",
                               gap_scale=args.gap_scale)
    if args.hole_half_width is not None:
        task = dataclasses.replace(task, hole_half_width=args.hole_half_width)
    if args.stages is None:
        args.stages = monoped_options(name).scheme.stages
    mp = monoped_problem(task)
    if args.guess == "linear":
        mp = dataclasses.replace(mp, problem=dataclasses.replace(
            mp.problem, guess=start_to_goal_guess(task)))
    options = solver_options(args)
    if args.profile:
        print(json.dumps(profile(mp, options, args.profile), indent=1))
        return 0
    print(f"TF-9 monoped: T = {task.horizon}, N = {task.n_intervals}, holes {task.holes}; "
          f"{options_text(args)}", flush=True)
    result = solve_contact(mp.problem, options, verbose=True)
    checks = plan_checks(mp, result)
    t = result.timings
    print(f"build {t['build']:.2f} s (OCP + NLP), NLP solves {t['solve']:.2f} s "
          f"({', '.join(f'{s:.1f}' for s in result.ocp.nlp_times)}), verify "
          f"{t['verify']:.2f} s, total {t['total']:.2f} s")
    print("plan:", json.dumps(checks))
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    path_figure(mp, result, out / "path.png")
    from tfcontact.viz import replay
    from tfcontact.viz.plan import save_plan

    traj = to_trajectory(mp, result)
    files = save_plan(result, traj, out)
    replay(traj, html=out / "replay.html")
    print(f"wrote {', '.join(str(f) for f in files)}, {out / 'replay.html'}, {out / 'path.png'}")
    if args.bench:
        bench = ROOT / "benchmarks"
        path_figure(mp, result, bench / "monoped.png")
        (bench / "monoped.md").write_text(bench_markdown(mp, result, checks, args))
        print(f"wrote {bench / 'monoped.md'}, {bench / 'monoped.png'}")
    return 0 if result.success else 1


if __name__ == "__main__":
    raise SystemExit(main())
