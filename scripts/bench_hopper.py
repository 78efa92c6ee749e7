"""Hopper OCP (TF-8 one-hop): tfcontact against nosnoc_py in the same run.

    python scripts/bench_hopper.py [--skip-nosnoc] [--out benchmarks/hopper_bench.md]

tfcontact states the problem from robots/hopper.urdf (rigid-body M(q); TF-8's diagonal M
is not a rigid body, see the URDF's comment); nosnoc_py (the bench extra, `pip install
nosnoc==0.2.0`) is given TF-8's hand-derived model through its public API, with the
settings of its own hopper example: N = 20, N_FE = 3, Radau IIA with 2 stages, Stewart
time-freezing, Scholtes with sigma_0 = 100 and 6 homotopy steps; tfcontact runs the
settings of `tfcontact plan hopper` for this task (`hopper_options("bench")`: the
homotopy runs from sigma_0 = 0.1 to residual 1e-3, where nosnoc_py's six steps end, its
stepping-stone NLPs solved to IPOPT tolerance 0.1, the FESD element differentiated once
and its derivatives evaluated on two threads), the same with every NLP solved to 1e-8,
and the same with CasADi differentiating the whole NLP. The cost column is tfcontact's
OCP cost (nosnoc_py discretises its cost otherwise). Both track the same reference (T = 1
s, x: 0.1 -> 1.0, apex height 1.0). The script prints and writes a markdown table: wall
time, NLPs, IPOPT iterations, complementarity residual, and the end-state deviation of
each plan from the replay of its controls in the event-detecting simulation of its own
model with exact impacts (no time-freezing).
"""

from __future__ import annotations

import os

# One BLAS thread for both tools, set before numpy loads OpenBLAS: a second thread doubled
# nosnoc_py's CPU time (its "NLP solves" column) without shortening its wall time. Only
# when run as a script: a test that imports this module must not change the BLAS threads
# of every solve after it.
if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from tfcontact.ocp.contact import ContactSolverOptions, solve_contact  # noqa: E402
from tfcontact.scenes.hopper import hopper_options, hopper_problem, hopper_task  # noqa: E402
from tfcontact.timefreezing import ComplementarityLagrangianSystem, Contact  # noqa: E402
from tfcontact.verify import replay_controls  # noqa: E402


def run_tfcontact(options: ContactSolverOptions, method: str) -> dict:
    start = time.perf_counter()
    _, _, problem = hopper_problem("bench")
    result = solve_contact(problem, options, verbose=True)
    wall = time.perf_counter() - start
    return {
        "method": method, "cost": result.ocp.cost,
        "wall": wall, "build": result.timings["build"], "solve": result.timings["solve"],
        "evaluations": result.ocp.mpcc_result.evaluation_time,
        "nlps": result.ocp.n_nlps, "iterations": result.ocp.total_iterations,
        "residual": result.ocp.residual, "status": result.status,
        "deviation": result.verification.end_state_deviation,
        "x_end": float(result.y[-1, 0]),
    }


