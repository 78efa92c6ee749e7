"""How the time-freezing right-hand side is written: per-mode solves, one solve, and the
inverse-dynamics form, side by side (issues 30/31, benchmarks/dynamics_forms.md).

    python scripts/bench_dynamics_forms.py [--samples 200] [--repeat 5] [--plans 1]
                                           [--out benchmarks/dynamics_forms.md]

For the hopper (TF-8 bench task), the monoped (TF-9) and solo12 (floating base, four
feet, mu = 0.7) the script builds `Inelastic`'s Heaviside right-hand side f(y, u, alpha)
in three forms of the same function:

* per-mode solves (`PerModeSolves`): sum_k theta_k f_k, one M(q)^-1 solve per mode;
* one solve (`OneSolve`, the default): (theta_0 v, M^-1 sum_k theta_k F_k, theta_0);
* inverse dynamics (`InverseDynamics`, opt-in): an acceleration variable a per stage
  point, f = (theta_0 v, a, theta_0) and the equality g = M(q) a - sum_k theta_k F_k = 0,
  no M^-1 at all. Its rows are (f, g) in (y, u, alpha, a): the NLP carries n_v more
  variables and equalities per stage point.

For each it prints SX instructions and evaluation time (CasADi's virtual machine, batched
with `Function.map`, best of --repeat, per evaluation) of f, of its Jacobian and of the
Hessian of lambda^T f (what IPOPT's Lagrangian Hessian evaluates per stage point), and
the nonzeros of the Jacobian and Hessian. Then it solves the hopper plan
(`hopper_problem("bench")`, `hopper_options("bench")`, as scripts/bench_hopper.py's first
row, and the same with every NLP solved to IPOPT's tol) with each form in turn, --plans
rounds.
"""

from __future__ import annotations

import os

# One BLAS thread, as scripts/bench_hopper.py (set before numpy loads OpenBLAS).
if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from tfcontact.timefreezing import ComplementarityLagrangianSystem, time_freeze  # noqa: E402
from tfcontact.timefreezing.inelastic import (  # noqa: E402
    HeavisideDynamics,
    Inelastic,
    InverseDynamics,
    OneSolve,
    PerModeSolves,
)

SOLO_FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


FORMS: tuple[tuple[str, HeavisideDynamics], ...] = (
    ("per-mode solves", PerModeSolves()), ("one solve", OneSolve()),
    ("inverse dynamics", InverseDynamics()))


def robots() -> dict[str, ComplementarityLagrangianSystem]:
    """The three CLS, as the library's scenes build them."""
    from tfcontact.robot import ContactSpec, Ground, load_robot
    from tfcontact.scenes.hopper import hopper_cls, hopper_robot, hopper_task
    from tfcontact.scenes.monoped import FOOT_RADIUS, monoped_task
    from tfcontact.timefreezing import from_robot

    systems = {}
    robot, ground = hopper_robot()
    systems["hopper"] = hopper_cls(robot, ground, hopper_task("bench"))
    task = monoped_task("full")
    monoped = load_robot("monoped", base="planar_xz",
                         contacts=(ContactSpec("foot", FOOT_RADIUS),))
    systems["monoped"] = from_robot(monoped, Ground(height=-FOOT_RADIUS), mu=task.mu,
                                    a_n=task.a_n)
    solo = load_robot("solo12", base="floating",
                      contacts=tuple(ContactSpec(foot, 0.016) for foot in SOLO_FEET))
    systems["solo12"] = from_robot(solo, Ground(), mu=0.7)
    return systems


@dataclass(frozen=True)
class Measure:
    """One form's figures: instructions, per-evaluation times [us], nonzeros."""

    form: str
    n_variables: int
    n_rows: int
    f_instructions: int
    f_us: float
    jac_instructions: int
    jac_us: float
    jac_nnz: int
    hess_instructions: int
    hess_us: float
    hess_nnz: int


def best_per_evaluation(function: ca.Function, inputs: list[np.ndarray], samples: int,
                        repeat: int) -> float:
    """Best of `repeat` batched calls of `function` over `samples` columns, per column [us]."""
    batched = function.map(samples)
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        batched(*inputs)
        best = min(best, time.perf_counter() - start)
    return best / samples * 1e6


