"""Linear complementarity problems by Lemke's algorithm (SciPy has no LCP solver).

Find z with w = M z + q >= 0, z >= 0, z^T w = 0 (LCP(M, q)). Lemke's complementary
pivoting with the covering vector e = (1, ..., 1) and a lexicographic ratio test (so that
degenerate problems do not cycle). It finds a solution whenever M is copositive-plus and
the LCP is feasible (Cottle, Pang, Stone, "The Linear Complementarity Problem", 1992,
Theorem 4.4.13), which covers the frictional contact LCPs of `tfcontact.verify.multicontact`
(Stewart and Trinkle, IJNME 39 (1996) 2673). A ray termination for any other M means no
solution was found (for a slipping contact in Painleve's region: none exists).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tfcontact.errors import InvalidInput


@dataclass(frozen=True, eq=False)
class LcpSolution:
    """The outcome of `solve_lcp`.

    Attributes:
        z: the solution, shape (n,) (the last iterate if not solved).
        w: M z + q, shape (n,).
        status: "solved", "ray" (Lemke's ray termination: no solution found; for a
            copositive-plus M the LCP is infeasible) or "max_pivots".
        pivots: the pivots made.
    """

    z: np.ndarray
    w: np.ndarray
    status: str
    pivots: int

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    def residual(self) -> float:
        """max(-min(z), -min(w), max |z_i w_i|): 0 for an exact solution."""
        if self.z.size == 0:
            return 0.0
        return float(max(-self.z.min(), -self.w.min(), np.abs(self.z * self.w).max(), 0.0))


def solve_lcp(M: np.ndarray, q: np.ndarray, *, max_pivots: int | None = None,
              tolerance: float = 1e-12) -> LcpSolution:
    """Solve LCP(M, q) by Lemke's algorithm (module docstring).

    Args:
        M: shape (n, n).
        q: shape (n,).
        max_pivots: pivot budget (default 50 n + 50).
        tolerance: pivot entries below this times the column's largest entry count as zero.

    Returns:
        An `LcpSolution`; check `status` (no exception for an unsolved problem).

    Raises:
        InvalidInput: shapes disagree or entries are not finite.
    """
    M = np.asarray(M, dtype=float)
    q = np.asarray(q, dtype=float).ravel()
    n = q.size
    if M.shape != (n, n):
        raise InvalidInput(f"`M` must have shape ({n}, {n}) for `q` of size {n}, "
                           f"got {M.shape}")
    if not (np.all(np.isfinite(M)) and np.all(np.isfinite(q))):
        raise InvalidInput("`M` and `q` must be finite")
    budget = 50 * n + 50 if max_pivots is None else max_pivots
    if n == 0 or q.min() >= 0.0:
        return LcpSolution(np.zeros(n), q.copy(), "solved", 0)
    # Tableau columns: w (0..n-1), z (n..2n-1), z0 (2n), rhs (2n+1); rows: basic variables.
    tableau = np.hstack([np.eye(n), -M, -np.ones((n, 1)), q[:, None]])
    basis = list(range(n))
    z0 = 2 * n

    def pivot(row: int, col: int) -> None:
        tableau[row] /= tableau[row, col]
        others = np.arange(n) != row
        tableau[others] -= np.outer(tableau[others, col], tableau[row])

    row = int(np.argmin(q))
    leaving = basis[row]
    pivot(row, z0)
    basis[row] = z0
    status = "max_pivots"
    pivots = 1
    while pivots < budget:
        entering = leaving + n if leaving < n else leaving - n  # the complement
        column = tableau[:, entering]
        scale = max(float(np.abs(column).max()), 1e-300)
        candidates = np.flatnonzero(column > tolerance * scale)
        if candidates.size == 0:
            status = "ray"
            break
        row = _lexicographic_min(tableau, column, candidates, n)
        if z0 in (basis[i] for i in candidates):
            # Let z0 leave on a tie: that ends the algorithm with a solution.
            ratios = tableau[candidates, -1] / column[candidates]
            z0_row = next(i for i in candidates if basis[i] == z0)
            if tableau[z0_row, -1] / column[z0_row] <= ratios.min() + 1e-12 * (
                    1.0 + abs(ratios.min())):
                row = int(z0_row)
        leaving = basis[row]
        pivot(row, entering)
        basis[row] = entering
        pivots += 1
        if leaving == z0:
            status = "solved"
            break
    values = np.zeros(2 * n + 1)
    values[basis] = np.maximum(tableau[:, -1], 0.0)
    z = values[n:2 * n]
    if status == "solved":
        z = _refined(M, q, z, [b - n for b in basis if n <= b < 2 * n])
    return LcpSolution(z, M @ z + q, status, pivots)


def _refined(M: np.ndarray, q: np.ndarray, z: np.ndarray, active: list[int]) -> np.ndarray:
    """z recomputed from its basis (M_aa z_a = -q_a) when that is at least as accurate:
    the tableau's updates accumulate rounding over many pivots."""
    if not active:
        return z
    refined = np.zeros_like(z)
    refined[active] = np.linalg.lstsq(M[np.ix_(active, active)], -q[active], rcond=None)[0]

    def residual(x: np.ndarray) -> float:
        w = M @ x + q
        return float(max(-x.min(), -w.min(), np.abs(x * w).max(), 0.0))
    return refined if residual(refined) <= residual(z) else z


def _lexicographic_min(tableau: np.ndarray, column: np.ndarray, candidates: np.ndarray,
                       n: int) -> int:
    """The row of the minimum ratio, ties broken lexicographically on B^-1 (the w columns)
    divided by the pivot column: no cycling on degenerate problems."""
    ratios = tableau[candidates, -1] / column[candidates]
    best = ratios.min()
    tied = candidates[ratios <= best + 1e-12 * (1.0 + abs(best))]
    for k in range(n):
        if tied.size == 1:
            break
        values = tableau[tied, k] / column[tied]
        low = values.min()
        tied = tied[values <= low + 1e-12 * (1.0 + abs(low))]
    return int(tied[0]) if math.isfinite(best) else int(candidates[0])
