"""Simulation of a piecewise smooth system with FESD, one MPCC per integration step.

Every step [tau_k, tau_k + H] is one control interval of N_FE finite elements. Its MPCC is
built once per step length with the step's initial state and control as parameters, its
relaxed NLP is built once (`MpccSolver`), and every step is a homotopy warm started from
the previous step's solution (states shifted to the step's initial state). A step whose
homotopy fails from there is retried once from the initial state with consistent
algebraic variables and the Scholtes relaxation. With FESD the switches land on element
boundaries, so the simulator reports them exactly (Nurkanovic et al., Numer. Math. 2024,
section 4).

What `simulate` adapts (`Adaptivity`, every change recorded as an `Adaptation`):

* A step that still fails is cut in halves, recursively: N_FE elements hold at most N_FE - 1
  switches inside a step, and an impact with friction brings several close together
  (impact, stick, exit of the frozen piece).
* Given a time-freezing system itself (not its `.pss`), the auxiliary gain a_n of inelastic
  impacts ([AUTO23] Prop. 3) is lowered before an impact so that the frozen piece lasts
  about `Adaptivity.frozen_steps` steps: it lasts tau_f = |v_n| / (D a_n) in numerical time
  (D = n^T M^-1 n, the Delassus scalar; v_n the normal velocity at the impact). Measured on
  the particle dropped 1 m with friction at steps of 0.1 s: with a_n = 100 (tau_f = 0.44
  steps) the impact and the exit from the frozen piece share a step, the relaxed solution
  leaves the state 2e-7 m/s inside the auxiliary region, and the next step's NLP is
  infeasible at sigma = 1e-9. The physical solution does not depend on a_n: multiplying
  every auxiliary field by the same factor only re-parametrises the frozen pieces and the
  persistent-contact sliding mode in numerical time, so the gain may change between steps.
  The gain is never lowered below the value at which persistent contact runs the clock at
  `min_clock_rate` (gamma = D a_n / (D a_n - phi), [AUTO23] Theorem 4).
* With a physical horizon (`Physical(T)`) the simulation runs until the clock reaches T,
  and its last step is shortened so that it ends there.

[AUTO23]: Nurkanovic, Albrecht, Brogliato, Diehl, Automatica 158 (2023) 111295.
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal, Protocol, runtime_checkable

import casadi as ca
import numpy as np

from tfcontact.errors import IncompatibleOptions, InvalidInput, SolveFailed, positive_int
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
from tfcontact.fesd.tableau import Scheme, Tableau, lagrange_weights
from tfcontact.mpcc import Homotopy, Ipopt, MpccResult, MpccSolver, Relaxation, Scholtes

FROZEN_RATE_TOL = 1e-3
"""Clock rate dt/dtau [-] at or below which a sampling interval counts as frozen.

Not 0: a relaxed complementarity (residual sigma) lets the step variable of the gap stay
at about sigma / |f_c| while the state sits on f_c = 0 during the auxiliary phase, so the
clock creeps at a rate of that order (measured: 1e-5 with sigma = 1e-9). A persistent
contact runs at gamma = D a_n / (D a_n - phi), far above it for any sensible a_n.
nosnoc uses the same number (`time_freezing_tolerance` = 1e-3)."""


class SimulationStatus(enum.Enum):
    """How a simulation ended."""

    SUCCESS = "success: every step's homotopy converged"
    STEP_FAILED = (
        "a step failed: its homotopy did not converge even on the cut steps (see `message` "
        "for values to try: a smaller auxiliary gain a_n, smaller steps, more finite "
        "elements, a larger Homotopy.max_nlps or another relaxation)"
    )
    BUDGET_EXCEEDED = (
        "the clock did not reach the physical horizon within the step budget "
        "(`Physical.budget` n_steps steps): the clock stalls, e.g. a tiny a_n keeps it "
        "frozen or persistent contact runs it at a tiny rate gamma"
    )


@dataclass(frozen=True)
class Physical:
    """A horizon in physical time: simulate until the clock state t reaches `time`.

    Only for time-freezing systems (the clock is their state t). The numerical step is
    H = time / n_steps; frozen pieces (impacts) and persistent contact (clock rate
    gamma < 1) take extra steps, and the last step is shortened so that the clock ends at
    `time` (within `tol`).

    Args:
        time: T [s], > 0.
        tol: the clock at the end may miss T by this much [s], > 0.
        budget: at most budget * n_steps steps [-], >= 1.
    """

    time: float
    tol: float = 1e-9
    budget: float = 20.0

    def __post_init__(self) -> None:
        for name in ("time", "tol", "budget"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating) \
                    or not math.isfinite(value):
                raise InvalidInput(f"`Physical.{name}` must be a finite number, got {value!r}")
        if self.time <= 0:
            raise InvalidInput(f"`Physical.time` must be > 0 [s], got {self.time!r}")
        if self.tol <= 0:
            raise InvalidInput(f"`Physical.tol` must be > 0 [s], got {self.tol!r}")
        if self.budget < 1:
            raise InvalidInput(f"`Physical.budget` must be >= 1, got {self.budget!r}")


@dataclass(frozen=True)
class Adaptivity:
    """What `simulate` may change to get through a step (module docstring).

    Args:
        max_cuts: a step whose homotopy fails (after the retry) is cut in halves,
            recursively, at most this deep: the shortest piece is H / 2^max_cuts. 0: never.
        gain: lower the auxiliary gain a_n of an inelastic time-freezing system before
            impacts (needs the time-freezing system, not its `.pss`).
        frozen_steps: the frozen piece of an impact should last about this many steps
            [-] (> 0): a_n = |v_n| / (D frozen_steps H), with |v_n| the normal speed the
            contact will hit with, estimated at each step's start from its normal velocity,
            gap and free normal acceleration phi (free fall: v_n^2 + 2 |phi| gap).
        min_clock_rate: a_n is never lowered below -phi/D gamma_min/(1 - gamma_min), where
            persistent contact runs the clock at gamma_min = min_clock_rate, in (0, 1).
        min_gain_factor: nor below this fraction of the system's own a_n, in (0, 1].
    """

    max_cuts: int = 3
    gain: bool = True
    frozen_steps: float = 2.0
    min_clock_rate: float = 0.5
    min_gain_factor: float = 0.01

    def __post_init__(self) -> None:
        if isinstance(self.max_cuts, bool) or not isinstance(self.max_cuts, int | np.integer) \
                or self.max_cuts < 0:
            raise InvalidInput(f"`max_cuts` must be a non-negative integer, got {self.max_cuts!r}")
        if not isinstance(self.gain, bool):
            raise InvalidInput(f"`gain` must be True or False, got {self.gain!r}")
        if not (math.isfinite(self.frozen_steps) and self.frozen_steps > 0):
            raise InvalidInput(f"`frozen_steps` must be a number > 0, got {self.frozen_steps!r}")
        if not 0 < self.min_clock_rate < 1:
            raise InvalidInput(
                f"`min_clock_rate` must lie in (0, 1), got {self.min_clock_rate!r}")
        if not 0 < self.min_gain_factor <= 1:
            raise InvalidInput(
                f"`min_gain_factor` must lie in (0, 1], got {self.min_gain_factor!r}")


NO_ADAPTATION = Adaptivity(max_cuts=0, gain=False)
"""The fixed-step simulator with the system's own gains (the behaviour before adaptation)."""