def run_nosnoc(tolerance: float) -> dict:
    import casadi as ca
    import nosnoc as ns
    from scipy.interpolate import CubicSpline

    task = hopper_task("bench")
    opts = ns.NosnocOpts()
    opts.pss_mode = ns.PssMode.STEWART
    opts.use_fesd = True
    opts.comp_tol = 1e-9
    opts.sigma_0 = 100.0
    opts.homotopy_update_slope = 0.1
    opts.homotopy_update_rule = ns.HomotopyUpdateRule.LINEAR
    opts.n_s = 2
    opts.step_equilibration = ns.StepEquilibrationMode.HEURISTIC_MEAN
    opts.mpcc_mode = ns.MpccMode.SCHOLTES_INEQ
    opts.print_level = 1
    opts.opts_casadi_nlp["ipopt"]["max_iter"] = 4000
    opts.opts_casadi_nlp["ipopt"]["acceptable_tol"] = 1e-6
    opts.time_freezing = True
    opts.equidistant_control_grid = True
    opts.N_stages = task.n_intervals
    opts.N_finite_elements = 3
    opts.max_iter_homotopy = 6
    opts.terminal_time = task.horizon

    # TF-8's model, written here for nosnoc's API (q = (x, y, theta, l)).
    q = ca.SX.sym("q", 4)
    v = ca.SX.sym("v", 4)
    t = ca.SX.sym("t")
    u = ca.SX.sym("u", 2)
    sot = ca.SX.sym("sot")
    m_b, m_l, i_b, i_l, g = 1.0, 0.1, 0.25, 0.025, 9.81
    mass = np.diag([m_b + m_l, m_b + m_l, i_b + i_l, m_l])
    inputs = ca.vertcat(ca.horzcat(0, -ca.sin(q[2])), ca.horzcat(0, ca.cos(q[2])),
                        ca.horzcat(1, 0), ca.horzcat(0, 1))
    f_v = ca.vertcat(0, -(m_b + m_l) * g, 0, 0) + inputs @ u
    normal = ca.vertcat(0, 1, q[3] * ca.sin(q[2]), -ca.cos(q[2]))
    tangent = ca.vertcat(1, 0, q[3] * ca.cos(q[2]), ca.sin(q[2]))
    gap = q[1] - q[3] * ca.cos(q[2])
    inv_m = np.linalg.inv(mass)
    f_ode = sot * ca.vertcat(v, inv_m @ f_v, 1)
    zeros = ca.SX.zeros(4, 1)
    f_pos = ca.vertcat(zeros, inv_m @ (normal - tangent * task.mu) * task.a_n, 0)
    f_neg = ca.vertcat(zeros, inv_m @ (normal + tangent * task.mu) * task.a_n, 0)
    signs = np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [1, -1, -1],
                      [-1, 1, 1], [-1, 1, -1], [-1, -1, 1], [-1, -1, -1]])
    modes = ca.horzcat(*([f_ode] * 6), f_pos, f_neg)
    switching = ca.vertcat(gap, normal.T @ v, tangent.T @ v)
    x = ca.vertcat(q, v)
    knots = np.linspace(0, 1, len(task.waypoints))
    x_ref = CubicSpline(knots, np.asarray(task.waypoints))(np.linspace(0, 1, opts.N_stages + 1))
    p_ref = ca.SX.sym("x_ref", 8)
    weights = np.diag(task.state_weights)
    running = sot * ((x - p_ref).T @ weights @ (x - p_ref)
                     + u.T @ np.diag(task.control_weights) @ u)
    final = (x - task.x_end).T @ np.diag(task.terminal_weights) @ (x - task.x_end)
    model = ns.NosnocModel(x=ca.vertcat(x, t), F=[modes], S=[signs], c=[switching],
                           x0=np.concatenate([task.x0, [0.0]]), u=ca.vertcat(u, sot),
                           p_time_var=p_ref, p_time_var_val=x_ref[1:, :], t_var=t)
    lower, upper = np.asarray(task.lower), np.asarray(task.upper)
    ocp = ns.NosnocOcp(lbu=np.array([-50, -50, 0.1]), ubu=np.array([50, 50, 20]),
                       u_guess=np.array([0, 0, 1]), f_q=running, f_terminal=final,
                       lbx=np.concatenate([lower, [-np.inf]]),
                       ubx=np.concatenate([upper, [np.inf]]))
    start = time.perf_counter()
    solver = ns.NosnocSolver(opts, model, ocp)
    results = solver.solve()
    wall = time.perf_counter() - start
    traj = np.asarray(results["x_traj"])
    residual = float(solver.problem.comp_res(results["w_sol"], solver.p_val))
    # The same independent check as tfcontact's plan gets: its controls, piecewise constant
    # between the clock values at the control-interval boundaries, replayed in physical
    # time by the event-detecting simulation of TF-8's model with exact impacts.
    cls = ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.SX(mass), forces=f_v,
        contacts=(Contact(gap=gap, normal=normal, tangents=tangent, mu=task.mu,
                          a_n=task.a_n, name="foot"),))
    clocks = traj[::opts.N_finite_elements, -1]
    controls = np.asarray(results["u_traj"])[:, :2]
    deviation = replay_deviation(cls, task.x0, clocks, controls, task.horizon, traj[-1, :8])
    return {
        "method": "nosnoc_py 0.2.0 (TF-8 hand model, Stewart time-freezing)",
        "wall": wall, "build": np.nan, "solve": float(sum(results["cpu_time_nlp"])),
        "nlps": len(results["nlp_iter"]), "iterations": int(sum(results["nlp_iter"])),
        "residual": residual, "deviation": deviation,
        "status": f"{results['status']}, {replay_verdict(deviation, tolerance)}",
        "x_end": float(traj[-1, 0]),
    }


