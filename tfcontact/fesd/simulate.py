"""Simulation of a piecewise smooth system with FESD, one MPCC per integration step.

Every step [t_k, t_k + T / n_steps] is one control interval of N_FE finite elements.
Its MPCC is built once with the step's initial state and control as parameters, its
relaxed NLP is built once (`MpccSolver`), and every step is a homotopy warm started
from the previous step's solution (states shifted to the step's initial state); a step
whose homotopy fails from there is retried once from the initial state with consistent
algebraic variables and the Scholtes relaxation. With FESD the switches land on element boundaries,
so the simulator reports them exactly (Nurkanovic et al., Numer. Math. 2024, section 4).
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from tfcontact.errors import InvalidInput, SolveFailed, positive_int
from tfcontact.fesd.discretization import (
    DEFAULT_METHOD,
    DEFAULT_SCHEME,
    Discretization,
    FesdGrid,
    Method,
    discretize,
    switch_times,
)
from tfcontact.fesd.system import HeavisideSystem, StewartSystem
from tfcontact.fesd.tableau import Scheme, Tableau
from tfcontact.mpcc import Homotopy, Ipopt, MpccResult, MpccSolver, Relaxation, Scholtes


class SimulationStatus(enum.Enum):
    """How a simulation ended."""

    SUCCESS = "success: every step's homotopy converged"
    STEP_FAILED = (
        "a step failed: its homotopy did not converge (see `message`); try more finite "
        "elements, a smaller step, a larger Homotopy.max_nlps or another relaxation"
    )


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """A simulated trajectory on the element boundaries, with the work it took.

    Shapes use K = n_steps, E = K N_FE elements, s stages.

    Attributes:
        status, message: how it ended (`success` is True when every step converged).
        t: (E + 1,) times of element boundaries [s], t[0] = 0.
        x: (E + 1, n_x) states there.
        t_stages, x_stages: (E, s) and (E, s, n_x) stage times [s] and states.
        algebraic: per block name ("theta", "lambda", "mu" or "alpha", "lambda_n",
            "lambda_p"; boundary blocks "*_end"), arrays (E, s, size) or (E, size).
        u: (K, n_u) the controls applied.
        h: (E,) element lengths [s].
        switch_times: times of element boundaries where the active set changes [s].
        n_nlps, total_iterations: NLPs solved and IPOPT iterations over all steps.
        residual: the largest complementarity residual over the steps.
        build_time: seconds to discretise and build the NLP [s]; solve_time: all steps [s].
        step_results: the `MpccResult` of every step solved (the retry's, if retried).
        n_retries: steps whose warm-started homotopy failed and were solved again from the
            consistent guess at x_k (their NLPs count in `n_nlps`).
        discretization: the one-step discretisation.
    """

    status: SimulationStatus
    message: str
    t: np.ndarray
    x: np.ndarray
    t_stages: np.ndarray
    x_stages: np.ndarray
    algebraic: dict[str, np.ndarray]
    u: np.ndarray
    h: np.ndarray
    switch_times: np.ndarray
    n_nlps: int
    total_iterations: int
    residual: float
    build_time: float
    solve_time: float
    step_results: tuple[MpccResult, ...]
    discretization: Discretization
    n_retries: int = 0

    @property
    def success(self) -> bool:
        return self.status is SimulationStatus.SUCCESS

    @property
    def n_steps(self) -> int:
        return len(self.step_results)


def _controls(u: object, n_steps: int, n_u: int) -> np.ndarray:
    if n_u == 0:
        if u is not None and np.asarray(u).size:
            raise InvalidInput(f"the system has no controls, got `u` of shape {np.shape(u)}")
        return np.zeros((n_steps, 0))
    if u is None:
        raise InvalidInput(f"the system has {n_u} controls: pass `u`")
    arr = np.asarray(u, dtype=float)
    if arr.size == n_u:
        return np.broadcast_to(arr.reshape(1, n_u), (n_steps, n_u)).copy()
    if arr.shape == (n_steps, n_u) or (n_u == 1 and arr.shape == (n_steps,)):
        return arr.reshape(n_steps, n_u).copy()
    raise InvalidInput(
        f"`u` must have shape ({n_u},) or (n_steps, n_u) = ({n_steps}, {n_u}), got {arr.shape}"
    )


def simulate(
    system: StewartSystem | HeavisideSystem,
    x0: np.ndarray,
    *,
    horizon: float,
    n_steps: int,
    u: np.ndarray | float | None = None,
    scheme: Scheme | Tableau = DEFAULT_SCHEME,
    n_finite_elements: int = 2,
    method: Method = DEFAULT_METHOD,
    homotopy: Homotopy | None = None,
    relaxation: Relaxation | None = None,
    nlp: Ipopt | None = None,
    retry: bool = True,
    verbose: bool = False,
    throw: bool = True,
) -> SimulationResult:
    """Simulate x' in F(x, u) on [0, horizon] with FESD (or the standard discretisation).

    Main args:
        system: a `StewartSystem` or `HeavisideSystem`.
        x0: initial state, shape (n_x,).
        horizon: T [s].
        n_steps: K integration steps of length T / K.
        u: controls, constant (n_u,) or per step (K, n_u); None for systems without controls.

    Other args:
        scheme: `RadauIIA(s)` (default s = 2) or `GaussLegendre(s)`.
        n_finite_elements: N_FE finite elements per step.
        method: `Fesd()` (default) or `Standard()`.
        homotopy: sigma schedule and tolerance (`Homotopy()`: sigma_0 = 1, kappa = 0.1,
            residual <= 1e-9).
        relaxation: `Scholtes()` (default), `L1Penalty()` or `LinfPenalty()`.
        nlp: IPOPT settings.
        retry: retry a failed step once from the consistent guess at x_k with the
            Scholtes relaxation and a gentler schedule (kappa -> sqrt(kappa), as many
            NLPs as it needs to reach the tolerance), counted in `n_retries`, its NLPs
            in `n_nlps`.
        verbose: print one line per NLP (from the MPCC layer) and one per step.
        throw: raise `SolveFailed` (result attached, up to the failed step) if a step fails.

    Returns:
        A `SimulationResult`.

    Raises:
        InvalidInput: wrong shapes or counts; SolveFailed: a step failed and `throw`.
    """
    n_steps = positive_int(n_steps, "n_steps")
    n_fe = positive_int(n_finite_elements, "n_finite_elements")
    if not isinstance(system, StewartSystem | HeavisideSystem):
        raise InvalidInput(
            f"`system` must be a StewartSystem or HeavisideSystem, got {type(system).__name__}"
        )
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.size != system.n_x:
        raise InvalidInput(f"`x0` has {x0.size} entries, expected n_x = {system.n_x}")
    if not np.all(np.isfinite(x0)):
        raise InvalidInput(f"`x0` must be finite, got {x0}")
    controls = _controls(u, n_steps, system.n_u)
    homotopy = homotopy if homotopy is not None else Homotopy()
    # An isolated IPOPT failure at one sigma (e.g. Infeasible_Problem_Detected where a
    # slip stops inside the step) is usually passed by smaller decrements of sigma.
    gentler = replace(homotopy, kappa=math.sqrt(homotopy.kappa), max_nlps=None)
    start = time.perf_counter()
    grid = FesdGrid(1, n_fe, float(horizon) / n_steps)
    disc = discretize(system, grid=grid, scheme=scheme, method=method, controls="parameters")
    solver = MpccSolver(disc.mpcc, relaxation=relaxation if relaxation is not None else Scholtes(),
                        nlp=nlp)
    build_time = time.perf_counter() - start

    s = disc.tableau.stages
    xs, ts, xst, tst, hs, alg = [x0[None, :]], [np.zeros(1)], [], [], [], []
    results: list[MpccResult] = []
    retries: list[tuple[int, MpccResult]] = []
    fallback: MpccSolver | None = None
    w = disc.initial_guess(x0)
    x = x0
    t0 = 0.0
    status = SimulationStatus.SUCCESS
    solve_start = time.perf_counter()
    for k in range(n_steps):
        p = disc.parameters(x, controls[k])
        if k > 0:
            # warm start: the previous step's solution, states shifted to start at x_k
            shift = x - w[disc.layout.x[0]]
            w = w.copy()
            w[disc.layout.x] += shift
            w[disc.layout.x_stages] += shift
        w[disc.layout.x[0]] = x
        result = solver.solve(p, w, homotopy=homotopy, verbose=verbose)
        if not result.success and retry:
            # Retry from x_k everywhere (algebraic variables consistent with x_k) with the
            # Scholtes relaxation: penalty relaxations can stop at a spurious stationary point
            # of the penalty when a switch needs the mode to change inside the step.
            first = result
            if fallback is None:
                fallback = (solver if isinstance(solver.relaxation, Scholtes)
                            else MpccSolver(disc.mpcc, relaxation=Scholtes(), nlp=nlp))
            result = fallback.solve(p, disc.initial_guess(x), homotopy=gentler,
                                    verbose=verbose)
            retries.append((k, first))
        results.append(result)
        if verbose:
            print(f"step {k + 1}/{n_steps}: {result.message}", flush=True)
        if not result.success:
            status = SimulationStatus.STEP_FAILED
            break
        w = result.w
        x = disc.states(w)[-1]
        xs.append(disc.states(w)[1:])
        ts.append(t0 + disc.times(w)[1:])
        xst.append(disc.stage_states(w))
        tst.append(t0 + disc.stage_times(w))
        hs.append(disc.steps(w))
        alg.append(disc.algebraic(w))
        t0 = float(ts[-1][-1])
    solve_time = time.perf_counter() - solve_start
    n_done = len(hs)
    algebraic = {name: np.concatenate([a[name] for a in alg]) if alg else np.zeros((0,))
                 for name in (alg[0] if alg else {})}
    t = np.concatenate(ts)
    theta = _theta(disc, algebraic) if alg else np.zeros((0, s, disc.form.m))
    message = status.value
    if status is SimulationStatus.STEP_FAILED:
        message = f"step {n_done + 1} of {n_steps} failed: {results[-1].message}"
    out = SimulationResult(
        status=status, message=message, t=t, x=np.concatenate(xs),
        t_stages=np.concatenate(tst) if tst else np.zeros((0, s)),
        x_stages=np.concatenate(xst) if xst else np.zeros((0, s, system.n_x)),
        algebraic=algebraic, u=controls[:n_done], h=np.concatenate(hs) if hs else np.zeros(0),
        switch_times=switch_times(t, theta.max(axis=1) > 1e-5, grid.h0),
        n_nlps=sum(r.n_nlps for r in results) + sum(r.n_nlps for _, r in retries),
        total_iterations=(sum(r.total_iterations for r in results)
                          + sum(r.total_iterations for _, r in retries)),
        residual=max((r.residual for r in results), default=0.0),
        build_time=build_time, solve_time=solve_time, step_results=tuple(results),
        discretization=disc, n_retries=len(retries),
    )
    if throw and not out.success:
        raise SolveFailed(message, out)
    return out


def _theta(disc: Discretization, algebraic: dict[str, np.ndarray]) -> np.ndarray:
    if isinstance(disc.system, StewartSystem):
        return algebraic["theta"]
    return np.concatenate([algebraic["alpha"], 1 - algebraic["alpha"]], axis=2)
