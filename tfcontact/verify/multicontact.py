"""An event-driven reference simulator of the ORIGINAL system with several frictional
contacts (for verification; never the FESD discretisation that made a plan).

`simulate_multicontact` integrates a CLS (DESIGN.md 4.3-4.4)

    q' = v,   M(q) v' = f_v(q, v, u) + sum_i (n_i lambda_n,i + B_i lambda_t,i),

with any number of unilateral contacts with Coulomb friction, phase by phase:

* **A smooth phase** has a fixed contact mode per contact: open, stick or slip (with a
  direction). Closed contacts (stick, slip, frictionless) keep n_i^T v' + dn_i/dt^T v = 0,
  sticking ones also B_i^T v' + dB_i/dt^T v = 0, slipping ones take
  lambda_t,i = -mu_i lambda_n,i d_i with d_i = v_t,i / ||v_t,i|| (the exact cone; planar:
  the sign of v_t at the phase start). These linear equations give the forces at every
  right-hand-side evaluation; the phase is integrated by `scipy.integrate.solve_ivp`
  (DOP853) until an event: a gap reaching zero (impact), a normal force reaching zero
  (lift-off), a slip velocity reaching zero (slip -> stick), a sticking force reaching the
  cone's edge (stick -> slip), or a control breakpoint.
* **At each mode change** the new modes come from the acceleration-level contact LCP
  (Stewart and Trinkle, IJNME 39 (1996) 2673; Cottle, Pang, Stone 1992, section 1.2):
  for each closed contact 0 <= lambda_n,i perp a_n,i >= 0; for one at rest tangentially
  lambda_t,i = D beta_i, 0 <= beta_i perp gamma_i e + D^T a_t,i >= 0,
  0 <= gamma_i perp mu_i lambda_n,i - e^T beta_i >= 0 (gamma_i > 0: it slips along
  a_t,i); a slipping one contributes n_i - mu_i B_i d_i. Solved by Lemke's algorithm
  (`tfcontact.verify.lcp`). No solution (Lemke's ray) is Painleve's inconsistency: the
  simulation stops with status "painleve".
* **Impacts** (restitution 0): the velocity-level impulse LCP over every contact whose gap
  is closed, 0 <= Lambda_n,i perp n_i^T v+ >= 0, tangential impulses D beta_i in the cone
  with maximal dissipation at the post-impact velocity (the same complementarity at the
  velocity level: Stewart and Trinkle 1996; Anitescu and Potra, Nonlinear Dyn. 14 (1997)
  231), v+ = v- + M^{-1} sum_i (n_i Lambda_n,i + B_i D beta_i); contacts left with
  n_i^T v+ = 0 stay closed, the LCP of the accelerations then decides their modes.

Friction cone: planar contacts (one tangent) are exact (D = [1, -1]). 3-D contacts (two
tangents) are exact in slip and in the cone event of an isolated stick (||lambda_t|| <=
mu lambda_n); the LCPs (mode decisions, impacts) and the stick margin of a statically
indeterminate set use the inscribed pyramid of `facets` edges, whose cone is smaller by the
factor cos(pi / facets) (16 facets: 1.9 %).

Statically indeterminate contacts (a box on four corners, two corners sticking side by side)
have non-unique forces: the phase uses the minimum-norm forces (least squares), which give
the unique motion when every closed contact sticks or is frictionless. Their lift-off and
stick-slip events are then one margin: the largest s such that some admissible force
distribution keeps every lambda_n,i >= s and every sticking force s inside the (pyramid)
cone, a linear program (`scipy.optimize.linprog`, HiGHS); the mode is decided anew when it
reaches zero. Slipping redundant contacts take the minimum-norm distribution (the rigid
model does not fix it; the motion can depend on it).

Drift: no stabilisation. The gaps of closed contacts are kept by the index-reduced
equations only; their drift is reported (`max_gap_drift`). At a mode change the normal
velocities of closed contacts, and the tangential velocities of contacts taken to be at
rest (|v| <= `velocity_tolerance`), are set to zero by the minimum-kinetic-energy
projection v <- v - M^-1 A^T (A M^-1 A^T)^+ A v; its size (of the integrator's tolerance)
is reported (`max_velocity_projection`).

Starts inside an obstacle (up to `start_gap_tolerance`, a plan's restart): a contact that
separates there flies and lands back at its starting depth (its touchdown level); the first
step of such a phase stays short of the landing so the event cannot fire at the start.

Limits (raised as IncompatibleOptions): every contact inelastic (restitution 0; frictionless
elastic contacts: `simulate_impacts`); n_q = n_v.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum

import casadi as ca
import numpy as np
from scipy import optimize
from scipy.integrate import solve_ivp
from scipy.optimize import linprog

from tfcontact.errors import IncompatibleOptions, InvalidInput, TfcontactError, positive_int
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem
from tfcontact.verify.lcp import solve_lcp
from tfcontact.verify.reference import StackedFunction, checked_control
from tfcontact.verify.replay import (
    LOCAL_DEFECT_IMPACT_WINDOW,
    ReplayedPlan,
    ReplayTo,
    StoppedReplay,
)


class ContactMode(StrEnum):
    """The mode of one contact in a smooth phase."""

    OPEN = "open"
    STICK = "stick"
    SLIP = "slip"


class EventKind(StrEnum):
    """What happened to a contact at an event."""

    IMPACT = "impact"
    TOUCHDOWN = "touchdown"  # closed without an impact (grazing, v_n = 0)
    LIFT_OFF = "lift_off"
    STICK = "stick"
    SLIP = "slip"


class SimulationStatus(StrEnum):
    """How `simulate_multicontact` ended; `hint` says what to do."""

    SUCCESS = "success"
    PAINLEVE = "painleve"
    MAX_EVENTS = "max_events"
    MAX_RHS_EVALUATIONS = "max_rhs_evaluations"
    INTEGRATION_FAILED = "integration_failed"

    @property
    def hint(self) -> str:
        return {
            "success": "reached the final time",
            "painleve": "the contact LCP has no solution (Painleve's paradox: a slip whose "
                        "normal force would be negative); lower mu or change the start",
            "max_events": "too many events (Zeno accumulation, chattering): raise "
                          "`max_events` if the events are genuine",
            "max_rhs_evaluations": "the step size collapsed: raise `max_rhs_evaluations` "
                                   "or look for a singular configuration",
            "integration_failed": "solve_ivp failed inside a phase, or its step reached "
                                  "states the contact equations cannot be solved at",
        }[self.value]


@dataclass(frozen=True)
class MultiContactOptions:
    """Settings of `simulate_multicontact`.

    Args:
        rtol, atol: solve_ivp (DOP853) tolerances.
        max_events: stop (status "max_events") after this many events (Zeno cap).
        max_rhs_evaluations: stop after this many model evaluations.
        facets: edges of the inscribed friction pyramid of 3-D contacts in the LCPs (even,
            >= 4); planar contacts are exact whatever this is.
        contact_tolerance: a gap at most this [m] counts as closed at a mode change.
        velocity_tolerance: a normal or tangential contact velocity at most this [m/s]
            counts as zero at a mode change (and is projected to zero).
        start_gap_tolerance: x0 may lie this far inside an obstacle [m].
        max_step: solve_ivp's max_step [s].

    Raises:
        InvalidInput: a value out of range.
    """

    rtol: float = 1e-10
    atol: float = 1e-11
    max_events: int = 200
    max_rhs_evaluations: int = 1_000_000
    facets: int = 16
    contact_tolerance: float = 1e-8
    velocity_tolerance: float = 1e-7
    start_gap_tolerance: float = 1e-9
    max_step: float = math.inf

    def __post_init__(self) -> None:
        for name in ("rtol", "atol", "contact_tolerance", "velocity_tolerance",
                     "start_gap_tolerance", "max_step"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not value > 0 or math.isnan(value):
                raise InvalidInput(f"`{name}` must be a positive number, got {value!r}")
        positive_int(self.max_events, "max_events")
        positive_int(self.max_rhs_evaluations, "max_rhs_evaluations")
        positive_int(self.facets, "facets")
        if self.facets < 4 or self.facets % 2:
            raise InvalidInput(f"`facets` must be even and >= 4 (the friction pyramid's "
                               f"edges), got {self.facets}")


@dataclass(frozen=True)
class ContactEvent:
    """A change of one contact's mode: time [s], kind, contact index and name."""

    time: float
    kind: EventKind
    contact: int
    name: str