def replay_deviation(cls: ComplementarityLagrangianSystem, x0: np.ndarray,
                      clocks: np.ndarray, controls: np.ndarray, horizon: float,
                      plan_end: np.ndarray) -> float:
    """max |x_replay(T) - x_plan(T)| (an impact at T counts on either side, as in
    tfcontact's own check), or nan if the replay stops (message printed)."""
    replay = replay_controls(cls, x0, clocks, controls, horizon, rtol=1e-10, atol=1e-11)
    if replay.status != "success":
        print(f"replay of the nosnoc_py plan stopped: {replay.message}")
        return float("nan")
    print(f"replay of the nosnoc_py plan: impacts at t = "
          f"{np.round(replay.impact_times, 4).tolist()} s")
    return replay.deviation_at(horizon, plan_end)[0]


def replay_verdict(deviation: float, tolerance: float) -> str:
    """nosnoc_py's own status does not check its plan: how the replay compares with the
    end-state tolerance tfcontact's plans must meet."""
    if not np.isfinite(deviation):
        return "replay stopped"
    return f"replay {'within' if deviation <= tolerance else 'outside'} {tolerance:g}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-nosnoc", action="store_true")
    parser.add_argument("--out", default="benchmarks/hopper_bench.md")
    args = parser.parse_args()
    options = hopper_options("bench")
    loose = options.nlp.intermediate_tol
    rows = [run_tfcontact(options, "tfcontact (URDF, Heaviside time-freezing, FESD; "
                                   f"stepping-stone NLPs to tol {loose:g})")]
    # The same task with every NLP solved to IPOPT's tol: what the stepping stones save.
    tight = dataclasses.replace(options, nlp=dataclasses.replace(options.nlp,
                                                                 intermediate_tol=None))
    rows.append(run_tfcontact(tight, "tfcontact (the same, every NLP to tol "
                                     f"{options.nlp.tol:g})"))
    # CasADi's own derivatives of the whole NLP: what differentiating the element once saves.
    whole = dataclasses.replace(options, nlp=dataclasses.replace(
        options.nlp, element_derivatives=False, threads=1))
    rows.append(run_tfcontact(whole, "tfcontact (the first row's settings, CasADi "
                                     "differentiating the whole NLP)"))
    n_tfcontact = len(rows)
    if not args.skip_nosnoc:
        try:
            rows.append(run_nosnoc(options.verify.end_state_tolerance))
        except ImportError:
            print("nosnoc is not installed (pip install -e '.[bench]'): skipped")
    lines = [
        f"# Hopper OCP benchmark ({datetime.date.today()}, {platform.machine()}, "
        "2 cores shared, OPENBLAS_NUM_THREADS="
        f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')})", "",
        "Command: `python scripts/bench_hopper.py`", "",
        "| method | wall [s] | NLP build [s] | NLP solves [s] | of which function "
        "evaluations [s] | NLPs | IPOPT iterations | ms per iteration | compl. residual | "
        "end-state deviation | x(T) | cost | status |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        per_iteration = 1e3 * r["solve"] / max(r["iterations"], 1)
        lines.append(
            f"| {r['method']} | {r['wall']:.1f} | {r['build']:.1f} | {r['solve']:.1f} | "
            f"{r.get('evaluations', float('nan')):.1f} | {r['nlps']} | {r['iterations']} | "
            f"{per_iteration:.0f} | {r['residual']:.1e} | {r['deviation']:.1e} | "
            f"{r['x_end']:.3f} | {r.get('cost', float('nan')):.2f} | {r['status']} |")
    if len(rows) > n_tfcontact:  # the tfcontact rows against nosnoc_py's
        nosnoc = rows[n_tfcontact]
        lines.append("")
        for r in rows[:n_tfcontact]:
            lines.append(f"Wall-time ratio nosnoc_py / {r['method']}: "
                         f"{nosnoc['wall'] / r['wall']:.2f}; iteration ratio: "
                         f"{nosnoc['iterations'] / max(r['iterations'], 1):.2f}  ")
    text = "\n".join(lines) + "\n"
    print(text)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    # Keep the hand-written analysis (every section after the table) across reruns.
    old = out.read_text() if out.is_file() else ""
    notes = old[old.index("\n## "):] if "\n## " in old else ""
    out.write_text(text + notes)


if __name__ == "__main__":
    main()
