"""FESD and standard discretisations of a piecewise smooth system into an MPCC.

The horizon [0, T] is split into N control intervals (controls piecewise constant)
of N_FE finite elements each. On element e with step h_e and start state x_e, an
s-stage collocation method (A, b, c) gives the stage states X_{e,j} and

    X_{e,j} = x_e + h_e sum_k A_jk f(X_{e,k}, u, z_{e,k}),      j = 1..s,
    x_{e+1} = x_e + h_e sum_j b_j f(X_{e,j}, u, z_{e,j})   (= X_{e,s} for Radau IIA),

with the algebraic variables z_{e,j} of the form (forms.py) at every stage point.
With Theta, Lambda >= 0 the complementarity vectors of the form (DESIGN.md 4.6):

* `Standard()`: h_e = T / (N N_FE) fixed; Theta_{e,j} perp Lambda_{e,j} stage by stage.
* `Fesd()` (Nurkanovic, Sperl, Albrecht, Diehl, Numer. Math. 2024, eqs. (20)-(25)):
  - h_e are variables, sum over an interval = T / N, h_e in [(1 - gamma_h) h0, (1 + gamma_h) h0];
  - cross complementarity: Theta_{e,j} perp sum_{k=0}^{s} Lambda_{e,k} (stage mode,
    s m pairs per element) or sum_j Theta_{e,j} perp sum_k Lambda_{e,k} (element mode,
    m pairs), where Lambda_{e,0} = Lambda at the end of element e - 1 (the initial state's
    Lambda for e = 0; continuity of lambda across element and interval boundaries) and,
    when the method's last stage is not the end point (Gauss-Legendre), the sum also holds
    Lambda at the end point, an extra boundary point with its own algebraic equations;
    since every term is nonnegative this makes all cross products vanish, so the active
    set cannot change inside an element and switches land on element boundaries;
  - step equilibration, one of `HeuristicMean` (nosnoc's default, a penalty
    rho sum (h_e - h0)^2 in the objective), `Direct` (the paper's eq. (25):
    eta_e (h_e - h_{e+1}) = 0 with eta_e = prod_r (pi^lambda_r + pi^theta_r), which
    vanishes only if a switch happens at the boundary) or `NoEquilibration`.

The result is an `Mpcc` whose parameters p are the initial state x0 (and the controls,
with `controls="parameters"`, as a simulator needs); the objective holds only the step
equilibration penalty. The collocation equations of one element are one CasADi SX
Function, mapped over all elements, so building scales to long horizons.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Literal

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.fesd.forms import Form, form_of
from tfcontact.fesd.system import HeavisideSystem, StewartSystem
from tfcontact.fesd.tableau import RadauIIA, Scheme, Tableau, as_tableau
from tfcontact.mpcc.problem import Mpcc, RepeatedBlock


@dataclass(frozen=True)
class FesdGrid:
    """The time grid: N control intervals of N_FE finite elements on [0, T].

    Args:
        n_intervals: N, control intervals (controls are constant on each).
        n_finite_elements: N_FE, finite elements per control interval.
        horizon: T [s] (numerical time for time-freezing systems).
    """

    n_intervals: int
    n_finite_elements: int
    horizon: float

    def __post_init__(self) -> None:
        positive_int(self.n_intervals, "n_intervals")
        positive_int(self.n_finite_elements, "n_finite_elements")
        if not (np.isfinite(self.horizon) and self.horizon > 0):
            raise InvalidInput(f"`horizon` must be a positive number [s], got {self.horizon!r}")

    @property
    def n_elements(self) -> int:
        """N N_FE, the number of finite elements."""
        return self.n_intervals * self.n_finite_elements

    @property
    def interval_length(self) -> float:
        """T / N [s]."""
        return self.horizon / self.n_intervals

    @property
    def h0(self) -> float:
        """The nominal step T / (N N_FE) [s]."""
        return self.horizon / self.n_elements


class StepEquilibration(ABC):
    """How FESD removes the spurious freedom of step sizes where no switch happens."""

    @abstractmethod
    def terms(self, ctx: _EquilibrationContext) -> tuple[ca.SX, ca.SX]:
        """(objective term, equality constraints = 0)."""


@dataclass(frozen=True)
class _EquilibrationContext:
    h: ca.SX  # (n_elements, 1) step sizes
    h0: float
    n_intervals: int
    n_fe: int
    theta_sum: ca.SX  # (m, n_elements): sum_j Theta_{e,j}
    lambda_cross: ca.SX  # (m, n_elements): sum_{k=0}^{s} Lambda_{e,k}


@dataclass(frozen=True)
class HeuristicMean(StepEquilibration):
    """Penalty rho sum_e (h_e - h0)^2 in the objective (nosnoc's `heuristic_mean`).

    Simple and well conditioned; at a switch, cross complementarity fixes the boundary and
    the penalty spreads the remaining steps evenly. It changes an OCP's objective by
    rho sum (h_e - h0)^2 [s^2].

    Args:
        rho: penalty weight [cost]/[s^2], positive.
    """

    rho: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.rho) and self.rho > 0):
            raise InvalidInput(f"`rho` must be a positive number, got {self.rho!r}")

    def terms(self, ctx):
        return self.rho * ca.sumsqr(ctx.h - ctx.h0), ca.SX(0, 1)


@dataclass(frozen=True)
class Direct(StepEquilibration):
    """The FESD paper's exact step equilibration, eq. (25): eta_e (h_e - h_{e+1}) = 0.

    With sigma^lambda_B = sum_k Lambda_{e,k}, sigma^lambda_F = sum_k Lambda_{e+1,k},
    sigma^theta_B = sum_j Theta_{e,j}, sigma^theta_F = sum_j Theta_{e+1,j},
    pi^lambda = sigma^lambda_B * sigma^lambda_F, pi^theta = sigma^theta_B * sigma^theta_F
    (componentwise) and eta_e = prod_r (pi^lambda_r + pi^theta_r): eta_e = 0 exactly when
    some component switches at the boundary between elements e and e + 1 of one interval.
    Exact but badly scaled (a product of m factors).
    """

    def terms(self, ctx):
        cons = []
        for n in range(ctx.n_intervals):
            for i in range(ctx.n_fe - 1):
                e = n * ctx.n_fe + i
                upsilon = (ctx.lambda_cross[:, e] * ctx.lambda_cross[:, e + 1]
                           + ctx.theta_sum[:, e] * ctx.theta_sum[:, e + 1])
                eta = upsilon[0]
                for r in range(1, upsilon.numel()):
                    eta = eta * upsilon[r]
                cons.append(eta * (ctx.h[e] - ctx.h[e + 1]))
        return ca.SX(0), ca.vertcat(*cons) if cons else ca.SX(0, 1)


@dataclass(frozen=True)
class NoEquilibration(StepEquilibration):
    """No step equilibration: the steps away from switches are not unique."""

    def terms(self, ctx):
        return ca.SX(0), ca.SX(0, 1)


@dataclass(frozen=True)
class Fesd:
    """Finite elements with switch detection (Nurkanovic et al., Numer. Math. 2024).

    Args:
        gamma_h: steps may vary in [(1 - gamma_h) h0, (1 + gamma_h) h0], gamma_h in (0, 1].
        step_equilibration: `HeuristicMean()` (default), `Direct()` or `NoEquilibration()`.
        cross_complementarity: "stage" (Theta of each stage against the element's summed
            Lambda: s m pairs per element, nosnoc's default) or "element" (summed Theta
            against summed Lambda: m pairs per element).
    """

    gamma_h: float = 1.0
    step_equilibration: StepEquilibration = field(default_factory=HeuristicMean)
    cross_complementarity: Literal["stage", "element"] = "stage"

    def __post_init__(self) -> None:
        if not (0 < self.gamma_h <= 1):
            raise InvalidInput(f"`gamma_h` must lie in (0, 1], got {self.gamma_h!r}")
        if not isinstance(self.step_equilibration, StepEquilibration):
            raise InvalidInput(
                "`step_equilibration` must be HeuristicMean(), Direct() or NoEquilibration(), "
                f"got {self.step_equilibration!r}"
            )
        if self.cross_complementarity not in ("stage", "element"):
            raise InvalidInput(
                "`cross_complementarity` must be 'stage' or 'element', "
                f"got {self.cross_complementarity!r}"
            )


@dataclass(frozen=True)
class Standard:
    """The standard discretisation: fixed equal steps, stage-wise complementarity only.

    Only first-order accurate across switches; the baseline FESD is compared against.
    """


Method = Fesd | Standard

DEFAULT_SCHEME = RadauIIA(2)
"""Radau IIA with 2 stages (order 3), nosnoc's default."""
DEFAULT_METHOD = Fesd()
"""FESD with gamma_h = 1, heuristic-mean step equilibration, stage cross complementarity."""


@dataclass(frozen=True, eq=False)
class Layout:
    """Where each quantity sits: index arrays into w (or p where said).

    Shapes use E = N N_FE elements, s stages.

    Attributes:
        x: (E + 1, n_x) states at element boundaries, x[0] the initial state.
        x_stages: (E, s, n_x) stage states.
        u: (N, n_u) controls, indices into w, or into p when `controls_in_p`.
        controls_in_p: whether the controls are parameters.
        h: (E,) step sizes (FESD) or None (Standard: all h0).
        z: per stage block name, (E, s, size).
        zb: per boundary block name, (E, size) (FESD with a non-stiffly accurate scheme).
        p_x0: (n_x,) indices of x0 in p.
    """

    x: np.ndarray
    x_stages: np.ndarray
    u: np.ndarray
    controls_in_p: bool
    h: np.ndarray | None
    z: dict[str, np.ndarray]
    zb: dict[str, np.ndarray]
    p_x0: np.ndarray


@dataclass(frozen=True, eq=False)
class Discretization:
    """A discretised piecewise smooth system: the MPCC and where everything is in it.

    Attributes:
        mpcc: the MPCC (objective: step equilibration only; p = (x0[, controls])).
        layout: index maps.
        system, grid, tableau, method: what was discretised and how.
        form: the system's form (forms.py).
        theta_stages, lambda_stages: SX (m s, E) Theta and Lambda at the stage points.
        lambda_end: SX (m, E) Lambda at each element's end point.
        build_time: seconds spent building [s].
    """

    mpcc: Mpcc
    layout: Layout
    system: StewartSystem | HeavisideSystem
    grid: FesdGrid
    tableau: Tableau
    method: Method
    form: Form
    theta_stages: ca.SX
    lambda_stages: ca.SX
    lambda_end: ca.SX
    build_time: float

    @property
    def n_x(self) -> int:
        return self.system.n_x

    @property
    def n_u(self) -> int:
        return self.system.n_u

    def steps(self, w: np.ndarray) -> np.ndarray:
        """The step sizes h_e [s], shape (E,)."""
        if self.layout.h is None:
            return np.full(self.grid.n_elements, self.grid.h0)
        return np.asarray(w)[self.layout.h]

    def times(self, w: np.ndarray) -> np.ndarray:
        """Times of the element boundaries [s], shape (E + 1,)."""
        return np.concatenate([[0.0], np.cumsum(self.steps(w))])

    def stage_times(self, w: np.ndarray) -> np.ndarray:
        """Times of the stage points [s], shape (E, s)."""
        h = self.steps(w)
        return self.times(w)[:-1, None] + h[:, None] * self.tableau.c[None, :]

    def states(self, w: np.ndarray) -> np.ndarray:
        """States at the element boundaries, shape (E + 1, n_x)."""
        return np.asarray(w)[self.layout.x]

    def stage_states(self, w: np.ndarray) -> np.ndarray:
        """Stage states, shape (E, s, n_x)."""
        return np.asarray(w)[self.layout.x_stages]

    def algebraic(self, w: np.ndarray) -> dict[str, np.ndarray]:
        """Algebraic variables by block name: stage blocks (E, s, size), boundary (E, size)."""
        w = np.asarray(w)
        out = {name: w[idx] for name, idx in self.layout.z.items()}
        out.update({name: w[idx] for name, idx in self.layout.zb.items()})
        return out

    def theta_values(self, w: np.ndarray) -> np.ndarray:
        """Theta at the stage points, shape (E, s, m) (Heaviside: (alpha, 1 - alpha))."""
        return self.system.theta(self.algebraic(w))

    def active_sets(self, w: np.ndarray, threshold: float = 1e-5) -> np.ndarray:
        """Boolean (E, m): component r of Theta is active (> threshold) somewhere in element e."""
        return self.theta_values(w).max(axis=1) > threshold

    def switch_times(self, w: np.ndarray, threshold: float = 1e-5) -> np.ndarray:
        """Times of element boundaries where the active set changes [s]."""
        return switch_times(self.times(w), self.active_sets(w, threshold), self.grid.h0)

    def initial_guess(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """w0 with every state x0, algebraic variables consistent with x0, steps h0.

        Args:
            x0: state, shape (n_x,).
            u: controls, shape (N, n_u) or (n_u,) (when controls are parameters only the
                auxiliary variables' guess uses them, the first interval's).
        """
        w0 = self.mpcc.w0.copy()
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        w0[self.layout.x] = x0
        w0[self.layout.x_stages] = x0
        first_u = None
        if u is not None and self.n_u:
            first_u = np.asarray(u, dtype=float).reshape(-1, self.n_u)[0]
        z = self.form.guess(x0, first_u)
        k = 0
        for b in self.form.stage_blocks:
            w0[self.layout.z[b.name]] = z[k:k + b.size]
            k += b.size
        if self.layout.zb:
            # boundary guesses: the last stage's values of the block of the same name
            for b in self.form.boundary_blocks:
                stage_name = b.name.removesuffix("_end")
                w0[self.layout.zb[b.name]] = w0[self.layout.z[stage_name]][:, -1, :]
        if u is not None and not self.layout.controls_in_p and self.n_u:
            w0[self.layout.u] = np.broadcast_to(np.asarray(u, dtype=float), self.layout.u.shape)
        return w0

    def parameters(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """The parameter vector p for a given x0 (and controls, if they are parameters)."""
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        if x0.size != self.n_x:
            raise InvalidInput(f"`x0` has {x0.size} entries, expected n_x = {self.n_x}")
        if not self.layout.controls_in_p:
            return x0
        n_u, n = self.n_u, self.grid.n_intervals
        if n_u == 0:
            return x0
        if u is None:
            raise InvalidInput(f"the system has {n_u} controls: pass `u`")
        u = np.asarray(u, dtype=float)
        try:
            u = np.broadcast_to(u.reshape(-1) if u.size == n_u else u, (n, n_u))
        except ValueError:
            raise InvalidInput(
                f"`u` must have shape ({n_u},) or ({n}, {n_u}), got {u.shape}"
            ) from None
        return np.concatenate([x0, u.reshape(-1)])


def switch_times(t: np.ndarray, active: np.ndarray, h0: float) -> np.ndarray:
    """Times where the active set changes between consecutive elements [s].

    Args:
        t: (E + 1,) element boundary times; active: (E, m) active components per element;
        h0: nominal step, elements shorter than 1e-9 h0 (collapsed, gamma_h = 1) are skipped.
    """
    keep = np.flatnonzero(np.diff(t) > 1e-9 * h0)
    if keep.size < 2:
        return np.zeros(0)
    changed = np.any(active[keep[1:]] != active[keep[:-1]], axis=1)
    return t[keep[1:]][changed]


def discretize(
    system: StewartSystem | HeavisideSystem,
    *,
    grid: FesdGrid,
    scheme: Scheme | Tableau = DEFAULT_SCHEME,
    method: Method = DEFAULT_METHOD,
    controls: Literal["variables", "parameters"] = "variables",
) -> Discretization:
    """Discretise a piecewise smooth system on a grid into an MPCC.

    Main args:
        system: a `StewartSystem` or `HeavisideSystem`.
        grid: `FesdGrid(n_intervals, n_finite_elements, horizon)`.

    Other args:
        scheme: `RadauIIA(stages)` (default s = 2), `GaussLegendre(stages)` or a `Tableau`.
        method: `Fesd(...)` (default) or `Standard()`.
        controls: "variables" (an OCP optimises them, block "u") or "parameters"
            (a simulator fixes them: p = (x0, u_0, ..., u_{N-1})).

    Returns:
        The `Discretization` (its `mpcc` has p = x0 first; states, stage states and
        algebraic variables as named blocks).

    Raises:
        InvalidInput: unknown system, scheme, method or controls mode.
    """
    start = time.perf_counter()
    form = form_of(system)
    tab = as_tableau(scheme)
    if not isinstance(grid, FesdGrid):
        raise InvalidInput(f"`grid` must be a FesdGrid(...), got {type(grid).__name__}")
    if not isinstance(method, Fesd | Standard):
        raise InvalidInput(f"`method` must be Fesd(...) or Standard(), got {method!r}")
    if controls not in ("variables", "parameters"):
        raise InvalidInput(
            f"`controls` must be 'variables' or 'parameters', got {controls!r}"
        )
    fesd = isinstance(method, Fesd)
    n_x, n_u, s = system.n_x, system.n_u, tab.stages
    N, n_fe, E = grid.n_intervals, grid.n_finite_elements, grid.n_elements
    stiff = tab.stiffly_accurate
    boundary = fesd and not stiff
    n_z, n_zb = form.n_z, (form.n_zb if boundary else 0)
    controls_in_p = controls == "parameters"

    # ---- variable layout, in time order (x0, then per interval: u, per element: h, X, Z, ...)
    counter = 0

    def take(n: int) -> np.ndarray:
        nonlocal counter
        idx = np.arange(counter, counter + n)
        counter += n
        return idx

    x_first = take(n_x)
    u_idx = np.zeros((N, n_u), dtype=int)
    h_idx = np.zeros(E, dtype=int)
    X_idx = np.zeros((E, s, n_x), dtype=int)
    Z_idx = np.zeros((E, s, n_z), dtype=int)
    xe_idx = np.zeros((E, n_x), dtype=int)
    zb_idx = np.zeros((E, n_zb), dtype=int)
    p_x0 = np.arange(n_x)
    for n in range(N):
        if controls_in_p:
            u_idx[n] = n_x + n * n_u + np.arange(n_u)
        else:
            u_idx[n] = take(n_u)
        for i in range(n_fe):
            e = n * n_fe + i
            if fesd:
                h_idx[e] = take(1)[0]
            X_idx[e] = take(s * n_x).reshape(s, n_x)
            Z_idx[e] = take(s * n_z).reshape(s, n_z)
            xe_idx[e] = X_idx[e, -1] if stiff else take(n_x)
            zb_idx[e] = take(n_zb)
    n_w = counter
    w = ca.SX.sym("w", n_w)
    n_p = n_x + (N * n_u if controls_in_p else 0)
    p = ca.SX.sym("p", n_p)

    def gather(vec: ca.SX, idx: np.ndarray) -> ca.SX:
        """SX matrix (idx.shape[-1] x rows) with column e = vec[idx[e]]."""
        idx = idx.reshape(idx.shape[0], -1)
        if idx.shape[1] == 0:
            return ca.SX(0, idx.shape[0])
        return ca.reshape(vec[idx.reshape(-1).tolist()], idx.shape[1], idx.shape[0])

    # ---- one element as an SX Function, mapped over all elements
    xs = ca.SX.sym("xs", n_x)
    Xv = ca.SX.sym("X", n_x * s)
    Zv = ca.SX.sym("Z", n_z * s)
    Xs = ca.reshape(Xv, n_x, s)
    Zs = ca.reshape(Zv, n_z, s)
    hs = ca.SX.sym("h")
    us = ca.SX.sym("u", n_u)
    xes = ca.SX.sym("xe", n_x)
    zbs = ca.SX.sym("zb", n_zb)
    fs = [form.rhs(Xs[:, j], us, Zs[:, j]) for j in range(s)]
    res = []
    for j in range(s):
        res.append(Xs[:, j] - xs - hs * sum(tab.A[j, k] * fs[k] for k in range(s)))
    for j in range(s):
        res.append(form.algebraic(Xs[:, j], us, Zs[:, j]))
    if not stiff:
        res.append(xes - xs - hs * sum(tab.b[j] * fs[j] for j in range(s)))
    if boundary:
        res.append(form.boundary_algebraic(xes, zbs))
    theta_s = ca.vertcat(*[form.theta(Zs[:, j]) for j in range(s)])
    lambda_s = ca.vertcat(*[form.lam(Zs[:, j]) for j in range(s)])
    lambda_e = form.boundary_lam(zbs) if boundary else form.lam(Zs[:, s - 1])
    element = ca.Function(
        "fesd_element", [xs, Xv, Zv, hs, us, xes, zbs],
        [ca.vertcat(*res), theta_s, lambda_s, lambda_e],
    )
    x_start_idx = np.vstack([x_first[None, :], xe_idx[:-1]])
    u_elem = np.repeat(u_idx, n_fe, axis=0)
    U = gather(p if controls_in_p else w, u_elem)
    H = gather(w, h_idx[:, None]) if fesd else ca.SX(ca.DM.ones(1, E) * grid.h0)
    mapped = element.map(E)
    arguments = (gather(w, x_start_idx), gather(w, X_idx), gather(w, Z_idx), H, U,
                 gather(w, xe_idx), gather(w, zb_idx))
    residual, theta_st, lambda_st, lambda_end = mapped(*arguments)
    g_parts = [w[x_first.tolist()] - p[p_x0.tolist()], ca.vec(residual)]
    # The collocation residuals (g's bulk) as one repeated function, differentiated once
    n_res = residual.shape[0]
    repeated = RepeatedBlock(
        function=ca.Function("fesd_residual", [xs, Xv, Zv, hs, us, xes, zbs],
                             [ca.vertcat(*res)]),
        arguments=arguments,
        rows=n_x + np.arange(E * n_res).reshape(E, n_res),
    )
    m = form.m

    # ---- complementarity
    f_obj = ca.SX(0)
    if fesd:
        lambda_start = ca.horzcat(form.initial_lam(p[p_x0.tolist()]), lambda_end[:, :-1])
        lambda_cross = lambda_start + lambda_end if boundary else lambda_start
        for j in range(s):
            lambda_cross = lambda_cross + lambda_st[j * m:(j + 1) * m, :]
        theta_sum = theta_st[0:m, :]
        for j in range(1, s):
            theta_sum = theta_sum + theta_st[j * m:(j + 1) * m, :]
        if method.cross_complementarity == "stage":
            G = ca.vertcat(*[ca.vec(theta_st[j * m:(j + 1) * m, :]) for j in range(s)])
            Hc = ca.vertcat(*[ca.vec(lambda_cross) for _ in range(s)])
        else:
            G, Hc = ca.vec(theta_sum), ca.vec(lambda_cross)
        h_all = w[h_idx.tolist()]
        for n in range(N):
            g_parts.append(ca.sum1(h_all[n * n_fe:(n + 1) * n_fe]) - grid.interval_length)
        ctx = _EquilibrationContext(h_all, grid.h0, N, n_fe, theta_sum, lambda_cross)
        f_eq, g_eq = method.step_equilibration.terms(ctx)
        f_obj = f_obj + f_eq
        g_parts.append(g_eq)
    else:
        G, Hc = ca.vec(theta_st), ca.vec(lambda_st)
    g = ca.vertcat(*g_parts)

    # ---- bounds and initial guess
    lbw = np.full(n_w, -np.inf)
    ubw = np.full(n_w, np.inf)
    w0 = np.zeros(n_w)
    z_blocks: dict[str, np.ndarray] = {}
    k = 0
    for b in form.stage_blocks:
        idx = Z_idx[:, :, k:k + b.size]
        z_blocks[b.name] = idx
        lbw[idx], ubw[idx] = b.lower, b.upper
        k += b.size
    zb_blocks: dict[str, np.ndarray] = {}
    if boundary:
        k = 0
        for b in form.boundary_blocks:
            idx = zb_idx[:, k:k + b.size]
            zb_blocks[b.name] = idx
            lbw[idx], ubw[idx] = b.lower, b.upper
            k += b.size
    if fesd:
        lbw[h_idx] = (1 - method.gamma_h) * grid.h0
        ubw[h_idx] = (1 + method.gamma_h) * grid.h0
        w0[h_idx] = grid.h0
    x_idx = np.vstack([x_first[None, :], xe_idx])
    blocks = {"x": x_idx.reshape(-1), "x_stages": X_idx.reshape(-1)}
    if not controls_in_p:
        blocks["u"] = u_idx.reshape(-1)
    if fesd:
        blocks["h"] = h_idx
    blocks.update({name: idx.reshape(-1) for name, idx in z_blocks.items()})
    blocks.update({name: idx.reshape(-1) for name, idx in zb_blocks.items()})
    n_g = g.numel()
    mpcc = Mpcc(w=w, f=f_obj, g=g, lbg=np.zeros(n_g), ubg=np.zeros(n_g), lbw=lbw, ubw=ubw,
                w0=w0, G=G, H=Hc, p=p, blocks=blocks, repeated=(repeated,))
    layout = Layout(x=x_idx, x_stages=X_idx, u=u_idx, controls_in_p=controls_in_p,
                    h=h_idx if fesd else None, z=z_blocks, zb=zb_blocks, p_x0=p_x0)
    return Discretization(
        mpcc=mpcc, layout=layout, system=system, grid=grid, tableau=tab, method=method,
        form=form, theta_stages=theta_st, lambda_stages=lambda_st, lambda_end=lambda_end,
        build_time=time.perf_counter() - start,
    )