@dataclass(frozen=True, eq=False)
class ContactImpact:
    """A simultaneous impact.

    Attributes:
        time: [s]; pre, post: x = (q, v) before and after.
        contacts: the contacts in the impulse LCP (every closed gap).
        normal_impulses: Lambda_n per contact of `contacts` [N s], shape (k,).
        tangential_impulses: Lambda_t per contact [N s], shape (k, n_t max) (zero-padded).
    """

    time: float
    pre: np.ndarray
    post: np.ndarray
    contacts: tuple[int, ...]
    normal_impulses: np.ndarray
    tangential_impulses: np.ndarray


@dataclass(frozen=True, eq=False)
class MultiContactSimulation:
    """The result of `simulate_multicontact`.

    Attributes:
        t: sample times [s], (K,), non-decreasing; an impact repeats its time (pre, post).
        x: states (q, v) at the samples, (K, 2 n_q).
        normal_forces: lambda_n per contact at the samples [N], (K, n_c); 0 when open, nan
            at the sample just after an impulse (before the new modes are decided).
        tangential_forces: lambda_t per contact [N], (K, n_c, n_t max).
        events: the mode changes, in order.
        impacts: the impacts, in order.
        modes: (start time [s], modes of all contacts) of each phase.
        status: a `SimulationStatus`; message: what happened.
        n_rhs: model evaluations.
        max_gap_drift: the largest |gap| of a closed contact at a sample [m].
        max_velocity_projection: the largest velocity change of the projections at mode
            changes [m/s, rad/s].
    """

    t: np.ndarray
    x: np.ndarray
    normal_forces: np.ndarray
    tangential_forces: np.ndarray
    events: tuple[ContactEvent, ...]
    impacts: tuple[ContactImpact, ...]
    modes: tuple[tuple[float, tuple[ContactMode, ...]], ...]
    status: SimulationStatus
    message: str
    n_rhs: int
    max_gap_drift: float = 0.0
    max_velocity_projection: float = 0.0

    @property
    def success(self) -> bool:
        return self.status == SimulationStatus.SUCCESS

    def final_state(self) -> np.ndarray:
        return self.x[-1].copy()

    def state_at(self, time: float) -> np.ndarray:
        """The state at the last sample at or before `time` (after an impact there)."""
        return self.x[int(np.flatnonzero(self.t <= time)[-1])].copy()

    def deviation_at(self, time: float, state: np.ndarray, window: float = 0.0) -> float:
        """max |x(time) - state|; an impact within `window` of `time` counts on either side
        (a plan may put it on the other side of a control-interval boundary)."""
        candidates = [self.state_at(time)]
        candidates += [x for imp in self.impacts if abs(imp.time - time) <= window
                       for x in (imp.pre, imp.post)]
        return min(float(np.max(np.abs(x - state))) for x in candidates)


class _BudgetExceeded(Exception):
    """The model evaluation budget is used up (caught in `simulate_multicontact`)."""


class _Painleve(Exception):
    """The contact LCP has no solution (caught in `simulate_multicontact`)."""


@dataclass
class _Terms:
    a_free: np.ndarray   # M^-1 f_v, (n,)
    minv_j: np.ndarray   # M^-1 J, (n, m); J = [n_0 B_0 n_1 B_1 ...]
    j: np.ndarray        # J, (n, m)
    drift: np.ndarray    # d/dt(J^T) v, (m,)
    gaps: np.ndarray     # (n_c,)

    @property
    def delassus(self) -> np.ndarray:
        return self.j.T @ self.minv_j

    @property
    def free_rate(self) -> np.ndarray:
        """J^T a_free + drift: the contact accelerations without contact forces."""
        return self.j.T @ self.a_free + self.drift