def measure(form: str, z: ca.SX, rows: ca.SX, samples: int, repeat: int,
            rng: np.random.Generator) -> Measure:
    """Figures of f(z) = rows, its Jacobian and the Hessian of lambda^T f."""
    lam = ca.SX.sym("lambda", rows.numel())
    jac = ca.jacobian(rows, z)
    hess = ca.hessian(ca.dot(lam, rows), z)[0]
    f = ca.Function("f", [z], [rows])
    j = ca.Function("j", [z], [jac])
    h = ca.Function("h", [z, lam], [hess])
    # every input of order 1: the cost of an SX evaluation does not depend on the values,
    # and velocities of this size keep the 3-D slip modes' norms well away from eps_t
    zs = rng.uniform(-0.5, 0.5, (z.numel(), samples))
    lams = rng.uniform(-1, 1, (rows.numel(), samples))
    return Measure(
        form=form, n_variables=z.numel(), n_rows=rows.numel(),
        f_instructions=f.n_instructions(), f_us=best_per_evaluation(f, [zs], samples, repeat),
        jac_instructions=j.n_instructions(),
        jac_us=best_per_evaluation(j, [zs], samples, repeat), jac_nnz=jac.nnz(),
        hess_instructions=h.n_instructions(),
        hess_us=best_per_evaluation(h, [zs, lams], samples, repeat),
        hess_nnz=ca.triu(hess).nnz(),
    )


def forms(cls: ComplementarityLagrangianSystem, samples: int, repeat: int,
          seed: int = 0) -> list[Measure]:
    """The three forms of `cls`'s Heaviside right-hand side, measured: rows (f, e) in
    (y, u, alpha, a), e and a empty for the explicit forms."""
    rng = np.random.default_rng(seed)
    out = []
    for form, dynamics in FORMS:
        pss = time_freeze(cls, method=Inelastic(dynamics=dynamics)).pss
        z = ca.vertcat(pss.x, pss.u, pss.alpha, pss.auxiliary)
        label = f"{form} (f, e)" if pss.n_auxiliary else form
        out.append(measure(label, z, ca.vertcat(pss.rhs, pss.auxiliary_equations), samples,
                           repeat, rng))
    return out


def check_equal(cls: ComplementarityLagrangianSystem, seed: int = 1) -> float:
    """max |f_one - f_per-mode| / max |f| at random points (the forms are one function)."""
    rng = np.random.default_rng(seed)
    values = []
    for _, dynamics in FORMS[:2]:
        pss = time_freeze(cls, method=Inelastic(dynamics=dynamics)).pss
        f = ca.Function("f", [ca.vertcat(pss.x, pss.u, pss.alpha)], [pss.rhs])
        values.append(f)
    worst = 0.0
    for _ in range(5):
        point = rng.uniform(-0.5, 0.5, values[0].size1_in(0))
        a, b = (np.asarray(f(point)).ravel() for f in values)
        worst = max(worst, float(np.max(np.abs(a - b)) / np.max(np.abs(a))))
    return worst


def with_dynamics(problem, dynamics: HeavisideDynamics):
    """`problem` with its time-freezing system rebuilt with `dynamics` (the scenes build
    the default form). The rebuild has a new clock symbol, which the hopper's running cost
    reads (its reference is a function of the clock): it is replaced by the problem's."""
    tf = problem.system
    method = Inelastic(normal_switching=tf.parameter("normal_switching"),
                       gap_scale=tf.parameter("gap_scale"), dynamics=dynamics)
    new = time_freeze(tf.cls, method=method)
    old_t, new_t = tf.y[tf.clock_index], new.y[new.clock_index]

    def same_clock(expr: ca.SX) -> ca.SX:
        return ca.substitute(expr, new_t, old_t)

    pss = dataclasses.replace(new.pss, x=tf.pss.x, rhs=same_clock(new.pss.rhs),
                              auxiliary_equations=same_clock(new.pss.auxiliary_equations))
    return dataclasses.replace(problem, system=dataclasses.replace(
        new, pss=pss, modes=same_clock(new.modes), weights=same_clock(new.weights)))


def hopper_plans(n_runs: int) -> list[dict]:
    """The hopper bench plan with each form in turn, `n_runs` rounds, with the bench
    settings (stepping-stone NLPs to IPOPT tolerance 0.1) and with every NLP to 1e-8."""
    from tfcontact.ocp.contact import solve_contact
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    bench = hopper_options("bench")
    tight = dataclasses.replace(bench, nlp=dataclasses.replace(bench.nlp,
                                                               intermediate_tol=None))
    settings = (("bench", bench), (f"every NLP to {bench.nlp.tol:g}", tight))
    rows = []
    for run in range(n_runs):
        for setting, options in settings:
            for form, dynamics in FORMS:
                start = time.perf_counter()
                _, _, problem = hopper_problem("bench")
                problem = with_dynamics(problem, dynamics)
                result = solve_contact(problem, options, verbose=False)
                wall = time.perf_counter() - start
                ocp = result.ocp
                rows.append({
                    "form": form, "settings": setting, "run": run + 1, "wall": wall,
                    "solve": result.timings["solve"],
                    "evaluations": ocp.mpcc_result.evaluation_time,
                    "iterations": ocp.total_iterations, "nlps": ocp.n_nlps, "cost": ocp.cost,
                    "x_end": float(result.y[-1, 0]), "status": result.status,
                })
                row = rows[-1]
                print(f"hopper plan, {form}, {setting}, run {run + 1}: {wall:.2f} s, "
                      f"{row['iterations']} iterations, cost {row['cost']:.4f}, "
                      f"{row['status']}", flush=True)
    return rows