@dataclass(frozen=True)
class Adaptation:
    """One change `simulate` made on its own.

    Attributes:
        kind: "gain" (a_n of every contact scaled, `quantity` "a_n"), "cut" (a failed
            step cut in halves, `quantity` "step") or "last_step" (the last step
            shortened to end at the physical horizon, `quantity` "step").
        step: the control step (0-based) it applies from.
        tau: numerical time where it applies [s].
        time: physical time (clock) there [s]; None without a clock.
        before, after: the value before and after: the largest a_n over the contacts
            [m/s^2 per unit normal] (all scale by after / before), or a step length [s].
        reason: why, with the figures that decided it.
    """

    kind: Literal["gain", "cut", "last_step"]
    step: int
    tau: float
    time: float | None
    before: float
    after: float
    reason: str

    @property
    def quantity(self) -> str:
        return "a_n" if self.kind == "gain" else "step"

    def __str__(self) -> str:
        where = f"tau = {self.tau:.6g} s" + (
            "" if self.time is None else f", t = {self.time:.6g} s")
        return (f"adaptation ({self.kind}) at step {self.step + 1} ({where}): "
                f"{self.quantity} {self.before:.4g} -> {self.after:.4g}: {self.reason}")


@runtime_checkable
class ClockedSystem(Protocol):
    """What `simulate` reads from a time-freezing system (tfcontact.timefreezing's
    `TimeFreezingSystem` has it): its piecewise smooth system and clock state, and for the
    gain adaptation its kind, modes (n_y, n_f), Heaviside weights and CLS."""

    pss: StewartSystem | HeavisideSystem
    clock_index: int
    kind: str
    modes: ca.SX
    weights: ca.SX | None
    cls: Any
    q_index: slice
    v_index: slice


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """A simulated trajectory on the element boundaries, with the work it took.

    Shapes use K = control steps done, E elements (K N_FE, more where steps were cut),
    s stages.

    Attributes:
        status, message: how it ended (`success` is True when every step converged).
        t: (E + 1,) numerical times of element boundaries [s], t[0] = 0.
        x: (E + 1, n_x) states there.
        t_stages, x_stages: (E, s) and (E, s, n_x) stage times [s] and states.
        algebraic: per block name ("theta", "lambda", "mu" or "alpha", "lambda_n",
            "lambda_p"; boundary blocks "*_end"), arrays (E, s, size) or (E, size).
        u: (K, n_u) the controls applied.
        h: (E,) element lengths [s].
        switch_times: times of element boundaries where the active set changes [s].
        n_nlps, total_iterations: NLPs solved and IPOPT iterations over all steps.
        residual: the largest complementarity residual over the steps.
        build_time: seconds to discretise and build the NLPs [s]; solve_time: all steps [s].
        step_results: the `MpccResult` of every piece solved (the retry's, if retried;
            a cut step has one per piece), the failed one last.
        discretization: the discretisation of one nominal step.
        n_retries: steps whose warm-started homotopy failed and were solved again from the
            consistent guess at x_k (their NLPs count in `n_nlps`).
        adaptations: every change `simulate` made (`Adaptation`), in order.
        clock_index: index of the clock state in x (time-freezing systems), else None.
        a_n: the auxiliary gains per contact at the end (inelastic time-freezing systems
            given as such), else ().
        n_steps: control steps reached (done, and the failed one if any).
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
    adaptations: tuple[Adaptation, ...] = ()
    clock_index: int | None = None
    a_n: tuple[float, ...] = ()
    n_steps: int = 0

    @property
    def success(self) -> bool:
        return self.status is SimulationStatus.SUCCESS

    def physical_time(self) -> np.ndarray:
        """The clock at the element boundaries [s], shape (E + 1,) (`t` without a clock)."""
        return self.t.copy() if self.clock_index is None else self.x[:, self.clock_index].copy()

    def state_at(self, t: float | np.ndarray, *, side: Literal["post", "pre"] = "post",
                 tol: float = 1e-8) -> np.ndarray:
        """The state at physical time t, from the collocation polynomials.

        Within an element the state is the method's collocation polynomial through the
        element's start and stage values (degree s), evaluated where the element's clock
        polynomial equals t. At an impact, a frozen piece (clock rate <= FROZEN_RATE_TOL;
        t within `tol` of the clock there), the state jumps: side="post" (default) returns
        the post-impact state (the frozen piece's end; the last state if the simulation
        ends inside it), side="pre" the pre-impact one (its start). Elsewhere both sides
        agree. For systems without a clock, t is the simulation time.

        Args:
            t: a physical time [s] or an array of them, in [t_0, t_end].
            side: "post" or "pre".
            tol: times within tol [s] of an impact are at the impact (the clock of a
                relaxed solution creeps by about 1e-5 times the frozen piece's duration).

        Returns:
            The state, shape (n_x,), or t.shape + (n_x,) for an array.

        Raises:
            InvalidInput: t outside the simulated range, an unknown side or a negative tol.
        """
        times = np.asarray(t, dtype=float)
        out = [self._state_at(float(v), side, tol) for v in np.atleast_1d(times).ravel()]
        return out[0] if times.ndim == 0 else np.array(out).reshape(*times.shape, -1)

    def _state_at(self, t: float, side: str, tol: float) -> np.ndarray:
        first, last, theta = self.locate(t, side=side, tol=tol)
        if theta is None:  # a frozen run: the jump
            return (self.x[last + 1] if side == "post" else self.x[first]).copy()
        weights = lagrange_weights(self._nodes(), theta)
        return weights @ self._element_values(first)

    def locate(self, t: float, *, side: Literal["post", "pre"] = "post", tol: float = 1e-8
               ) -> tuple[int, int, float | None]:
        """Where the clock reaches physical time t: (e, e, theta) for a point theta in
        [0, 1] of element e, or (first, last, None) for the frozen run of elements
        first..last (an impact at t). `state_at` explains `side` and `tol`.

        Raises:
            InvalidInput: t outside the simulated range, an unknown side or a negative tol.
        """
        if side not in ("post", "pre"):
            raise InvalidInput(f"`side` must be 'post' or 'pre', got {side!r}")
        if not (math.isfinite(tol) and tol >= 0):
            raise InvalidInput(f"`tol` must be finite and >= 0 [s], got {tol!r}")
        clock = self.physical_time()
        if clock.size < 2:
            raise InvalidInput("the simulation has no element to read (no step done)")
        low, high = float(clock[0]), float(clock[-1])
        if not (math.isfinite(t) and low - tol <= t <= high + tol):
            raise InvalidInput(
                f"`t` must lie in the simulated physical times [{low:.9g}, {high:.9g}] s, "
                f"got {t!r}")
        dt, dtau = np.diff(clock), np.diff(self.t)
        running = dt > FROZEN_RATE_TOL * dtau
        hits: list[tuple[int, int]] = []  # elements or frozen runs that hold t, in order
        e, n = 0, dt.size
        while e < n:
            if running[e]:
                if clock[e] <= t <= clock[e + 1]:
                    hits.append((e, e))
                e += 1
                continue
            start = e
            while e < n and not running[e]:
                e += 1
            if clock[start] - tol <= t <= clock[e] + tol:
                hits.append((start, e - 1))
        if not hits:  # within tol of the range's ends
            e = 0 if t <= low else n - 1
            return e, e, 0.0 if t <= low else 1.0
        first, last = hits[-1] if side == "post" else hits[0]
        if not running[first]:
            return first, last, None
        if self.clock_index is None:
            return first, first, float(np.clip((t - self.t[first]) / self.h[first], 0, 1))
        theta = _solve_clock(self._nodes(), self._element_values(first)[:, self.clock_index], t)
        return first, first, theta

    def _nodes(self) -> np.ndarray:
        return np.concatenate([[0.0], np.asarray(self.discretization.tableau.c, dtype=float)])

    def _element_values(self, e: int) -> np.ndarray:
        """(s + 1, n_x): the state at element e's start and its stages."""
        return np.vstack([self.x[e][None, :], self.x_stages[e]])


def _solve_clock(nodes: np.ndarray, clock: np.ndarray, t: float) -> float:
    """theta in [0, 1] where the clock's interpolation polynomial equals t: bisection (the
    clock is non-decreasing), finished by a secant step in the last bracket."""
    def value(theta: float) -> float:
        return float(lagrange_weights(nodes, theta) @ clock) - t

    lo, hi = 0.0, 1.0
    f_lo, f_hi = value(lo), value(hi)
    if f_lo >= 0:
        return 0.0
    if f_hi <= 0:
        return 1.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        f_mid = value(mid)
        if f_mid < 0:
            lo, f_lo = mid, f_mid
        else:
            hi, f_hi = mid, f_mid
        if hi - lo < 1e-15:
            break
    return lo - f_lo * (hi - lo) / (f_hi - f_lo) if f_hi > f_lo else lo


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


# ----------------------------------------------------------------------------- gain


def _scaled_system(tf: ClockedSystem, factor: float) -> StewartSystem | HeavisideSystem:
    """The PSS with every auxiliary (frozen: clock row 0) mode multiplied by `factor`.

    For the inelastic builder these modes are M^-1 (n a_n -+ B mu a_n): the factor
    scales every contact's a_n, exactly as a rebuild with the scaled gains would.
    A Heaviside system with auxiliary variables (the inverse-dynamics form) keeps them and
    their equations, so every step's discretisation has the same blocks, and gets the
    difference (factor - 1) sum_frozen theta_k f_k added to its rhs explicitly (with
    M^-1: only the simulator's rescaled steps pay for it).
    """
    pss = tf.pss
    if factor == 1.0:
        return pss
    names = {"state_names": pss.state_names, "control_names": pss.control_names}
    if isinstance(pss, StewartSystem):
        modes = pss.modes
        scale = [factor if modes[tf.clock_index, j].is_zero() else 1.0
                 for j in range(modes.shape[1])]
        return StewartSystem(x=pss.x, u=pss.u, modes=ca.mtimes(modes, ca.diag(ca.DM(scale))),
                             indicators=pss.indicators, switching=pss.switching, **names)
    modes = tf.modes
    scale = [factor if modes[tf.clock_index, j].is_zero() else 1.0
             for j in range(modes.shape[1])]
    if pss.n_auxiliary:
        extra = [k - 1.0 for k in scale]
        rhs = pss.rhs + ca.mtimes(ca.mtimes(modes, ca.diag(ca.DM(extra))), tf.weights)
        return HeavisideSystem(x=pss.x, u=pss.u, alpha=pss.alpha, rhs=rhs,
                               switching=pss.switching, auxiliary=pss.auxiliary,
                               auxiliary_equations=pss.auxiliary_equations, **names)
    rhs = ca.mtimes(ca.mtimes(modes, ca.diag(ca.DM(scale))), tf.weights)
    return HeavisideSystem(x=pss.x, u=pss.u, alpha=pss.alpha, rhs=rhs,
                           switching=pss.switching, **names)


class _Gain:
    """The auxiliary-gain policy of an inelastic time-freezing system (Adaptivity)."""

    def __init__(self, tf: ClockedSystem, options: Adaptivity, step: float):
        cls = tf.cls
        self.tf, self.options, self.step = tf, options, step
        self.base = np.array([c.a_n for c in cls.contacts], dtype=float)
        self.factor = 1.0
        n_c = cls.n_contacts
        gaps = ca.vertcat(*[c.gap for c in cls.contacts])
        vn = ca.vertcat(*[cls.normal_velocity(i) for i in range(n_c)])
        dl = ca.vertcat(*[cls.delassus(i) for i in range(n_c)])
        phi = ca.vertcat(*[cls.phi(i) for i in range(n_c)])
        self._terms = ca.Function("contact_scales", [cls.q, cls.v, cls.u], [gaps, vn, dl, phi])
        self._n_u = cls.n_u

    @property
    def a_n(self) -> tuple[float, ...]:
        return tuple(float(a) for a in self.base * self.factor)

    def terms(self, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, ...]:
        q, v = y[self.tf.q_index], y[self.tf.v_index]
        out = self._terms(q, v, np.asarray(u, dtype=float).reshape(-1)[: self._n_u])
        return tuple(np.asarray(o, dtype=float).reshape(-1) for o in out)

    def impact_speeds(self, y: np.ndarray, u: np.ndarray, *, first: bool
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(speed, D, phi) per contact: the normal speed [m/s] it will hit with from y
        (0 where none is expected), the Delassus scalar D(q) and phi(q, v, u).

        Only open contacts (gap > 0) count, and closed ones at the first step: a closed,
        approaching contact later on is inside a frozen piece, whose gain is settled."""
        gaps, vn, dl, phi = self.terms(y, u)
        pull = np.maximum(-phi, 0.0)
        speed = np.sqrt(np.maximum(-vn, 0.0) ** 2 + 2.0 * pull * np.maximum(gaps, 0.0))
        # A resting or sliding contact (gap ~ 0, v_n ~ 0 up to the relaxation) is no impact.
        speed[speed <= np.maximum(0.01 * pull * self.step, 1e-6)] = 0.0
        if not first:
            speed[gaps <= 0] = 0.0
        return speed, np.maximum(dl, 1e-300), phi

    def target(self, y: np.ndarray, u: np.ndarray, *, first: bool) -> tuple[float, str]:
        """The gain factor wanted at y (never above the current one) and why."""
        speed, dl, phi = self.impact_speeds(y, u, first=first)
        o = self.options
        if not np.any(speed > 0):
            return self.factor, ""
        rate = o.min_clock_rate / (1.0 - o.min_clock_rate)
        wanted = speed / (dl * o.frozen_steps * self.step)
        floor = rate * np.maximum(-phi, 0.0) / dl
        factors = np.maximum(wanted, floor) / self.base
        i = int(np.argmin(np.where(speed > 0, factors, np.inf)))
        factor = max(float(factors[i]), o.min_gain_factor)
        why = (f"contact {i} hits at |v_n| = {speed[i]:.3g} m/s with D = {dl[i]:.3g}: its "
               f"frozen piece lasts |v_n|/(D a_n) = "
               f"{speed[i] / (dl[i] * self.base[i] * self.factor) / self.step:.2f} steps at "
               f"a_n = {self.base[i] * self.factor:.4g}, "
               f"{speed[i] / (dl[i] * self.base[i] * factor) / self.step:.2f} at "
               f"a_n = {self.base[i] * factor:.4g}")
        return min(factor, self.factor), why


# ----------------------------------------------------------------------------- stepping


@dataclass(eq=False)
class _Piece:
    """One solved MPCC: control step k from numerical time tau."""

    k: int
    tau: float
    disc: Discretization
    result: MpccResult
    factor: float

    @property
    def w(self) -> np.ndarray:
        return self.result.w

    @property
    def end(self) -> np.ndarray:
        return self.disc.states(self.result.w)[-1]

    @property
    def start(self) -> np.ndarray:
        return self.disc.states(self.result.w)[0]

    @property
    def length(self) -> float:
        return self.disc.grid.horizon


@dataclass(eq=False)
class _Stepper:
    """Builds (and caches) one step's discretisation per (length, gain factor) and solves
    steps, cutting failed ones."""

    system: StewartSystem | HeavisideSystem
    tf: ClockedSystem | None
    scheme: Scheme | Tableau
    method: Method
    n_fe: int
    relaxation: Relaxation
    nlp: Ipopt | None
    homotopy: Homotopy
    retry: bool
    max_cuts: int
    verbose: bool
    cache: dict[tuple[float, float], tuple[Discretization, MpccSolver]] = field(
        default_factory=dict)
    fallbacks: dict[int, MpccSolver] = field(default_factory=dict)
    build_time: float = 0.0
    retries: list[MpccResult] = field(default_factory=list)
    failed: list[MpccResult] = field(default_factory=list)
    attempts: list[MpccResult] = field(default_factory=list)  # every homotopy run

    def built(self, length: float, factor: float) -> tuple[Discretization, MpccSolver]:
        key = (float(length), float(factor))
        if key not in self.cache:
            start = time.perf_counter()
            system = self.system if self.tf is None else _scaled_system(self.tf, factor)
            disc = discretize(system, grid=FesdGrid(1, self.n_fe, length), scheme=self.scheme,
                              method=self.method, controls="parameters")
            self.cache[key] = (disc, MpccSolver(disc.mpcc, relaxation=self.relaxation,
                                                nlp=self.nlp))
            self.build_time += time.perf_counter() - start
        return self.cache[key]

    def solve(self, x: np.ndarray, u: np.ndarray, length: float, factor: float,
              warm: _Piece | None) -> tuple[Discretization, MpccResult]:
        disc, solver = self.built(length, factor)
        p = disc.parameters(x, u[None, :])
        if warm is not None and warm.disc is disc:
            # warm start: the previous step's solution, states shifted to start at x
            w = warm.w.copy()
            shift = x - w[disc.layout.x[0]]
            w[disc.layout.x] += shift
            w[disc.layout.x_stages] += shift
        else:
            w = disc.initial_guess(x, u)
        w[disc.layout.x[0]] = x
        result = solver.solve(p, w, homotopy=self.homotopy, verbose=self.verbose)
        self.attempts.append(result)
        if not result.success and self.retry:
            # Retry from x everywhere (algebraic variables consistent with x) with the
            # Scholtes relaxation and a gentler schedule: penalty relaxations can stop at
            # a spurious stationary point when a switch needs the mode to change inside
            # the step, and an isolated IPOPT failure at one sigma (e.g.
            # Infeasible_Problem_Detected where a slip stops inside the step) is usually
            # passed by smaller decrements of sigma.
            self.retries.append(result)
            if id(solver) not in self.fallbacks:
                self.fallbacks[id(solver)] = (
                    solver if isinstance(solver.relaxation, Scholtes)
                    else MpccSolver(disc.mpcc, relaxation=Scholtes(), nlp=self.nlp))
            gentler = replace(self.homotopy, kappa=math.sqrt(self.homotopy.kappa),
                              max_nlps=None)
            result = self.fallbacks[id(solver)].solve(p, disc.initial_guess(x, u),
                                                       homotopy=gentler, verbose=self.verbose)
            self.attempts.append(result)
        return disc, result

    def span(self, k: int, tau: float, x: np.ndarray, u: np.ndarray, length: float,
             factor: float, warm: _Piece | None, depth: int, record: list[Adaptation],
             clock: float | None) -> list[_Piece] | None:
        """Solve [tau, tau + length] from x, cutting it in halves where it fails."""
        disc, result = self.solve(x, u, length, factor, warm)
        if result.success:
            return [_Piece(k, tau, disc, result, factor)]
        self.failed.append(result)
        if depth >= self.max_cuts:
            return None
        record.append(Adaptation(
            "cut", k, tau, clock, length, length / 2,
            f"the step's homotopy failed: {result.message}"))
        if self.verbose:
            print(record[-1], flush=True)
        first = self.span(k, tau, x, u, length / 2, factor, warm, depth + 1, record, clock)
        if first is None:
            return None
        end = first[-1]
        mid_clock = None if clock is None or self.tf is None else float(
            end.end[self.tf.clock_index])
        second = self.span(k, tau + length / 2, end.end, u, length / 2, factor, end,
                           depth + 1, record, mid_clock)
        return None if second is None else first + second


def simulate(
    system: StewartSystem | HeavisideSystem | ClockedSystem,
    x0: np.ndarray,
    *,
    horizon: float | Physical,
    n_steps: int,
    u: np.ndarray | float | None = None,
    scheme: Scheme | Tableau = DEFAULT_SCHEME,
    n_finite_elements: int = 2,
    method: Method = DEFAULT_METHOD,
    homotopy: Homotopy | None = None,
    relaxation: Relaxation | None = None,
    nlp: Ipopt | None = None,
    retry: bool = True,
    adapt: Adaptivity = Adaptivity(),
    verbose: bool = False,
    throw: bool = True,
) -> SimulationResult:
    """Simulate x' in F(x, u) on [0, horizon] with FESD (or the standard discretisation).

    Main args:
        system: a `StewartSystem` or `HeavisideSystem`, or a time-freezing system
            (`tfcontact.timefreezing.TimeFreezingSystem`, simulated through its `.pss`):
            given as such, `simulate` knows its clock (physical horizon, `state_at` in
            physical time) and may adapt its auxiliary gain a_n (the physical trajectory
            does not change; with a numerical horizon the clock then ends elsewhere).
        x0: initial state, shape (n_x,).
        horizon: T [s] in the system's own (for time-freezing: numerical) time, or
            `Physical(T)`: until the clock reaches T [s] (time-freezing systems only).
        n_steps: K integration steps of length H = T / K (with `Physical(T)`: steps of
            H = T / K in numerical time, as many as the clock needs).
        u: controls, constant (n_u,) or per step (K, n_u) (constant only with
            `Physical`); None for systems without controls.

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
        adapt: `Adaptivity()` (default: cut failed steps, adapt a_n before impacts) or
            `NO_ADAPTATION`; every change is recorded in the result's `adaptations`.
        verbose: print one line per NLP (from the MPCC layer), one per step and one per
            adaptation.
        throw: raise `SolveFailed` (result attached, up to the failed step) if a step fails.

    Returns:
        A `SimulationResult` (`state_at(t)` reads it at any physical time).

    Raises:
        InvalidInput: wrong shapes, counts or horizon; IncompatibleOptions: a physical
        horizon without a clock, or per-step controls with it; SolveFailed: a step failed
        and `throw`.
    """
    n_steps = positive_int(n_steps, "n_steps")
    n_fe = positive_int(n_finite_elements, "n_finite_elements")
    tf: ClockedSystem | None = None
    if isinstance(system, ClockedSystem) and not isinstance(system, StewartSystem
                                                            | HeavisideSystem):
        tf = system
        pss = system.pss
    else:
        pss = system
    if not isinstance(pss, StewartSystem | HeavisideSystem):
        raise InvalidInput(
            "`system` must be a StewartSystem, HeavisideSystem or time-freezing system, "
            f"got {type(system).__name__}"
        )
    if not isinstance(adapt, Adaptivity):
        raise InvalidInput(f"`adapt` must be an Adaptivity(...), got {adapt!r}")
    physical = horizon if isinstance(horizon, Physical) else None
    if physical is None:
        if isinstance(horizon, bool) or not isinstance(horizon, int | float | np.floating) \
                or not (math.isfinite(horizon) and horizon > 0):
            raise InvalidInput(
                f"`horizon` must be a positive number [s] or Physical(T), got {horizon!r}")
        step = float(horizon) / n_steps
    else:
        if tf is None:
            raise IncompatibleOptions(
                "`horizon=Physical(...)` needs the clock of a time-freezing system: pass the "
                "TimeFreezingSystem itself (e.g. `simulate(tf, ...)`, not `tf.pss`)")
        step = physical.time / n_steps
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    if x0.size != pss.n_x:
        raise InvalidInput(f"`x0` has {x0.size} entries, expected n_x = {pss.n_x}")
    if not np.all(np.isfinite(x0)):
        raise InvalidInput(f"`x0` must be finite, got {x0}")
    if physical is not None and u is not None and pss.n_u and np.asarray(u).size != pss.n_u:
        raise IncompatibleOptions(
            f"with `horizon=Physical(...)` the number of steps is not known in advance: "
            f"give constant controls of shape ({pss.n_u},), got {np.shape(u)}")
    max_steps = n_steps if physical is None else math.ceil(physical.budget * n_steps)
    controls = _controls(u, n_steps, pss.n_u)
    if physical is not None:
        controls = np.broadcast_to(controls[:1], (max_steps, pss.n_u))
    homotopy = homotopy if homotopy is not None else Homotopy()
    clock_index = None if tf is None else int(tf.clock_index)
    gain = None
    if tf is not None and adapt.gain and tf.kind == "inelastic" and tf.cls is not None:
        gain = _Gain(tf, adapt, step)
    stepper = _Stepper(
        system=pss, tf=tf, scheme=scheme, method=method, n_fe=n_fe,
        relaxation=relaxation if relaxation is not None else Scholtes(), nlp=nlp,
        homotopy=homotopy, retry=retry, max_cuts=adapt.max_cuts, verbose=verbose)

    def clock_of(y: np.ndarray) -> float | None:
        return None if clock_index is None else float(y[clock_index])

    adaptations: list[Adaptation] = []
    pieces: list[_Piece] = []
    x, tau, k = x0, 0.0, 0
    status = SimulationStatus.SUCCESS
    failure = ""
    solve_start = time.perf_counter()
    while True:
        if physical is None and k == n_steps:
            break
        if physical is not None and clock_of(x) >= physical.time - physical.tol:
            break
        if k >= max_steps:
            status = SimulationStatus.BUDGET_EXCEEDED
            failure = (f"the clock reached t = {clock_of(x):.6g} s of {physical.time:.6g} s "
                       f"in {k} steps (budget {max_steps})")
            break
        if gain is not None:
            factor, why = gain.target(x, controls[k], first=k == 0)
            # A new gain costs a new discretisation: changes under 25 % are not made.
            if factor < gain.factor * 0.75:
                adaptations.append(Adaptation(
                    "gain", k, tau, clock_of(x), float(np.max(gain.a_n)),
                    float(np.max(gain.base * factor)), why))
                gain.factor = factor
                if verbose:
                    print(adaptations[-1], flush=True)
        factor = 1.0 if gain is None else gain.factor
        warm = pieces[-1] if pieces else None
        got = stepper.span(k, tau, x, controls[k], step, factor, warm, 0, adaptations,
                           clock_of(x))
        if got is not None and physical is not None and \
                got[-1].end[clock_index] > physical.time + physical.tol:
            got = _land(stepper, got, k, tau, x, controls[k], factor, physical, clock_index,
                        adaptations)
        if got is None:
            status = SimulationStatus.STEP_FAILED
            failure = _failure_message(k, n_steps, tau, clock_of(x), step, adapt, stepper,
                                       gain, tf, physical is not None)
            break
        pieces += got
        x, tau = got[-1].end, got[-1].tau + got[-1].length
        if verbose:
            print(f"step {k + 1}" + ("" if physical else f"/{n_steps}") + f": tau = {tau:.6g} s"
                  + ("" if clock_index is None else f", t = {clock_of(x):.6g} s")
                  + f", {got[-1].result.message}", flush=True)
        k += 1
    solve_time = time.perf_counter() - solve_start
    # the discretisation of one nominal step (built by the first step already)
    nominal, _ = stepper.built(step, pieces[0].factor if pieces else
                               (1.0 if gain is None else gain.factor))
    return _result(
        status, failure, pieces, stepper, nominal, controls[:k], x0, adaptations,
        clock_index, gain, build_time=stepper.build_time, solve_time=solve_time,
        n_reached=k + (status is SimulationStatus.STEP_FAILED),
        throw=throw)


def _land(stepper: _Stepper, got: list[_Piece], k: int, tau: float, x: np.ndarray,
          u: np.ndarray, factor: float, physical: Physical, clock_index: int,
          record: list[Adaptation]) -> list[_Piece] | None:
    """Re-solve the step that passes the physical horizon T so that its clock ends at T:
    the first length from the overshooting step's clock polynomial, then regula falsi on
    the clock at the end (non-decreasing in the length)."""
    target = physical.time
    probe = _result(SimulationStatus.SUCCESS, "", got, stepper, got[0].disc,
                    np.zeros((1, u.size)), x, [], clock_index, None, 0.0, 0.0, 1, False)
    tau_hit = _tau_at(probe, target)
    lo, c_lo = 0.0, float(x[clock_index])
    hi, c_hi = sum(p.length for p in got), float(got[-1].end[clock_index])
    full, best = hi, got
    length = min(max(tau_hit, 1e-6 * hi), hi)
    for _ in range(6):
        trial = stepper.span(k, tau, x, u, length, factor, None, 0, record,
                             float(x[clock_index]))
        if trial is None:
            break
        c = float(trial[-1].end[clock_index])
        if abs(c - target) <= physical.tol:
            record.append(Adaptation(
                "last_step", k, tau, float(x[clock_index]), full, length,
                f"the clock ends at t = {c:.12g} s (Physical({target:g}))"))
            if stepper.verbose:
                print(record[-1], flush=True)
            return trial
        if c < target:
            lo, c_lo = length, c
        else:
            hi, c_hi, best = length, c, trial
        length = lo + (target - c_lo) * (hi - lo) / (c_hi - c_lo) if c_hi > c_lo else \
            0.5 * (lo + hi)
        length = min(max(length, lo + 1e-3 * (hi - lo)), hi - 1e-3 * (hi - lo))
    c = float(best[-1].end[clock_index])
    record.append(Adaptation(
        "last_step", k, tau, float(x[clock_index]), full, sum(p.length for p in best),
        f"the clock ends at t = {c:.12g} s, {c - target:.3g} s past Physical({target:g}) "
        "(no shorter step landed within `Physical.tol`; `state_at` reads the state at T)"))
    if stepper.verbose:
        print(record[-1], flush=True)
    return best


def _tau_at(result: SimulationResult, t: float) -> float:
    """The numerical time (from the result's start) where its clock reaches t; the end of
    the frozen piece if t is an impact time."""
    first, last, theta = result.locate(t, side="post", tol=0.0)
    tau = result.t[last + 1] if theta is None else result.t[first] + theta * result.h[first]
    return float(tau - result.t[0])


def _failure_message(k: int, n_steps: int, tau: float, clock: float | None, step: float,
                     adapt: Adaptivity, stepper: _Stepper, gain: _Gain | None,
                     tf: ClockedSystem | None, physical: bool) -> str:
    """Where the simulation failed and concrete settings to try (a_n, step, elements)."""
    last = stepper.failed[-1] if stepper.failed else None
    where = (f"step {k + 1}" + ("" if physical else f" of {n_steps}")
             + f" failed at tau = {tau:.6g} s" + ("" if clock is None else f" (t = {clock:.6g} s)"))
    if adapt.max_cuts:
        where += f", also cut down to steps of {step / 2 ** adapt.max_cuts:.3g} s"
    hints = []
    inelastic = tf is not None and tf.kind == "inelastic" and tf.cls is not None
    if inelastic:
        a_n = gain.a_n if gain is not None else tuple(c.a_n for c in tf.cls.contacts)
        now = ", ".join(f"{a:.4g}" for a in a_n)
        smaller = ", ".join(f"{a / 4:.4g}" for a in a_n)
        hints.append(f"a smaller auxiliary gain: the contacts had a_n = {now}, try a_n = "
                     f"{smaller} (Contact.a_n; a frozen piece lasts |v_n| / (D a_n) in "
                     "numerical time)" + ("" if gain is not None else
                                          ", or let simulate adapt it (Adaptivity(gain=True))"))
    hints.append(f"smaller steps: n_steps = {2 * n_steps} (step {step / 2:.4g} s instead "
                 f"of {step:.4g} s)")
    hints.append(f"more finite elements: n_finite_elements = {stepper.n_fe + 1}")
    if adapt.max_cuts < 3:
        hints.append("cutting failed steps: Adaptivity(max_cuts=3)")
    if tf is None:
        hints.append("for a time-freezing system, passing the TimeFreezingSystem itself (not "
                     "`.pss`), so that simulate can adapt its auxiliary gain a_n")
    return (f"{where}: {last.message if last else 'no NLP solved'}. Try "
            + "; or ".join(hints))


def _result(status: SimulationStatus, failure: str, pieces: list[_Piece], stepper: _Stepper,
            nominal: Discretization, controls: np.ndarray, x0: np.ndarray,
            adaptations: list[Adaptation], clock_index: int | None, gain: _Gain | None,
            build_time: float, solve_time: float, n_reached: int,
            throw: bool) -> SimulationResult:
    s = nominal.tableau.stages
    n_x = nominal.n_x
    xs, ts, xst, tst, hs, alg = [x0[None, :]], [np.zeros(1)], [], [], [], []
    if pieces:
        xs = [pieces[0].disc.states(pieces[0].w)[:1]]
        ts = [np.array([pieces[0].tau])]
    for piece in pieces:
        disc, w = piece.disc, piece.w
        xs.append(disc.states(w)[1:])
        ts.append(piece.tau + disc.times(w)[1:])
        xst.append(disc.stage_states(w))
        tst.append(piece.tau + disc.stage_times(w))
        hs.append(disc.steps(w))
        alg.append(disc.algebraic(w))
    algebraic = {name: np.concatenate([a[name] for a in alg]) if alg else np.zeros((0,))
                 for name in (alg[0] if alg else {})}
    t = np.concatenate(ts)
    theta = _theta(nominal, algebraic) if alg else np.zeros((0, s, nominal.form.m))
    solved = [p.result for p in pieces]
    message = status.value if not failure else failure
    out = SimulationResult(
        status=status, message=message, t=t, x=np.concatenate(xs),
        t_stages=np.concatenate(tst) if tst else np.zeros((0, s)),
        x_stages=np.concatenate(xst) if xst else np.zeros((0, s, n_x)),
        algebraic=algebraic, u=controls, h=np.concatenate(hs) if hs else np.zeros(0),
        switch_times=switch_times(t, theta.max(axis=1) > 1e-5, nominal.grid.h0),
        n_nlps=sum(r.n_nlps for r in stepper.attempts),
        total_iterations=sum(r.total_iterations for r in stepper.attempts),
        residual=max((r.residual for r in solved), default=0.0),
        build_time=build_time, solve_time=solve_time,
        step_results=tuple(solved + stepper.failed[-1:])
        if status is SimulationStatus.STEP_FAILED else tuple(solved),
        discretization=nominal, n_retries=len(stepper.retries),
        adaptations=tuple(adaptations), clock_index=clock_index,
        a_n=() if gain is None else gain.a_n, n_steps=n_reached,
    )
    if throw and not out.success:
        raise SolveFailed(message, out)
    return out


def _theta(disc: Discretization, algebraic: dict[str, np.ndarray]) -> np.ndarray:
    return disc.system.theta(algebraic)