class _Model:
    """Numeric terms of a CLS with several contacts, one CasADi call per evaluation."""

    def __init__(self, cls: ComplementarityLagrangianSystem, facets: int, max_calls: int):
        self.n = cls.n_q
        self.n_c = cls.n_contacts
        self.names = tuple(c.name for c in cls.contacts)
        self.mu = np.array([c.mu if c.has_friction else 0.0 for c in cls.contacts])
        self.n_t = [c.n_tangents if c.has_friction else 0 for c in cls.contacts]
        self.n_t_max = max(self.n_t)
        self.start = np.cumsum([0] + [1 + k for k in self.n_t])  # column of n_i in J
        self.m = int(self.start[-1])
        columns = []
        for c, k in zip(cls.contacts, self.n_t, strict=True):
            columns += [c.normal] + ([c.tangents] if k else [])
        jac = ca.horzcat(*columns)
        rates = ca.mtimes(jac.T, cls.v)
        drift = ca.mtimes(ca.jacobian(rates, cls.q), cls.v)
        gaps = ca.vertcat(*[c.gap for c in cls.contacts])
        self._f = StackedFunction("multicontact_terms", [ca.vertcat(cls.q, cls.v), cls.u],
                                  [cls.acceleration, cls.solve_mass(jac), jac, drift, gaps])
        self.facets = {1: np.array([[1.0, -1.0]])}  # D per tangent count: columns d_j
        angles = 2 * np.pi * np.arange(facets) / facets
        self.facets[2] = np.vstack([np.cos(angles), np.sin(angles)])
        # The inscribed pyramid's faces: normals between the edges, at cos(pi/k) of mu.
        mid = angles + np.pi / facets
        self.faces = {1: (np.array([[1.0], [-1.0]]), 1.0),
                      2: (np.column_stack([np.cos(mid), np.sin(mid)]), math.cos(np.pi / facets))}
        self.calls = 0
        self.max_calls = max_calls

    def terms(self, x: np.ndarray, u: np.ndarray) -> _Terms:
        self.calls += 1
        if self.calls > self.max_calls:
            raise _BudgetExceeded
        a_free, minv_j, jac, drift, gaps = self._f(x, u)
        return _Terms(a_free.ravel(), minv_j, jac, drift.ravel(), gaps.ravel())

    def normal_col(self, i: int) -> int:
        return int(self.start[i])

    def tangent_cols(self, i: int) -> slice:
        return slice(int(self.start[i]) + 1, int(self.start[i]) + 1 + self.n_t[i])

    def unit(self, col: int) -> np.ndarray:
        e = np.zeros(self.m)
        e[col] = 1.0
        return e


@dataclass
class _Phase:
    """The modes of a smooth phase and their slip directions."""

    modes: list[ContactMode]
    directions: list[np.ndarray | None] = field(default_factory=list)

    def closed(self) -> list[int]:
        return [i for i, m in enumerate(self.modes) if m != ContactMode.OPEN]


def _mode_forces(model: _Model, terms: _Terms, v: np.ndarray, phase: _Phase,
                 direction_floor: float):
    """(v', lambda (stacked by unknown), G, layout) of the phase's equality system:
    G lambda = -rate, minimum norm where G is singular (statically indeterminate)."""
    force_cols, rows, layout = [], [], []  # layout: (contact, "n" | "t", tangent k)
    for i in phase.closed():
        e_n = model.unit(model.normal_col(i))
        column = e_n.copy()
        if phase.modes[i] == ContactMode.SLIP and model.n_t[i]:  # frictionless: no term
            column[model.tangent_cols(i)] -= model.mu[i] * _slip_direction(
                model, terms, v, i, phase.directions[i], direction_floor)
        force_cols.append(column)
        rows.append(e_n)
        layout.append((i, "n", 0))
        if phase.modes[i] == ContactMode.STICK:
            for k in range(model.n_t[i]):
                e_t = model.unit(model.normal_col(i) + 1 + k)
                force_cols.append(e_t)
                rows.append(e_t)
                layout.append((i, "t", k))
    if not layout:
        return terms.a_free, np.zeros(0), np.zeros((0, 0)), layout, np.zeros((model.m, 0))
    s_w, s_h = np.column_stack(force_cols), np.column_stack(rows)
    g = s_h.T @ terms.delassus @ s_w
    lam = np.linalg.lstsq(g, -(s_h.T @ terms.free_rate), rcond=1e-10)[0]
    return terms.a_free + terms.minv_j @ (s_w @ lam), lam, g, layout, s_w


def _slip_direction(model: _Model, terms: _Terms, v: np.ndarray, i: int,
                    direction: np.ndarray, floor: float) -> np.ndarray:
    """d_i: the phase's direction for a planar contact (its sign cannot flip inside the
    phase: the stop event ends it), v_t / ||v_t|| in 3-D once ||v_t|| exceeds `floor`."""
    if model.n_t[i] == 1:
        return direction
    vt = terms.j[:, model.tangent_cols(i)].T @ v
    speed = float(np.linalg.norm(vt))
    return vt / speed if speed > floor else direction


def _split_forces(model: _Model, lam: np.ndarray, layout, phase: _Phase, terms: _Terms,
                  v: np.ndarray, floor: float):
    """Per contact (lambda_n (n_c,), lambda_t (n_c, n_t max))."""
    normal = np.zeros(model.n_c)
    tangential = np.zeros((model.n_c, max(model.n_t_max, 1)))
    for value, (i, kind, k) in zip(lam, layout, strict=True):
        if kind == "n":
            normal[i] = value
        else:
            tangential[i, k] = value
    for i in phase.closed():
        if phase.modes[i] == ContactMode.SLIP and model.n_t[i]:
            d = _slip_direction(model, terms, v, i, phase.directions[i], floor)
            tangential[i, :model.n_t[i]] = -model.mu[i] * normal[i] * d
    return normal, tangential[:, :model.n_t_max]