def expression_table(results: dict[str, list[Measure]], builds: dict[str, float],
                     equal: dict[str, float]) -> list[str]:
    lines = ["| robot | form | variables | rows | f instr. | f [us] | Jacobian instr. | "
             "Jacobian [us] | Jacobian nnz | Hessian instr. | Hessian [us] | Hessian nnz "
             "(upper) | Hessian time vs per-mode |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for robot, measures in results.items():
        base = measures[0].hess_us
        for m in measures:
            lines.append(
                f"| {robot} | {m.form} | {m.n_variables} | {m.n_rows} | {m.f_instructions} | "
                f"{m.f_us:.2f} | {m.jac_instructions} | {m.jac_us:.2f} | {m.jac_nnz} | "
                f"{m.hess_instructions} | {m.hess_us:.2f} | {m.hess_nnz} | "
                f"{m.hess_us / base:.2f} |")
    lines.append("")
    for robot in results:
        lines.append(f"{robot}: three forms built and measured in {builds[robot]:.2f} s; "
                     "one solve vs per-mode solves, max relative difference of f at 5 "
                     "random points: "
                     f"{equal[robot]:.1e}  ")
    return lines


def plan_table(rows: list[dict]) -> list[str]:
    lines = ["| form | settings | run | wall [s] | NLP solves [s] | function evaluations [s] | "
             "NLPs | IPOPT iterations | ms per iteration | cost | x(T) | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['form']} | {r['settings']} | {r['run']} | {r['wall']:.2f} | "
            f"{r['solve']:.2f} | {r['evaluations']:.2f} | {r['nlps']} | {r['iterations']} | "
            f"{1e3 * r['solve'] / max(r['iterations'], 1):.1f} | {r['cost']:.4f} | "
            f"{r['x_end']:.4f} | {r['status']} |")
    lines.append("")
    for setting in dict.fromkeys(r["settings"] for r in rows):
        best = {}
        for form, _ in FORMS:
            mine = [r for r in rows if r["form"] == form and r["settings"] == setting]
            best[form] = {key: min(r[key] for r in mine)
                          for key in ("wall", "solve", "evaluations")}
        reference = best["per-mode solves"]
        for form in list(best)[1:]:
            lines.append(f"{setting}: ratio per-mode solves / {form} (best of each): wall "
                         f"{reference['wall'] / best[form]['wall']:.2f}, evaluations "
                         f"{reference['evaluations'] / best[form]['evaluations']:.2f}  ")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--plans", type=int, default=1,
                        help="rounds of hopper solves, each form and setting (0: none)")
    parser.add_argument("--out", default="benchmarks/dynamics_forms.md")
    args = parser.parse_args()
    results, builds, equal = {}, {}, {}
    start = time.perf_counter()
    systems = robots()
    print(f"robots loaded in {time.perf_counter() - start:.1f} s", flush=True)
    for name, cls in systems.items():
        t0 = time.perf_counter()
        results[name] = forms(cls, args.samples, args.repeat)
        builds[name] = time.perf_counter() - t0
        equal[name] = check_equal(cls)
        for m in results[name]:
            print(f"{name:8s} {m.form:24s} f {m.f_instructions:7d} instr {m.f_us:8.2f} us | "
                  f"J {m.jac_instructions:7d} instr {m.jac_us:8.2f} us nnz {m.jac_nnz:5d} | "
                  f"H {m.hess_instructions:7d} instr {m.hess_us:8.2f} us nnz {m.hess_nnz:5d}",
                  flush=True)
    lines = [
        f"```\n{platform.machine()}, casadi {ca.__version__}, OPENBLAS_NUM_THREADS="
        f"{os.environ.get('OPENBLAS_NUM_THREADS')}, samples {args.samples}, best of "
        f"{args.repeat}; run {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC\n```",
        "", "Expressions (SX virtual machine, per evaluation):", "",
        *expression_table(results, builds, equal)]
    if args.plans > 0:
        rows = hopper_plans(args.plans)
        lines += ["", "Hopper plan (`hopper_problem(\"bench\")`, `hopper_options(\"bench\")` "
                  "and the same with every NLP to IPOPT's tol):", "", *plan_table(rows)]
    text = "\n".join(lines)
    print(text)
    out = Path(args.out)
    marker = "<!-- figures -->"
    if out.exists() and marker in out.read_text():
        head, _, _ = out.read_text().partition(marker)
        tail = out.read_text().split("<!-- /figures -->", 1)[-1]
        out.write_text(f"{head}{marker}\n{text}\n<!-- /figures -->{tail}")
    else:
        out.write_text(f"# Dynamics forms\n\nCommand: `python scripts/bench_dynamics_forms.py`"
                       f"\n\n{marker}\n{text}\n<!-- /figures -->\n")
    print(f"written to {out}")


if __name__ == "__main__":
    main()
