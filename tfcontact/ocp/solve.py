"""Transcription of an `OptimalControlProblem` into an MPCC (build) and its solution (solve).

`build` discretises the system with FESD (tfcontact.fesd.discretize), then adds the cost
(the Lagrange term by the collocation quadrature sum_e h_e sum_j b_j L(X_{e,j}, u)),
the bounds, path, terminal and interval-boundary constraints and the initial guess.
`solve` runs the MPCC homotopy (tfcontact.mpcc) and maps the solution back onto the grid.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, SolveFailed, positive_int
from tfcontact.fesd.discretization import (
    DEFAULT_METHOD,
    DEFAULT_SCHEME,
    Discretization,
    FesdGrid,
    Method,
    discretize,
)
from tfcontact.fesd.tableau import Scheme, Tableau
from tfcontact.mpcc import (
    Homotopy,
    Ipopt,
    Mpcc,
    MpccResult,
    MpccSolver,
    MpccStatus,
    Relaxation,
    Scholtes,
)
from tfcontact.ocp.problem import OptimalControlProblem


@dataclass(frozen=True)
class Transcription:
    """How the OCP is discretised.

    Args:
        scheme: `RadauIIA(s)` (default s = 2) or `GaussLegendre(s)`.
        n_finite_elements: N_FE finite elements per control interval.
        method: `Fesd(...)` (default) or `Standard()`.
    """

    scheme: Scheme | Tableau = DEFAULT_SCHEME
    n_finite_elements: int = 2
    method: Method = DEFAULT_METHOD

    def __post_init__(self) -> None:
        positive_int(self.n_finite_elements, "n_finite_elements")


DEFAULT_TRANSCRIPTION = Transcription()


@dataclass(frozen=True, eq=False)
class OcpBuild:
    """An OCP transcribed into an MPCC, not solved.

    Attributes:
        problem: the OCP.
        mpcc: the MPCC (p = x0; objective = cost + step equilibration penalty).
        discretization: the FESD discretisation with its index maps (`layout`).
        cost: SX in (w, p): the OCP's own cost (no step equilibration penalty).
        p: the parameter values (x0).
        build_time: seconds [s].
    """

    problem: OptimalControlProblem
    mpcc: Mpcc
    discretization: Discretization
    cost: ca.SX
    p: np.ndarray
    build_time: float

    @property
    def interval_indices(self) -> np.ndarray:
        """(N + 1, n_x) indices into w of the states at the interval boundaries."""
        n_fe = self.discretization.grid.n_finite_elements
        return self.discretization.layout.x[::n_fe]


def _quadrature(disc: Discretization, lagrange: ca.SX, system) -> ca.SX:
    """sum_e h_e sum_j b_j L(X_{e,j}, u_{n(e)}) as an SX scalar in w."""
    tab, lay, grid = disc.tableau, disc.layout, disc.grid
    if lagrange.is_zero():
        return ca.SX(0)
    E, s = grid.n_elements, tab.stages
    L = ca.Function("lagrange", [system.x, system.u], [lagrange])
    w = disc.mpcc.w
    X = ca.reshape(w[lay.x_stages.reshape(-1).tolist()], system.n_x, E * s)
    u_pts = np.repeat(np.repeat(lay.u, grid.n_finite_elements, axis=0), s, axis=0)
    U = (ca.reshape(w[u_pts.reshape(-1).tolist()], system.n_u, E * s) if system.n_u
         else ca.SX(0, E * s))
    values = ca.reshape(L.map(E * s)(X, U), s, E)  # column e: L at the stages of element e
    per_element = ca.mtimes(ca.DM(tab.b).T, values)  # (1, E)
    h = w[lay.h.tolist()] if lay.h is not None else ca.SX(ca.DM.ones(E, 1) * grid.h0)
    return ca.mtimes(per_element, h)


def build(problem: OptimalControlProblem, *,
          discretization: Transcription = DEFAULT_TRANSCRIPTION) -> OcpBuild:
    """Transcribe an OCP into an MPCC (nothing is solved).

    Args:
        problem: the OCP.
        discretization: scheme, finite elements per interval and method.

    Returns:
        An `OcpBuild`: the MPCC with named blocks ("x", "x_stages", "u", "h", algebraic
        blocks) and the discretisation's index maps.
    """
    if not isinstance(problem, OptimalControlProblem):
        raise InvalidInput(
            f"`problem` must be an OptimalControlProblem, got {type(problem).__name__}"
        )
    if not isinstance(discretization, Transcription):
        raise InvalidInput(
            "`discretization` must be a Transcription(scheme=..., n_finite_elements=..., "
            f"method=...), got {type(discretization).__name__}"
        )
    start = time.perf_counter()
    sys = problem.system
    grid = FesdGrid(problem.n_intervals, discretization.n_finite_elements, problem.horizon)
    disc = discretize(sys, grid=grid, scheme=discretization.scheme,
                      method=discretization.method, controls="variables")
    base = disc.mpcc
    lay = disc.layout
    w = base.w
    n_x, n_u, N, n_fe = sys.n_x, sys.n_u, grid.n_intervals, grid.n_finite_elements
    E, s = grid.n_elements, disc.tableau.stages

    # cost
    cost = _quadrature(disc, problem.lagrange, sys)
    if not problem.mayer.is_zero():
        mayer = ca.Function("mayer", [sys.x], [problem.mayer])
        cost = cost + mayer(w[lay.x[-1].tolist()])

    # bounds
    lbw, ubw = base.lbw.copy(), base.ubw.copy()
    if n_u:
        lbw[lay.u] = problem.u_lower
        ubw[lay.u] = problem.u_upper
    x_after = np.concatenate([lay.x[1:].reshape(-1), lay.x_stages.reshape(-1)])
    lbw[x_after] = np.tile(problem.x_lower, x_after.size // n_x)
    ubw[x_after] = np.tile(problem.x_upper, x_after.size // n_x)

    # constraints
    g, lbg, ubg = [base.g], [base.lbg], [base.ubg]

    def add(expr: ca.SX, lower: np.ndarray, upper: np.ndarray) -> None:
        g.append(expr)
        lbg.append(np.asarray(lower, dtype=float).reshape(-1))
        ubg.append(np.asarray(upper, dtype=float).reshape(-1))

    if problem.path is not None and problem.path.size:
        path = ca.Function("path", [sys.x, sys.u], [problem.path.expression])
        points = lay.x_stages.reshape(E * s, n_x)
        u_pts = np.repeat(np.repeat(lay.u, n_fe, axis=0), s, axis=0)
        if not disc.tableau.stiffly_accurate:
            points = np.vstack([points, lay.x[1:]])
            u_pts = np.vstack([u_pts, np.repeat(lay.u, n_fe, axis=0)])
        n_pts = points.shape[0]
        X = ca.reshape(w[points.reshape(-1).tolist()], n_x, n_pts)
        U = ca.reshape(w[u_pts.reshape(-1).tolist()], n_u, n_pts) if n_u else ca.SX(0, n_pts)
        add(ca.vec(path.map(n_pts)(X, U)), np.tile(problem.path.lower, n_pts),
            np.tile(problem.path.upper, n_pts))
    if problem.terminal is not None and problem.terminal.size:
        terminal = ca.Function("terminal", [sys.x], [problem.terminal.expression])
        add(terminal(w[lay.x[-1].tolist()]), problem.terminal.lower, problem.terminal.upper)
    if problem.boundary_constraints is not None:
        for k in range(1, N + 1):
            xk = w[lay.x[k * n_fe].tolist()]
            con = problem.boundary_constraints(k, xk)
            if con is None:
                continue
            if not hasattr(con, "expression"):
                raise InvalidInput(
                    f"`boundary_constraints` returned {type(con).__name__} for k = {k}; "
                    "return a Constraint or None"
                )
            free = {v.name() for v in ca.symvar(con.expression)} - {
                v.name() for v in ca.symvar(w)}
            if free:
                raise InvalidInput(
                    f"`boundary_constraints` for k = {k} uses symbols {sorted(free)}; "
                    "build it from the state x_k it is given"
                )
            add(con.expression, con.lower, con.upper)

    # initial guess
    w0 = _initial_guess(problem, disc)
    mpcc = dataclasses.replace(
        base, f=base.f + cost, g=ca.vertcat(*g), lbg=np.concatenate(lbg),
        ubg=np.concatenate(ubg), lbw=lbw, ubw=ubw, w0=np.clip(w0, lbw, ubw),
    )
    return OcpBuild(problem=problem, mpcc=mpcc, discretization=disc, cost=cost,
                    p=problem.x0.copy(), build_time=time.perf_counter() - start)


def _initial_guess(problem: OptimalControlProblem, disc: Discretization) -> np.ndarray:
    lay, grid = disc.layout, disc.grid
    N, n_u = grid.n_intervals, problem.n_u
    if problem.u_guess is not None:
        u = np.broadcast_to(problem.u_guess, (N, n_u))
    else:
        u = np.broadcast_to(np.clip(0.0, problem.u_lower, problem.u_upper), (N, n_u))
    w0 = disc.initial_guess(problem.x0, u)
    if problem.x_guess is None or problem.x_guess.ndim == 1:
        x_const = problem.x0 if problem.x_guess is None else problem.x_guess
        if problem.x_guess is not None:
            w0 = disc.initial_guess(x_const, u)
        w0[lay.x[0]] = problem.x0
        return w0
    # a trajectory guess at the interval boundaries: interpolate onto all points,
    # with algebraic variables consistent with the guessed state at each point
    t_int = np.linspace(0.0, grid.horizon, N + 1)
    t_b = np.linspace(0.0, grid.horizon, grid.n_elements + 1)
    t_st = t_b[:-1, None] + grid.h0 * disc.tableau.c[None, :]
    xg = problem.x_guess

    def interp(t: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, t_int, xg[:, i]) for i in range(problem.n_x)], axis=-1)

    w0[lay.x] = interp(t_b)
    w0[lay.x_stages] = interp(t_st)
    form = disc.form
    for e in range(grid.n_elements):
        for j in range(disc.tableau.stages):
            z = form.guess(w0[lay.x_stages[e, j]])
            k = 0
            for b in form.stage_blocks:
                w0[lay.z[b.name][e, j]] = z[k:k + b.size]
                k += b.size
        for b in form.boundary_blocks:
            if b.name in lay.zb:
                w0[lay.zb[b.name][e]] = w0[lay.z[b.name.removesuffix("_end")][e, -1]]
    w0[lay.x[0]] = problem.x0
    return w0


@dataclass(frozen=True, eq=False)
class OcpResult:
    """The solution of an OCP on its grid, with status and work counters.

    Shapes use N intervals, E = N N_FE elements, s stages.

    Attributes:
        status: `MpccStatus` (CONVERGED, NOT_CONVERGED, NLP_FAILED); `success`, `message`.
        objective: the MPCC objective (cost + step equilibration penalty); cost: the OCP cost.
        t: (E + 1,) element boundary times [s]; x: (E + 1, n_x) states there.
        t_intervals: (N + 1,) interval boundary times [s]; x_intervals: states there.
        t_stages, x_stages: (E, s), (E, s, n_x).
        u: (N, n_u) controls; h: (E,) element lengths [s].
        algebraic: algebraic variables by block name.
        switch_times: element boundaries where the active set changes [s].
        residual: complementarity residual max |G_i H_i|.
        n_nlps, iterations (per NLP), total_iterations, nlp_times [s].
        build_time, solve_time [s].
        mpcc_result: the homotopy's `MpccResult`; build: the `OcpBuild`.
    """

    status: MpccStatus
    objective: float
    cost: float
    t: np.ndarray
    x: np.ndarray
    t_stages: np.ndarray
    x_stages: np.ndarray
    u: np.ndarray
    h: np.ndarray
    algebraic: dict[str, np.ndarray]
    switch_times: np.ndarray
    residual: float
    build_time: float
    solve_time: float
    mpcc_result: MpccResult
    build: OcpBuild

    @property
    def success(self) -> bool:
        return self.status is MpccStatus.CONVERGED

    @property
    def message(self) -> str:
        return self.mpcc_result.message

    @property
    def ipopt_status(self) -> str:
        return self.mpcc_result.ipopt_status

    @property
    def n_nlps(self) -> int:
        return self.mpcc_result.n_nlps

    @property
    def iterations(self) -> list[int]:
        return self.mpcc_result.iterations

    @property
    def total_iterations(self) -> int:
        return self.mpcc_result.total_iterations

    @property
    def nlp_times(self) -> list[float]:
        return self.mpcc_result.nlp_times

    @property
    def t_intervals(self) -> np.ndarray:
        return self.t[:: self.build.discretization.grid.n_finite_elements]

    @property
    def x_intervals(self) -> np.ndarray:
        return self.x[:: self.build.discretization.grid.n_finite_elements]

    def complementarity_residual(self) -> float:
        """max_i |G_i H_i| at the solution."""
        return self.residual


def solve(
    problem: OptimalControlProblem | OcpBuild,
    *,
    discretization: Transcription = DEFAULT_TRANSCRIPTION,
    relaxation: Relaxation | None = None,
    homotopy: Homotopy | None = None,
    nlp: Ipopt | None = None,
    w0: np.ndarray | None = None,
    verbose: bool = True,
    throw: bool = True,
) -> OcpResult:
    """Solve an OCP: transcribe (unless given an `OcpBuild`), then run the MPCC homotopy.

    Main args:
        problem: the `OptimalControlProblem`, or an `OcpBuild` from `build`.

    Other args:
        discretization: `Transcription(scheme, n_finite_elements, method)` (ignored for
            an `OcpBuild`).
        relaxation: `Scholtes()` (default), `L1Penalty()` or `LinfPenalty()`.
        homotopy: `Homotopy()` by default (sigma_0 = 1, kappa = 0.1, residual 1e-9).
        nlp: `Ipopt()` settings.
        w0: initial guess of the MPCC variables (default: the problem's guess).
        verbose: one line per NLP: sigma, IPOPT iterations, objective, residual, seconds.
        throw: raise `SolveFailed` (with this result as `.result`) unless converged.

    Returns:
        An `OcpResult` (the last iterate if not converged and `throw` is False).

    Raises:
        SolveFailed: the homotopy did not converge and `throw`.
    """
    built = problem if isinstance(problem, OcpBuild) else build(
        problem, discretization=discretization)
    solver = MpccSolver(built.mpcc, relaxation=relaxation if relaxation is not None
                        else Scholtes(), nlp=nlp)
    if verbose:
        disc = built.discretization
        print(f"OCP: N = {disc.grid.n_intervals}, N_FE = {disc.grid.n_finite_elements}, "
              f"{disc.tableau.name}, {type(disc.method).__name__}: "
              f"{built.mpcc.n_w} variables, {built.mpcc.n_g} constraints, "
              f"{built.mpcc.n_comp} complementarity pairs; build {built.build_time:.3f} s, "
              f"NLP build {solver.build_time:.3f} s", flush=True)
    res = solver.solve(built.p, w0, homotopy=homotopy, verbose=verbose)
    disc = built.discretization
    w = res.w
    cost = float(ca.Function("cost", [built.mpcc.w, built.mpcc.p], [built.cost])(w, built.p))
    result = OcpResult(
        status=res.status, objective=res.objective, cost=cost, t=disc.times(w),
        x=disc.states(w), t_stages=disc.stage_times(w), x_stages=disc.stage_states(w),
        u=w[disc.layout.u], h=disc.steps(w), algebraic=disc.algebraic(w),
        switch_times=disc.switch_times(w), residual=res.residual,
        build_time=built.build_time + solver.build_time, solve_time=res.solve_time,
        mpcc_result=res, build=built,
    )
    if verbose:
        print(f"OCP: {res.message}; cost {cost:.6g}", flush=True)
    if throw and not result.success:
        raise SolveFailed(result.message, result)
    return result