def _margin_lp(model: _Model, lam: np.ndarray, g: np.ndarray, layout,
               phase: _Phase) -> tuple[float, np.ndarray, list[tuple[int, str]]]:
    """The largest s such that lambda + N c (N spanning G's null space) keeps every
    lambda_n >= s and every sticking force s inside the inscribed pyramid (module
    docstring), capped at max(1, |lambda|); with the distribution lambda + N c that
    reaches it and the constraints tight there: (contact, "lift" | "slip")."""
    _, sv, vt = np.linalg.svd(g)
    rank = int(np.sum(sv > 1e-10 * max(sv.max(), 1e-300)))
    null = vt[rank:].T
    index = {(i, kind, k): j for j, (i, kind, k) in enumerate(layout)}
    a_rows, b_rows, owners = [], [], []  # a . (c, s) <= b
    for i in phase.closed():
        jn = index[(i, "n", 0)]
        a_rows.append(np.append(-null[jn], 1.0))
        b_rows.append(lam[jn])
        owners.append((i, "lift"))
        if phase.modes[i] == ContactMode.STICK and model.n_t[i]:
            normals, factor = model.faces[model.n_t[i]]
            jt = [index[(i, "t", k)] for k in range(model.n_t[i])]
            for face in normals:
                # face . lambda_t - factor mu lambda_n + s <= 0
                row = face @ null[jt] - factor * model.mu[i] * null[jn]
                a_rows.append(np.append(row, 1.0))
                b_rows.append(factor * model.mu[i] * lam[jn] - face @ lam[jt])
                owners.append((i, "slip"))
    cap = max(1.0, float(np.abs(lam).max()))
    cost = np.zeros(null.shape[1] + 1)
    cost[-1] = -1.0
    bounds = [(None, None)] * null.shape[1] + [(None, cap)]
    a_ub, b_ub = np.array(a_rows), np.array(b_rows)
    res = linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    if res.status != 0:
        return -cap, lam, []
    slack = b_ub - a_ub @ res.x
    tight = sorted({owner for owner, gap in zip(owners, slack, strict=True)
                    if gap <= 1e-9 * cap})
    return float(res.x[-1]), lam + null @ res.x[:-1], tight


def _project(model: _Model, terms: _Terms, x: np.ndarray, cols: list[int]) -> tuple[
        np.ndarray, float]:
    """v <- v - M^-1 A^T (A M^-1 A^T)^+ A v with A = J[:, cols]^T (module docstring)."""
    if not cols:
        return x, 0.0
    n = model.n
    a = terms.j[:, cols]
    w = a.T @ terms.minv_j[:, cols]
    dv = -terms.minv_j[:, cols] @ np.linalg.lstsq(w, a.T @ x[n:], rcond=1e-10)[0]
    x = x.copy()
    x[n:] += dv
    return x, float(np.abs(dv).max())


def _contact_lcp(model: _Model, terms: _Terms, contacts: list[int],
                 slipping: dict[int, np.ndarray], velocity: np.ndarray | None):
    """The contact LCP of `contacts` (module docstring), at the acceleration level
    (`velocity` None: rates J^T a_free + drift) or the velocity level (impulses; rates
    J^T v). Contacts in `slipping` (acceleration level only) slip along the given
    direction. Returns (z split as {contact: (lambda_n, beta, gamma)}, force vector over
    J's columns, contact rates after the forces, solved)."""
    rate0 = terms.free_rate if velocity is None else terms.j.T @ velocity
    if not contacts:  # every closed contact lifts off (a lone foot's announced lift-off)
        return {}, np.zeros(model.m), rate0, True
    force_cols, rows, blocks = [], [], []  # blocks: (contact, first var, n_beta)
    for i in contacts:
        e_n = model.unit(model.normal_col(i))
        column = e_n.copy()
        if i in slipping:
            column[model.tangent_cols(i)] -= model.mu[i] * slipping[i]
        force_cols.append(column)
        rows.append(e_n)
    for i in contacts:
        if model.n_t[i] and i not in slipping:
            d = model.facets[model.n_t[i]]
            blocks.append((i, len(force_cols), d.shape[1]))
            for j in range(d.shape[1]):
                e = np.zeros(model.m)
                e[model.tangent_cols(i)] = d[:, j]
                force_cols.append(e)
                rows.append(e)
    p = len(force_cols)
    n_var = p + len(blocks)
    s_w, s_h = np.column_stack(force_cols), np.column_stack(rows)
    mat = np.zeros((n_var, n_var))
    mat[:p, :p] = s_h.T @ terms.delassus @ s_w
    q = np.zeros(n_var)
    q[:p] = s_h.T @ rate0
    for b, (i, first, count) in enumerate(blocks):
        gamma = p + b
        mat[first:first + count, gamma] = 1.0
        mat[gamma, contacts.index(i)] = model.mu[i]
        mat[gamma, first:first + count] = -1.0
    solution = solve_lcp(mat, q)
    z = solution.z
    forces = s_w @ z[:p]
    rates = rate0 + terms.delassus @ forces
    split = {}
    for k, i in enumerate(contacts):
        split[i] = (float(z[k]), np.zeros(0), 0.0)
    for b, (i, first, count) in enumerate(blocks):
        split[i] = (split[i][0], z[first:first + count], float(z[p + b]))
    return split, forces, rates, solution.solved


def simulate_multicontact(
    cls: ComplementarityLagrangianSystem,
    x0: np.ndarray,
    u_of_t: Callable[[float], np.ndarray] | None,
    T: float,
    *,
    options: MultiContactOptions | None = None,
    breakpoints: Sequence[float] = (),
) -> MultiContactSimulation:
    """Event-driven simulation of a CLS with several frictional contacts (module
    docstring).

    Main arguments:
        cls: the CLS; every contact inelastic (restitution 0).
        x0: start state (q0, v0), shape (2 n_q,), every gap >= -start_gap_tolerance.
        u_of_t: control as a function of time [s] -> shape (n_u,); None without controls.
        T: final time [s].

    Other arguments:
        options: `MultiContactOptions` (tolerances, event cap, pyramid facets).
        breakpoints: times [s] where u_of_t jumps; each ends a phase, the modes are then
            decided anew, and the samples include each.

    Returns:
        A `MultiContactSimulation`; a failure is a status, not an exception.

    Raises:
        InvalidInput: wrong shapes or values, x0 inside an obstacle.
        IncompatibleOptions: a contact with restitution > 0.
    """
    options = MultiContactOptions() if options is None else options
    if not isinstance(options, MultiContactOptions):
        raise InvalidInput(f"`options` must be a MultiContactOptions, got {options!r}")
    if not isinstance(cls, ComplementarityLagrangianSystem):
        raise InvalidInput(f"`cls` must be a ComplementarityLagrangianSystem, got {type(cls)}")
    if not (isinstance(T, int | float) and math.isfinite(T) and T > 0):
        raise InvalidInput(f"`T` must be a finite number > 0 [s], got {T!r}")
    for c in cls.contacts:
        if c.restitution > 0:
            raise IncompatibleOptions(
                f"contact {c.name!r} has restitution {c.restitution}: "
                "`simulate_multicontact` models inelastic impacts only; use "
                "`simulate_impacts` for frictionless elastic contacts")
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.shape != (2 * cls.n_q,) or not np.all(np.isfinite(x0)):
        raise InvalidInput(f"`x0` must be finite with shape ({2 * cls.n_q},), got {x0.shape}")
    control = checked_control(u_of_t, cls.n_u)
    model = _Model(cls, options.facets, options.max_rhs_evaluations)
    return _Simulator(model, control, T, options, breakpoints).run(x0)


