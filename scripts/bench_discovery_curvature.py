"""Where a discovery's Hessian regularisation comes from (issue 30, benchmarks/legged.md).

IPOPT regularises the Hessian of the Lagrangian in nearly every iteration of a legged
task's first relaxed NLP (biped-walk: 232 of 246), so each iteration factorises the KKT
matrix several times and its steps are short. This script stops the task's first NLP
after `--iterations`, takes IPOPT's iterate and constraint multipliers, and prints:

* on the null space of the equality rows, the eigenvalue range of each part of the
  Hessian of the Lagrangian: the objective, lambda_g^T g (the FESD rows: dynamics, steps,
  path, periodicity), lambda_c^T (G H) (the Scholtes rows), and their sum;
* the rows with the largest multipliers, by the state components of x in the row;
* the equality rows' largest and smallest singular values and the share of their
  multipliers along the left singular vectors of the 20 smallest.

    python scripts/bench_discovery_curvature.py biped-walk --iterations 100
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import casadi as ca
import numpy as np
import scipy.linalg

from tfcontact.ocp.contact import solve_contact
from tfcontact.task import load_task, shipped_tasks
from tfcontact.task.build import build_task


@dataclasses.dataclass(frozen=True)
class Curvature:
    """The first NLP's iterate after `iterations`: `hessians` (n_w x n_w, by part, their
    sum under "all"), `ranges` (smallest and largest eigenvalue on the null space of the
    equality rows, and how many are below -1e-6), the multipliers `lam_g` (the FESD
    rows) and `lam_c` (the Scholtes rows), each FESD row's state components (`row_states`),
    the equality rows' `singular_values` (descending), the `share` of their multipliers'
    norm along the 20 smallest, and the `point`: the MPCC, its iterate w and parameters p."""

    task: str
    iterations: int
    sigma: float
    objective: float
    hessians: dict[str, np.ndarray]
    ranges: dict[str, tuple[float, float, int]]
    lam_g: np.ndarray
    lam_c: np.ndarray
    row_states: tuple[str, ...]
    singular_values: np.ndarray
    share: float
    point: tuple[Any, np.ndarray, np.ndarray]


def reduced_range(hessian: np.ndarray, null: np.ndarray) -> tuple[float, float, int]:
    """Smallest and largest eigenvalue of null^T H null, and how many are below -1e-6."""
    reduced = null.T @ hessian @ null
    eigenvalues = np.linalg.eigvalsh(0.5 * (reduced + reduced.T))
    return float(eigenvalues[0]), float(eigenvalues[-1]), int((eigenvalues < -1e-6).sum())


def curvature(task_name: str, iterations: int) -> Curvature:
    """Solve `task_name`'s first relaxed NLP for `iterations` IPOPT iterations and take
    its Hessian apart (module docstring)."""
    task = load_task(shipped_tasks().get(task_name, task_name))
    setup = build_task(task)
    options = setup.options
    options = dataclasses.replace(
        options, attempts=1, homotopy=dataclasses.replace(options.homotopy, max_nlps=1),
        nlp=dataclasses.replace(options.nlp, max_iter=iterations))
    result = solve_contact(setup.problem, options, verbose=False)
    built, nlp = result.ocp.build, result.ocp.mpcc_result
    mpcc, w, p = built.mpcc, nlp.w, built.p
    lam_g, lam_c = nlp.lam_g[:mpcc.n_g], nlp.lam_g[mpcc.n_g:]
    products = mpcc.G * mpcc.H
    weights_g, weights_c = ca.SX.sym("lam_g", mpcc.n_g), ca.SX.sym("lam_c", products.numel())

    def value(expression: ca.SX, weights: ca.SX | None = None,
              values: np.ndarray | None = None) -> np.ndarray:
        symbols = [mpcc.w, mpcc.p] + ([] if weights is None else [weights])
        arguments = [w, p] + ([] if values is None else [values])
        return np.asarray(ca.Function("f", symbols, [expression])(*arguments))

    hessians = {
        "objective": value(ca.hessian(mpcc.f, mpcc.w)[0]),
        "lambda_g^T g (FESD rows)": value(ca.hessian(ca.dot(weights_g, mpcc.g), mpcc.w)[0],
                                          weights_g, lam_g),
        "lambda_c^T (G H) (Scholtes rows)": value(
            ca.hessian(ca.dot(weights_c, products), mpcc.w)[0], weights_c, lam_c),
    }
    hessians["all"] = sum(hessians.values())
    jacobian = value(ca.jacobian(mpcc.g, mpcc.w))
    equality = np.flatnonzero(mpcc.lbg == mpcc.ubg)
    null = scipy.linalg.null_space(jacobian[equality])
    names = result.system.state_names
    n_x = len(names)
    x_columns = {int(c): int(k) % n_x for k, c in enumerate(mpcc.blocks["x"].ravel())}
    row_states = tuple(
        ", ".join(names[s] for s in sorted({x_columns[c] for c in np.flatnonzero(row)
                                             if c in x_columns})) or "-"
        for row in jacobian)
    left, singular, _ = np.linalg.svd(jacobian[equality], full_matrices=False)
    multipliers = lam_g[equality]
    share = float(np.linalg.norm(left[:, -20:].T @ multipliers) / np.linalg.norm(multipliers))
    return Curvature(
        task=task_name, iterations=nlp.total_iterations, sigma=nlp.history[0].sigma,
        objective=nlp.objective, hessians=hessians,
        ranges={name: reduced_range(h, null) for name, h in hessians.items()},
        lam_g=lam_g, lam_c=lam_c, row_states=row_states, singular_values=singular,
        share=share, point=(mpcc, w, p))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", help="a shipped task's name or a task file")
    parser.add_argument("--iterations", type=int, default=100,
                        help="IPOPT iterations of the first NLP before its iterate is read")
    args = parser.parse_args()
    found = curvature(args.task, args.iterations)
    print(f"{found.task}: NLP 1 (sigma {found.sigma:g}) after {found.iterations} IPOPT "
          f"iterations, objective {found.objective:.4g}\n\n"
          "| Hessian part, on the null space of the equality rows | smallest eigenvalue "
          "| largest | negative |\n| --- | --- | --- | --- |")
    for name, (low, high, negative) in found.ranges.items():
        print(f"| {name} | {low:.3g} | {high:.3g} | {negative} |")
    lam = found.lam_g
    print(f"\nLargest |lambda_g| {np.abs(lam).max():.3g} (Scholtes rows: "
          f"{np.abs(found.lam_c).max():.3g}); rows above 1e7: {int((np.abs(lam) > 1e7).sum())}."
          " The 12 largest:")
    for row in np.argsort(-np.abs(lam))[:12]:
        print(f"  row {row:5d}: lambda {lam[row]: .3e}, states {found.row_states[row]}")
    s = found.singular_values
    print(f"\nEquality rows: largest singular value {s[0]:.3g}, smallest "
          + ", ".join(f"{v:.2g}" for v in s[-5:])
          + f"; the 20 smallest carry {found.share:.1%} of the multipliers' norm")


if __name__ == "__main__":
    main()
