"""Mixed-integer baseline for the time-optimal car with hysteresis (PROBLEMS.md TF-13).

The comparison method of Nurkanovic and Diehl (IEEE CSL 2022, section V; nosnoc's
`hysteresis_car_minlp_formulation.m`): a fixed grid of N control intervals of length
h = T/N, one binary mode variable per interval, big-M hysteresis logic, switches only on
grid points, a feasibility MILP for each fixed T and bisection on T for the minimum time.
The paper used Gurobi; here HiGHS through `scipy.optimize.milp`.

Formulation (k = 0..N-1 intervals, grid points 0..N; b_k = 1: turbo on interval k):

* exact discretisation of q' = v, v' = u (nominal) or k_turbo u (turbo) for u piecewise
  constant and the mode fixed on each interval, with the bilinear b_k u_k replaced by
  a_k and its exact McCormick/big-M envelope (b_k binary, |u_k| <= U):
      v_{k+1} = v_k + h (u_k + (k_turbo - 1) a_k)
      q_{k+1} = q_k + h v_k + h^2/2 (u_k + (k_turbo - 1) a_k)
      -U b_k <= a_k <= U b_k,   -U (1 - b_k) <= u_k - a_k <= U (1 - b_k)
* the automaton's invariants on the whole interval (v is affine on it, so the two end
  points suffice): nominal keeps v <= v_2, turbo keeps v >= v_1
      v_k, v_{k+1} <= v_2 + (v_max - v_2) b_k,   v_k, v_{k+1} >= v_1 - (v_1 - v_min)(1 - b_k)
* guards on grid points: nominal -> turbo at grid point k only if v_k >= v_2,
  turbo -> nominal only if v_k <= v_1
      v_k >= v_2 - (v_2 - v_min)(1 - b_k + b_{k-1}),  v_k <= v_1 + (v_max - v_1)(1 - b_{k-1} + b_k)
  with b_{-1} the initial mode.

The invariants make the nominal mode leave at v_2 exactly (it cannot pass it), so every
feasible plan is an exact trajectory of the automaton: its accuracy is limited by the
solver's feasibility tolerance only, and the price of the grid is paid in T (switches
must fall on grid points, so the plan slows down to meet v_2 on one).

`sampled_guards=True` gives the variant closer to nosnoc's MILP script (its guards are
only tested at discretisation points): no invariants inside the intervals, and the mode
of interval k is the automaton's response to the sampled velocity v_k,
    b_{k-1} = 0, v_k >= v_2 => b_k = 1:  v_k <= v_2 - eps + (v_max - v_2 + eps)(b_k + b_{k-1})
    b_{k-1} = 1, v_k <= v_1 => b_k = 0:  v_k >= v_1 + eps - (v_1 - v_min + eps)(2 - b_k - b_{k-1})
with eps = 1e-6 m/s, plus the guards above. The velocity may then cross a threshold
inside an interval while the plan keeps the old mode up to the next grid point: the plan
is a sampled-data model of the automaton and the event-located simulation of its
controls measures the resulting terminal error.
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import Bounds, LinearConstraint, milp

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.scenes.car import NOMINAL, TF13, TURBO, CarProblem

_EPS = 1e-6  # [m/s] strictness margin of the sampled guards (nosnoc's script uses 1e-6)


@dataclass(frozen=True)
class MilpOptions:
    """HiGHS options for one feasibility MILP.

    Args:
        time_limit: wall-clock limit per MILP [s]; a MILP that hits it without a
            feasible point counts as infeasible (unproven) in the bisection.
        presolve: HiGHS presolve on/off.
    """

    time_limit: float = 20.0
    presolve: bool = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.time_limit) and self.time_limit > 0):
            raise InvalidInput(
                f"`time_limit` must be a positive number of seconds, got {self.time_limit}"
            )


@dataclass(frozen=True)
class Bisection:
    """Bisection on the final time T [s].

    Args:
        lower, upper: the initial bracket [s] (the paper's 5 and 20); `upper` must be feasible.
        tolerance: stop when upper - lower <= tolerance [s].
        max_milps: hard cap on the number of MILPs.
    """

    lower: float = 5.0
    upper: float = 20.0
    tolerance: float = 1e-6
    max_milps: int = 60

    def __post_init__(self) -> None:
        if not 0 < self.lower < self.upper:
            raise InvalidInput(
                f"need 0 < `lower` < `upper`, got lower = {self.lower}, upper = {self.upper}"
            )
        if self.tolerance <= 0:
            raise InvalidInput(f"`tolerance` must be positive, got {self.tolerance}")
        if self.max_milps < 1:
            raise InvalidInput(f"`max_milps` must be at least 1, got {self.max_milps}")


class MilpStatus(enum.Enum):
    FEASIBLE = "feasible"
    INFEASIBLE = "infeasible"
    TIME_LIMIT = "time limit reached without a feasible point (treated as infeasible)"
    FAILED = "HiGHS failed"


@dataclass(frozen=True)
class CarMilp:
    """The built MILP for one (N, T): min c^T z s.t. lb_A <= A z <= ub_A, bounds, integrality.

    Attributes:
        blocks: name -> indices into z: "q", "v" (N + 1 each), "u", "a", "b" (N each).
    """

    n_intervals: int
    final_time: float
    c: np.ndarray
    A: sp.csr_matrix
    lb_A: np.ndarray
    ub_A: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    integrality: np.ndarray
    blocks: dict[str, np.ndarray]

    @property
    def n_variables(self) -> int:
        return self.c.size

    @property
    def n_binaries(self) -> int:
        return int(self.integrality.sum())


@dataclass(frozen=True)
class CarMilpSolution:
    """One feasibility MILP. Arrays are empty unless status is FEASIBLE."""

    status: MilpStatus
    message: str
    final_time: float
    controls: np.ndarray
    modes: np.ndarray
    q: np.ndarray
    v: np.ndarray
    nodes: int
    wall_time: float
    cpu_time: float

    @property
    def feasible(self) -> bool:
        return self.status is MilpStatus.FEASIBLE


@dataclass(frozen=True)
class CarMilpResult:
    """Minimum time by bisection on T.

    Attributes:
        final_time: the smallest feasible T found [s] (the bisection's upper end).
        lower_bound: the largest T found infeasible [s] (or the initial bracket end).
        best: the feasible MILP solution at `final_time`.
        history: every MILP solved, in order.
        n_milps, nodes: work counters (MILPs, branch-and-bound nodes summed).
        wall_time, cpu_time: summed over the MILPs [s] (build included).
    """

    final_time: float
    lower_bound: float
    best: CarMilpSolution
    history: list[CarMilpSolution] = field(repr=False)

    @property
    def n_milps(self) -> int:
        return len(self.history)

    @property
    def nodes(self) -> int:
        return int(sum(s.nodes for s in self.history))

    @property
    def wall_time(self) -> float:
        return float(sum(s.wall_time for s in self.history))

    @property
    def cpu_time(self) -> float:
        return float(sum(s.cpu_time for s in self.history))

    @property
    def times(self) -> np.ndarray:
        """The equidistant control grid [s] of the best plan."""
        return np.linspace(0.0, self.final_time, self.best.controls.size + 1)

    @property
    def unproven(self) -> int:
        """MILPs that hit the time limit and were counted as infeasible."""
        return sum(s.status is MilpStatus.TIME_LIMIT for s in self.history)


def build_car_milp(
    n_intervals: int,
    final_time: float,
    problem: CarProblem = TF13,
    *,
    initial_mode: int = NOMINAL,
    sampled_guards: bool = False,
) -> CarMilp:
    """Assemble the feasibility MILP of the module docstring for N intervals and horizon T.

    Args:
        n_intervals: N, control intervals (each with its own u_k and binary b_k).
        final_time: T [s], fixed.
        problem: the car data; start from rest at q = 0, end at (q_goal, v_goal).
        initial_mode: the automaton's mode at t = 0.
        sampled_guards: drop the invariants inside the intervals and force the switch
            from the sampled v_k instead (see the module docstring).
    """
    positive_int(n_intervals, "n_intervals")
    if not (np.isfinite(final_time) and final_time > 0):
        raise InvalidInput(f"`final_time` must be a positive number of seconds, got {final_time}")
    if initial_mode not in (NOMINAL, TURBO):
        raise InvalidInput(f"`initial_mode` must be NOMINAL (0) or TURBO (1), got {initial_mode}")
    p = problem
    n = int(n_intervals)
    h = final_time / n
    iq = np.arange(n + 1)
    iv = n + 1 + np.arange(n + 1)
    base = 2 * (n + 1)
    iu = base + np.arange(n)
    ia = base + n + np.arange(n)
    ib = base + 2 * n + np.arange(n)
    nz = base + 3 * n
    U = p.u_max
    extra = p.turbo_gain - 1.0
    m_nominal = p.v_max - p.v_turbo_on  # nominal invariant v <= v_2
    m_turbo = p.v_turbo_off - p.v_min  # turbo invariant v >= v_1
    m_on = p.v_turbo_on - p.v_min  # guard nominal -> turbo
    m_off = p.v_max - p.v_turbo_off  # guard turbo -> nominal

    rows: list[dict[int, float]] = []
    lo: list[float] = []
    hi: list[float] = []

    def row(coeffs: dict[int, float], lower: float, upper: float) -> None:
        rows.append(coeffs)
        lo.append(lower)
        hi.append(upper)

    inf = np.inf
    for k in range(n):
        q0, q1, v0, v1 = iq[k], iq[k + 1], iv[k], iv[k + 1]
        u, a, b = iu[k], ia[k], ib[k]
        # exact discretisation of the double integrator with acceleration u + extra a
        row({v1: 1.0, v0: -1.0, u: -h, a: -h * extra}, 0.0, 0.0)
        row({q1: 1.0, q0: -1.0, v0: -h, u: -h * h / 2, a: -h * h / 2 * extra}, 0.0, 0.0)
        # a = b u (exact for binary b and |u| <= U)
        row({a: 1.0, b: -U}, -inf, 0.0)
        row({a: -1.0, b: -U}, -inf, 0.0)
        row({u: 1.0, a: -1.0, b: U}, -inf, U)
        row({u: -1.0, a: 1.0, b: U}, -inf, U)
        if not sampled_guards:
            # invariants on the interval (end points of an affine v)
            for vi in (v0, v1):
                row({vi: 1.0, b: -m_nominal}, -inf, p.v_turbo_on)
                row({vi: 1.0, b: -m_turbo}, p.v_turbo_off - m_turbo, inf)
        elif k > 0:
            # forced switches from the sampled velocity (b_{-1} = initial mode: v_0 is fixed)
            bp = ib[k - 1]
            m_f = m_nominal + _EPS
            row({v0: 1.0, b: -m_f, bp: -m_f}, -inf, p.v_turbo_on - _EPS)
            m_f = m_turbo + _EPS
            row({v0: 1.0, b: -m_f, bp: -m_f}, p.v_turbo_off + _EPS - 2 * m_f, inf)
        # guards on grid point k (b_{-1} = initial mode is a constant)
        if k == 0:
            row({v0: 1.0, b: -m_on}, p.v_turbo_on - m_on - m_on * initial_mode, inf)
            row({v0: 1.0, b: -m_off}, -inf, p.v_turbo_off + m_off - m_off * initial_mode)
        else:
            bp = ib[k - 1]
            row({v0: 1.0, b: -m_on, bp: m_on}, p.v_turbo_on - m_on, inf)
            row({v0: 1.0, b: -m_off, bp: m_off}, -inf, p.v_turbo_off + m_off)

    data, ri, ci = [], [], []
    for r, coeffs in enumerate(rows):
        for j, val in coeffs.items():
            ri.append(r)
            ci.append(j)
            data.append(val)
    A = sp.csr_matrix((data, (ri, ci)), shape=(len(rows), nz))

    lb = np.full(nz, -np.inf)
    ub = np.full(nz, np.inf)
    lb[iv], ub[iv] = p.v_min, p.v_max
    lb[iu], ub[iu] = -U, U
    lb[ia], ub[ia] = -U, U
    lb[ib], ub[ib] = 0.0, 1.0
    lb[iq[0]] = ub[iq[0]] = 0.0
    lb[iv[0]] = ub[iv[0]] = 0.0
    lb[iq[-1]] = ub[iq[-1]] = p.q_goal
    lb[iv[-1]] = ub[iv[-1]] = p.v_goal
    integrality = np.zeros(nz)
    integrality[ib] = 1
    return CarMilp(
        n_intervals=n,
        final_time=float(final_time),
        c=np.zeros(nz),
        A=A,
        lb_A=np.array(lo),
        ub_A=np.array(hi),
        lb=lb,
        ub=ub,
        integrality=integrality,
        blocks={"q": iq, "v": iv, "u": iu, "a": ia, "b": ib},
    )


def solve_car_milp(
    n_intervals: int,
    final_time: float,
    problem: CarProblem = TF13,
    *,
    options: MilpOptions = MilpOptions(),
    sampled_guards: bool = False,
) -> CarMilpSolution:
    """Build and solve the feasibility MILP for one (N, T) with HiGHS."""
    wall0, cpu0 = time.perf_counter(), time.process_time()
    model = build_car_milp(n_intervals, final_time, problem, sampled_guards=sampled_guards)
    res = milp(
        c=model.c,
        constraints=LinearConstraint(model.A, model.lb_A, model.ub_A),
        bounds=Bounds(model.lb, model.ub),
        integrality=model.integrality,
        options={"time_limit": options.time_limit, "presolve": options.presolve},
    )
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    nodes = int(getattr(res, "mip_node_count", 0) or 0)
    empty = np.zeros(0)
    if res.x is not None and res.status in (0, 1):
        z = res.x
        b = model.blocks
        return CarMilpSolution(
            status=MilpStatus.FEASIBLE,
            message=res.message,
            final_time=float(final_time),
            controls=z[b["u"]].copy(),
            modes=np.rint(z[b["b"]]).astype(int),
            q=z[b["q"]].copy(),
            v=z[b["v"]].copy(),
            nodes=nodes,
            wall_time=wall,
            cpu_time=cpu,
        )
    if res.status == 2:
        status = MilpStatus.INFEASIBLE
    elif res.status == 1:
        status = MilpStatus.TIME_LIMIT
    else:
        status = MilpStatus.FAILED
    return CarMilpSolution(
        status=status,
        message=res.message,
        final_time=float(final_time),
        controls=empty,
        modes=empty.astype(int),
        q=empty,
        v=empty,
        nodes=nodes,
        wall_time=wall,
        cpu_time=cpu,
    )


def car_minimum_time_milp(
    n_intervals: int,
    problem: CarProblem = TF13,
    *,
    bisection: Bisection = Bisection(),
    options: MilpOptions = MilpOptions(),
    sampled_guards: bool = False,
) -> CarMilpResult:
    """Minimum final time over the N-interval grid by bisection on T (feasibility MILPs).

    Returns:
        A `CarMilpResult`; its `final_time` is feasible and within `bisection.tolerance`
        of the largest T the bisection found infeasible.

    Raises:
        SolveFailed: if `bisection.upper` is infeasible or HiGHS fails.
    """
    from tfcontact.errors import SolveFailed

    history: list[CarMilpSolution] = []
    top = solve_car_milp(
        n_intervals, bisection.upper, problem, options=options, sampled_guards=sampled_guards
    )
    history.append(top)
    if not top.feasible:
        raise SolveFailed(
            f"the MILP with N = {n_intervals} is not feasible at the bracket's upper end "
            f"T = {bisection.upper} s ({top.status.value}); raise `Bisection.upper`",
            top,
        )
    lower, upper, best = bisection.lower, bisection.upper, top
    while upper - lower > bisection.tolerance and len(history) < bisection.max_milps:
        mid = 0.5 * (lower + upper)
        sol = solve_car_milp(
            n_intervals, mid, problem, options=options, sampled_guards=sampled_guards
        )
        history.append(sol)
        if sol.status is MilpStatus.FAILED:
            raise SolveFailed(f"HiGHS failed at T = {mid}: {sol.message}", sol)
        if sol.feasible:
            upper, best = mid, sol
        else:
            lower = mid
    return CarMilpResult(final_time=upper, lower_bound=lower, best=best, history=history)