class _Simulator:
    """The event loop of `simulate_multicontact`."""

    def __init__(self, model: _Model, control: Callable[[float], np.ndarray], T: float,
                 options: MultiContactOptions, breakpoints: Sequence[float]):
        self.model, self.control, self.T, self.opt = model, control, float(T), options
        self.stops = sorted({float(b) for b in breakpoints if 0.0 < b < T} | {float(T)})
        self.ts: list[np.ndarray] = []
        self.xs: list[np.ndarray] = []
        self.fn: list[np.ndarray] = []
        self.ft: list[np.ndarray] = []
        self.events: list[ContactEvent] = []
        self.impacts: list[ContactImpact] = []
        self.modes: list[tuple[float, tuple[ContactMode, ...]]] = []
        self.drift = 0.0
        self.projection = 0.0
        self.floor = options.velocity_tolerance

    # ---------------------------------------------------------------- samples

    def record(self, t: np.ndarray, x: np.ndarray, phase: _Phase | None) -> None:
        """Append samples with their contact forces (nan forces: `phase` None)."""
        model = self.model
        n_t = max(model.n_t_max, 0)
        normal = np.full((len(t), model.n_c), np.nan)
        tangential = np.full((len(t), model.n_c, n_t), np.nan)
        if phase is not None:
            for k, (tk, xk) in enumerate(zip(t, x, strict=True)):
                terms = model.terms(xk, self.control(tk))
                _, lam, _, layout, _ = _mode_forces(model, terms, xk[model.n:], phase,
                                                    self.floor)
                normal[k], tangential[k] = _split_forces(model, lam, layout, phase, terms,
                                                         xk[model.n:], self.floor)
                closed = phase.closed()
                if closed:
                    self.drift = max(self.drift, float(np.abs(terms.gaps[closed]).max()))
        self.ts.append(np.asarray(t, dtype=float))
        self.xs.append(np.asarray(x, dtype=float))
        self.fn.append(normal)
        self.ft.append(tangential)

    # ---------------------------------------------------------------- mode changes

    def decide(self, t: float, x: np.ndarray, previous: _Phase | None,
               fired: Sequence[tuple[str, int]] = ()) -> tuple[np.ndarray, _Phase]:
        """Impact if a closed gap approaches, then the contact LCP: the next phase.

        At a lift-off or stick -> slip event (`fired`) the LCP of that instant is
        degenerate (stick and slip, or closed and open, both fit with a zero force or
        margin): the transition the event announced is imposed first (the contact opens,
        or slips against its friction force), and the LCP decides the rest; if that has no
        solution the LCP decides alone."""
        model, opt = self.model, self.opt
        u = self.control(t)
        terms = model.terms(x, u)
        n = model.n
        near = [i for i in range(model.n_c) if terms.gaps[i] <= opt.contact_tolerance]
        vn = np.array([terms.j[:, model.normal_col(i)] @ x[n:] for i in range(model.n_c)])
        if any(vn[i] < -opt.velocity_tolerance for i in near):
            x, terms = self.impact(t, x, near, vn, previous)
            vn = np.array([terms.j[:, model.normal_col(i)] @ x[n:] for i in range(model.n_c)])
        closed = [i for i in near if vn[i] <= opt.velocity_tolerance]
        at_rest, slipping = [], {}
        for i in closed:
            if model.n_t[i]:
                vt = terms.j[:, model.tangent_cols(i)].T @ x[n:]
                with np.errstate(under="ignore"):  # a resting contact's speed may be ~1e-160
                    speed = float(np.linalg.norm(vt))
                if speed <= opt.velocity_tolerance:
                    at_rest.append(i)
                else:
                    slipping[i] = vt / speed
        cols = [model.normal_col(i) for i in closed]
        cols += [c for i in at_rest for c in range(model.tangent_cols(i).start,
                                                    model.tangent_cols(i).stop)]
        lifting, forced_slip = self.announced(terms, x, previous, fired)
        x, moved = _project(model, terms, x, cols)
        self.projection = max(self.projection, moved)
        modes = [ContactMode.OPEN] * model.n_c
        directions: list[np.ndarray | None] = [None] * model.n_c
        if closed:
            terms = model.terms(x, u)
            kept = [i for i in closed if i not in lifting]
            split, _, rates, solved = _contact_lcp(model, terms, kept,
                                                   {**slipping, **forced_slip}, None)
            if solved:
                closed, slipping = kept, {**slipping, **forced_slip}
            else:
                split, _, rates, solved = _contact_lcp(model, terms, closed, slipping, None)
            if not solved:
                raise _Painleve(
                    f"no contact forces at t = {t:.9g} s satisfy the complementarity "
                    f"conditions of the closed contacts "
                    f"{[model.names[i] for i in closed]} (slipping: "
                    f"{[model.names[i] for i in slipping]})")
            scale = 1e-12 * (1.0 + float(np.abs(rates).max()))
            for i in closed:
                lam_n, _, gamma = split[i]
                a_n = rates[model.normal_col(i)]
                if lam_n <= scale and a_n > scale:
                    continue  # lifts off
                if i in slipping:
                    modes[i], directions[i] = ContactMode.SLIP, slipping[i]
                elif model.n_t[i] and gamma > scale:
                    a_t = rates[model.tangent_cols(i)]
                    modes[i] = ContactMode.SLIP
                    directions[i] = a_t / np.linalg.norm(a_t)
                else:
                    modes[i] = ContactMode.STICK if model.n_t[i] else ContactMode.SLIP
            phase = _Phase(modes, directions)
            self.refine_directions(terms, x, phase, slipping)
        else:
            phase = _Phase(modes, directions)
        self.report(t, previous, phase)
        return x, phase

    def announced(self, terms: _Terms, x: np.ndarray, previous: _Phase | None,
                  fired: Sequence[tuple[str, int]]) -> tuple[set[int], dict[int, np.ndarray]]:
        """(contacts that open, {contact: slip direction}) that the fired events announce;
        a slip goes against the friction force of the phase that ended."""
        if previous is None or not fired:
            return set(), {}
        model, n = self.model, self.model.n
        _, lam, g, layout, _ = _mode_forces(model, terms, x[n:], previous, self.floor)
        changes = [(kind, i) for kind, i in fired if kind in ("lift", "slip")]
        if any(kind == "margin" for kind, _ in fired):
            _, lam, tight = _margin_lp(model, lam, g, layout, previous)
            changes += [(kind, i) for i, kind in tight]
        _, tangential = _split_forces(model, lam, layout, previous, terms, x[n:], self.floor)
        lifting = {i for kind, i in changes if kind == "lift"}
        slips = {}
        for kind, i in changes:
            force = tangential[i, :model.n_t[i]] if model.n_t[i] else np.zeros(0)
            if kind == "slip" and i not in lifting and np.linalg.norm(force) > 0:
                slips[i] = -force / np.linalg.norm(force)
        return lifting, slips

    def refine_directions(self, terms: _Terms, x: np.ndarray, phase: _Phase,
                          slipping: dict[int, np.ndarray]) -> None:
        """A 3-D slip starting from rest: the directions d_i with each tangential
        acceleration along its d_i (d_i x a_t,i = 0, d_i . a_t,i > 0), solved for the
        angles from the pyramid LCP's directions (a fixed-point iteration d <- a_t / |a_t|
        diverges when the push barely exceeds the friction). Kept if no root is found."""
        model = self.model
        starting = [i for i, m in enumerate(phase.modes)
                    if m == ContactMode.SLIP and model.n_t[i] == 2 and i not in slipping]
        if not starting:
            return
        first = [phase.directions[i].copy() for i in starting]

        def tangential_rates(angles: np.ndarray) -> list[np.ndarray]:
            for i, angle in zip(starting, angles, strict=True):
                phase.directions[i] = np.array([math.cos(angle), math.sin(angle)])
            acc = _mode_forces(model, terms, np.zeros(model.n), phase, math.inf)[0]
            return [terms.j[:, model.tangent_cols(i)].T @ acc
                    + terms.drift[model.tangent_cols(i)] for i in starting]

        def residual(angles: np.ndarray) -> np.ndarray:
            rates = tangential_rates(angles)
            return np.array([(math.cos(a) * r[1] - math.sin(a) * r[0]) / max(
                float(np.linalg.norm(r)), 1e-300) for a, r in zip(angles, rates, strict=True)])

        start = np.array([math.atan2(d[1], d[0]) for d in first])
        root = optimize.root(residual, start, method="hybr", options={"xtol": 1e-14})
        rates = tangential_rates(root.x)
        if not (root.success and np.abs(residual(root.x)).max() < 1e-10
                and all(r @ phase.directions[i] > 0
                        for i, r in zip(starting, rates, strict=True))):
            for i, d in zip(starting, first, strict=True):
                phase.directions[i] = d

    def impact(self, t: float, x: np.ndarray, near: list[int], vn: np.ndarray,
               previous: _Phase | None) -> tuple[np.ndarray, _Terms]:
        model, n = self.model, self.model.n
        terms = model.terms(x, self.control(t))
        split, forces, _, solved = _contact_lcp(model, terms, near, {}, x[n:])
        if not solved:
            raise _Painleve(f"the impulse LCP at t = {t:.9g} s has no solution")
        post = x.copy()
        post[n:] += terms.minv_j @ forces
        tangential = np.zeros((len(near), model.n_t_max))
        for k, i in enumerate(near):
            if model.n_t[i]:
                tangential[k, :model.n_t[i]] = model.facets[model.n_t[i]] @ split[i][1]
        self.impacts.append(ContactImpact(
            t, x.copy(), post.copy(), tuple(near),
            np.array([split[i][0] for i in near]), tangential))
        for i in near:
            was_open = previous is None or previous.modes[i] == ContactMode.OPEN
            if was_open and vn[i] < -self.opt.velocity_tolerance:
                self.events.append(ContactEvent(t, EventKind.IMPACT, i, model.names[i]))
        self.record(np.array([t]), post[None, :], None)
        return post, model.terms(post, self.control(t))

    def report(self, t: float, previous: _Phase | None, phase: _Phase) -> None:
        if not self.modes or self.modes[-1][1] != tuple(phase.modes):
            self.modes.append((t, tuple(phase.modes)))
        if previous is None:
            return
        hit = {e.contact for e in self.events if e.time == t and e.kind == EventKind.IMPACT}
        for i, (old, new) in enumerate(zip(previous.modes, phase.modes, strict=True)):
            if old == new or i in hit:
                continue
            if new == ContactMode.OPEN:
                kind = EventKind.LIFT_OFF
            elif old == ContactMode.OPEN:
                kind = EventKind.TOUCHDOWN
            else:
                kind = EventKind.STICK if new == ContactMode.STICK else EventKind.SLIP
            self.events.append(ContactEvent(t, kind, i, self.model.names[i]))

    # ---------------------------------------------------------------- phases

    def phase_functions(self, phase: _Phase, control: Callable[[float], np.ndarray],
                        x_start: np.ndarray):
        model, n, floor = self.model, self.model.n, self.floor
        cache: dict[tuple[float, bytes], tuple] = {}

        def solved(t: float, x: np.ndarray):
            key = (t, x.tobytes())
            if key not in cache:
                cache.clear()
                terms = model.terms(x, control(t))
                cache[key] = (terms,) + _mode_forces(model, terms, x[n:], phase, floor)
            return cache[key]

        def rhs(t: float, x: np.ndarray) -> np.ndarray:
            return np.concatenate([x[n:], solved(t, x)[1]])

        events, tags = [], []  # tags: what each event means, for `decide`

        def event(function, direction=-1):
            function.terminal, function.direction = True, direction
            events.append(function)

        terms0 = model.terms(x_start, control(float(self.t_now)))
        for i in range(model.n_c):
            if phase.modes[i] == ContactMode.OPEN:
                surface = min(float(terms0.gaps[i]), 0.0)
                event(lambda t, x, i=i, s=surface: solved(t, x)[0].gaps[i] - s)
                tags.append(("touchdown", i))
        closed = phase.closed()
        _, lam0, g0, layout0, _ = _mode_forces(model, terms0, x_start[n:], phase, floor)
        redundant = bool(closed) and np.linalg.matrix_rank(g0, tol=1e-10 * max(
            1.0, float(np.abs(g0).max()))) < g0.shape[0]
        if redundant:
            event(lambda t, x: _margin_lp(model, *solved(t, x)[2:5], phase)[0])
            tags.append(("margin", -1))
        else:
            for j, (i, kind, _) in enumerate(layout0):
                if kind != "n":
                    continue
                event(lambda t, x, j=j: solved(t, x)[2][j])  # lift-off
                tags.append(("lift", i))
                if phase.modes[i] == ContactMode.STICK:
                    cols = [k for k, (ci, kd, _) in enumerate(layout0) if ci == i and kd == "t"]
                    event(lambda t, x, j=j, cols=cols, mu=model.mu[i]: mu * solved(t, x)[2][j]
                          - float(np.linalg.norm(solved(t, x)[2][cols])))
                    tags.append(("slip", i))
        for i in closed:
            if phase.modes[i] != ContactMode.SLIP or not model.n_t[i]:
                continue
            reference = phase.directions[i].copy()

            def tangential(t, x, i=i):
                return solved(t, x)[0].j[:, model.tangent_cols(i)].T @ x[n:]

            event(lambda t, x, i=i, r=reference: float(tangential(t, x, i) @ r))  # stops
            tags.append(("stop", i))
            if model.n_t[i] == 2:  # the slip turned: restart with a new reference
                event(lambda t, x, i=i, r=reference: float(
                    tangential(t, x, i) @ r - 0.5 * np.linalg.norm(tangential(t, x, i))))
                tags.append(("turn", i))
        return rhs, events, tags

    def first_step(self, phase: _Phase, rhs: Callable[[float, np.ndarray], np.ndarray],
                   t: float, x: np.ndarray) -> float | None:
        """A first step short enough that every open contact leaving its surface (gap
        within `contact_tolerance`, v_n > 0, a_n < 0) is still above its touchdown level
        at the step's end (half its time to the apex). Its touchdown event is 0 at the
        start (a start inside the surface lands back at its own depth, `phase_functions`);
        a first step past the landing makes the event's root finder return the start
        itself, and the contact would open again and again at the same instant."""
        model, n = self.model, self.model.n
        terms = model.terms(x, self.control(t))
        leaving = [i for i in range(model.n_c) if phase.modes[i] == ContactMode.OPEN
                   and terms.gaps[i] <= self.opt.contact_tolerance]
        if not leaving:
            return None
        acceleration = rhs(t, x)[n:]
        flights = []
        for i in leaving:
            normal = terms.j[:, model.normal_col(i)]
            vn = float(normal @ x[n:])
            an = float(normal @ acceleration + terms.drift[model.normal_col(i)])
            if vn > 0 and an < 0:
                flights.append(vn / -an)
        return 0.5 * min(flights) if flights else None

    # ---------------------------------------------------------------- loop

    def run(self, x0: np.ndarray) -> MultiContactSimulation:
        model, opt = self.model, self.opt
        status, message = SimulationStatus.SUCCESS, f"reached T = {self.T} s"
        self.t_now = 0.0
        gaps0 = model.terms(x0, self.control(0.0)).gaps
        if np.any(gaps0 < -opt.start_gap_tolerance):
            raise InvalidInput(f"`x0` is inside an obstacle: gaps(q0) = {gaps0.tolist()} m; "
                               "start on or above every surface")
        self.record(np.array([0.0]), x0[None, :], None)
        t, x = 0.0, x0.copy()
        n_events = 0
        try:
            x, phase = self.decide(t, x, None)
            self.record(np.array([t]), x[None, :], phase)
            while t < self.T:
                self.t_now = t
                t_stop = next(b for b in self.stops if b > t)
                t_left = float(np.nextafter(t_stop, -np.inf))

                def segment(time: float, t_left=t_left) -> np.ndarray:
                    return self.control(min(time, t_left))

                rhs, events, tags = self.phase_functions(phase, segment, x)
                step = self.first_step(phase, rhs, t, x)
                step = None if step is None else min(step, t_stop - t, opt.max_step)
                with np.errstate(under="ignore"):
                    sol = solve_ivp(rhs, (t, t_stop), x, method="DOP853", rtol=opt.rtol,
                                    atol=opt.atol, events=events, max_step=opt.max_step,
                                    first_step=step)
                if sol.status == -1:
                    status = SimulationStatus.INTEGRATION_FAILED
                    message = f"solve_ivp failed in modes {phase.modes}: {sol.message}"
                    break
                t, x = float(sol.t[-1]), sol.y[:, -1].copy()
                self.record(sol.t[1:], sol.y.T[1:], phase)
                fired = [tag for tag, te in zip(tags, sol.t_events, strict=True) if te.size]
                if sol.status == 1:
                    n_events += 1
                    if n_events > opt.max_events:
                        status = SimulationStatus.MAX_EVENTS
                        message = f"stopped after {opt.max_events} events at t = {t:.9g} s"
                        break
                elif t >= self.T:
                    break
                x, phase = self.decide(t, x, phase, fired if sol.status == 1 else [])
                self.record(np.array([t]), x[None, :], phase)
        except _Painleve as error:
            status, message = SimulationStatus.PAINLEVE, str(error)
        except _BudgetExceeded:
            status = SimulationStatus.MAX_RHS_EVALUATIONS
            message = f"stopped after {opt.max_rhs_evaluations} model evaluations"
        except np.linalg.LinAlgError as error:
            # a trial step into states the model cannot evaluate (non-finite): a failed
            # simulation, not an error of the verification (bolt on a step: SVD of the
            # contact rows did not converge in a restart)
            status = SimulationStatus.INTEGRATION_FAILED
            message = (f"the contact equations could not be solved near t = "
                       f"{self.t_now:.9g} s ({error})")
        message = f"{message} ({status.hint})" if status != SimulationStatus.SUCCESS \
            else message
        return MultiContactSimulation(
            t=np.concatenate(self.ts), x=np.concatenate(self.xs),
            normal_forces=np.concatenate(self.fn), tangential_forces=np.concatenate(self.ft),
            events=tuple(self.events), impacts=tuple(self.impacts), modes=tuple(self.modes),
            status=status, message=message, n_rhs=model.calls, max_gap_drift=self.drift,
            max_velocity_projection=self.projection)


def replay_multicontact(
    cls: ComplementarityLagrangianSystem,
    x0: np.ndarray,
    clocks: np.ndarray,
    controls: np.ndarray,
    T: float,
    *,
    options: MultiContactOptions | None = None,
) -> MultiContactSimulation:
    """`simulate_multicontact` with piecewise constant controls.

    Args:
        cls, x0, T, options: as for `simulate_multicontact`.
        clocks: times of the control-interval boundaries [s], (N + 1,); each is a
            breakpoint (so the samples include it).
        controls: (N, n_u); controls[k] acts from clocks[k] on (the last also after
            clocks[N]).
    """
    clocks = np.asarray(clocks, dtype=float).ravel()
    controls = np.atleast_2d(np.asarray(controls, dtype=float))
    if controls.shape[0] != len(clocks) - 1:
        raise InvalidInput(f"`controls` has {controls.shape[0]} rows for {len(clocks)} "
                           "clock values: give one control per interval")
    boundaries = clocks.tolist()
    last = len(controls) - 1

    def u_of_t(t: float) -> np.ndarray:
        return controls[min(max(bisect.bisect_right(boundaries, t) - 1, 0), last)]

    return simulate_multicontact(cls, x0, u_of_t if controls.shape[1] else None, T,
                                 options=options, breakpoints=clocks[1:])


def stopped_replay(sim: MultiContactSimulation, plan: ReplayedPlan,
                   replay_to: ReplayTo) -> StoppedReplay:
    """What `end_state_check` reads of `sim`, an open-loop replay of `plan` that stopped:
    its deviation from the plan and its state at each control-interval boundary before
    its stop (an impact within `LOCAL_DEFECT_IMPACT_WINDOW` of an interval of a boundary
    counts on either side of it); `replay_to` replays from another start."""
    stop = float(sim.t[-1]) if sim.t.size else 0.0
    reached = np.flatnonzero(plan.clocks < stop) if sim.t.size else np.zeros(0, dtype=int)
    window = LOCAL_DEFECT_IMPACT_WINDOW * plan.horizon / (len(plan.clocks) - 1)
    # a time-freezing plan's clock may start a round-off before 0
    times = np.maximum(plan.clocks[reached], sim.t[0]) if sim.t.size else []
    deviations = np.array([sim.deviation_at(t, plan.states[k], window)
                           for t, k in zip(times, reached, strict=True)])
    states = np.array([sim.state_at(t) for t in times]
                      ).reshape(len(reached), plan.states.shape[1])
    return StoppedReplay(stop, deviations, states, replay_to)


__all__ = [
    "ContactEvent",
    "ContactImpact",
    "ContactMode",
    "EventKind",
    "MultiContactOptions",
    "MultiContactSimulation",
    "SimulationStatus",
    "multicontact_local_defects",
    "replay_multicontact",
    "simulate_multicontact",
    "stopped_replay",
]


class EvaluationBudget:
    """Model evaluations shared by several simulations (a verification's open-loop replay
    and its local-defect restarts): each runs with at most what is left, and a restart
    after the budget is used up is not run (`skipped`). A chattering plan otherwise
    spends the simulator's own cap in every restart (measured on a failed solo12 jump:
    83 s per restart, 12 restarts)."""

    def __init__(self, evaluations: int) -> None:
        self.total = positive_int(evaluations, "budget")
        self.remaining = self.total
        self.skipped = 0

    @property
    def exhausted(self) -> bool:
        return self.remaining <= 0

    def options(self, options: MultiContactOptions) -> MultiContactOptions:
        """`options` with at most the evaluations left."""
        return replace(options, max_rhs_evaluations=max(1, min(options.max_rhs_evaluations,
                                                                self.remaining)))

    def spend(self, evaluations: int) -> None:
        self.remaining -= evaluations


def multicontact_local_defects(plan: ReplayedPlan, segments: list[tuple[int, int]],
                               gap_tolerance: float,
                               options: MultiContactOptions | None = None,
                               budget: EvaluationBudget | None = None
                               ) -> tuple[float, ...]:
    """`tfcontact.verify.local_defects` with this simulator: per control interval, the
    deviation (inf norm) at its end of `simulate_multicontact` restarted from the plan's
    own state at its segment's start (`defect_segments`) and run with the plan's
    piecewise constant controls; nan where the segment runs on, inf where the simulation
    did not succeed (Painleve, event cap, a start it rejects).

    Args:
        plan: the plan as arrays (`ReplayedPlan`); its CLS may have several frictional
            contacts (all inelastic).
        segments: (first, last + 1) control intervals of each restart (`defect_segments`).
        gap_tolerance: a restart may lie this far inside an obstacle [m].
        options: `MultiContactOptions` (default: defaults with `start_gap_tolerance` =
            gap_tolerance).
        budget: model evaluations shared with other simulations (`EvaluationBudget`);
            a restart after it is used up is not run, its defect inf.
    """
    if options is None:
        options = MultiContactOptions(start_gap_tolerance=max(gap_tolerance, 1e-12))
    clocks, states = plan.clocks, plan.states
    defects = np.full(len(clocks) - 1, np.nan)
    for first, end in segments:
        duration = float(clocks[end] - clocks[first])
        if duration <= 1e-12:
            continue  # frozen throughout: nothing physical to compare
        # Run a little past the end, so that an impact the plan puts on the boundary and
        # the simulation just after it is compared on both sides.
        window = LOCAL_DEFECT_IMPACT_WINDOW * duration / (end - first)
        if budget is not None and budget.exhausted:
            budget.skipped += 1
            defects[end - 1] = np.inf
            continue
        try:
            local = replay_multicontact(plan.cls, states[first],
                                        clocks[first:end + 1] - clocks[first],
                                        plan.controls[first:end], duration + window,
                                        options=options if budget is None
                                        else budget.options(options))
        except TfcontactError:
            local = None
        if budget is not None and local is not None:
            budget.spend(local.n_rhs)
        if local is None or not local.success:
            defects[end - 1] = np.inf
            continue
        defects[end - 1] = local.deviation_at(duration, states[end], window)
    return tuple(float(d) for d in defects)
