"""The exact re-solve ("polish") of a contact plan along a fixed contact sequence.

The homotopy of `solve_contact` discovers when a contact closes, slips and opens; its
relaxed plan may hover above the ground while it pushes, sink into it, or cross a fast
flight with a coarse element. `polish_contact` keeps a sequence
of phases and re-solves the OCP as a smooth NLP with the original system's dynamics:

* stick: M a = f + n lambda_n + B lambda_t with n^T a + (dn/dt)^T v = -(2 alpha v_n +
  alpha^2 gap) and B^T a + (dB/dt)^T v = -alpha v_t (index-reduced, Baumgarte
  stabilised); lambda_n >= 0, |lambda_t| <= c mu lambda_n;
* slip with sign s ("slip+", "slip-"): M a = f + (n - s mu B) lambda_n, the same normal
  row; lambda_n >= 0, s v_t >= 0, W_nn - s mu W_nt >= 1e-2 (a unique normal force);
* flight: M a = f, gap >= 0;
* stick -> slip where lambda_t = -s mu lambda_n; slip -> flight where lambda_n = 0;
  stick -> flight only at a control jump k T / N, where the new control's free normal
  acceleration n^T M^-1 f + (dn/dt)^T v >= 0 (inside an interval, lambda_n = 0 with the
  cone row at the same node would force lambda_t = 0 too); inside a contact phase the
  contact rows hold with both controls at each control jump;
* touchdown into stick: gap = 0 and the reference's impulse flow stopping the slip before
  the normal velocity (|v_t| r_n <= -v_n r_t, r_n = W_nn - s mu W_nt, r_t = mu W_tt -
  s W_tn, then |W_tn| <= mu W_tt); the post-impact state has J v+ = 0.

Controls are piecewise constant on the fixed grid k T / N; each control interval is cut at
the switches inside it and every piece integrated by RK4 (`substeps` shooting nodes per
interval, `steps_per_node` RK4 steps between two, nodes at most 1.5 T / (N substeps)
apart), multiple shooting; or (`integrator="radau"`) by Radau IIA collocation, `substeps`
elements per interval, each stage state a node: FESD with the active set fixed, the
switches at element boundaries. Optional Painleve margin
W_nn -+ mu W_nt >= delta at contact nodes. The result is checked like a time-freezing plan
(replay, local defects, kicked sensitivity).

Tested: the dynamics and touchdown rows against closed forms and the reference's impulse
flow (tests/test_ocp_polish.py); the solves in tests/test_monoped_exact.py. The solves
are fragile (benchmarks/monoped_settings.md): writing the grid as linspace or the
touchdown rows as "expression >= 0" (equal up to round-off) moved one of them from 472
iterations to the 3000 cap. It handles one frictional planar contact (the monoped's foot).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, TfcontactError, positive_int
from tfcontact.fesd.tableau import RadauIIA
from tfcontact.ocp.contact import ContactProblem, ContactResult
from tfcontact.ocp.nodes import (
    NlpTiming,
    NodeFunctions,
    RepeatedRows,
    bound_violation,
    bounded_rows,
    collocation_function,
    collocation_residuals,
    interpolate,
    ipopt_solver,
    report_progress,
    shooting_function,
    solve_timed,
    spd_solve,
    system_states,
)
from tfcontact.verify import (
    LOCAL_DEFECT_IMPACT_WINDOW,
    ReplayedPlan,
    Verification,
    VerifyOptions,
    end_state_check,
    friction_cone_violation,
    local_defects,
    reference_deviation,
    state_indices,
)

STICK, FLIGHT = "stick", "flight"
CLOCK_TOLERANCE = 1e-9
"""A plan's last node may differ from the horizon by this fraction of it (round-off)."""
TRANSITIONS = {(STICK, "slip+"), (STICK, "slip-"), ("slip+", FLIGHT), ("slip-", FLIGHT),
               (FLIGHT, STICK), (STICK, FLIGHT)}
"""The phase changes the re-solve models. Inside a control interval a foot lifts off
through slip: straight from stick, lambda_n = 0 with the cone row at the same node would
force lambda_t = 0 too, and the exact dynamics do not give that. Straight from stick it
lifts off at a control jump (a grid point k T / N): the new control's free normal
acceleration n^T M^-1 f + (dn/dt)^T v >= 0 opens the contact."""


@dataclass(frozen=True)
class PolishOptions:
    """Settings of `polish_contact`.

    Args:
        substeps: shooting nodes per control interval (a piece of an interval gets its
            share, at least 2), or a tuple of one count per interval (a mesh refined
            where the local defects are large, `refined_substeps`).
        steps_per_node: RK4 steps from one node to the next (more accuracy without more
            variables).
        integrator: "rk4" (explicit RK4 multiple shooting) or "radau": Radau IIA
            collocation with `radau_stages` stages (order 2 s - 1), `substeps` finite
            elements per control interval, the stage states variables constrained like
            the nodes (FESD on a fixed active set: the switches sit at element
            boundaries, their times free).
        radau_stages: stages of the Radau IIA elements (3: order 5, TF-9's).
        expand: expand the whole NLP into one SX graph (fast per iteration; the full task
            with 16 x 4 RK4 steps took more than 16 GB to build). False: each RK4 step is
            one SX function called from an MX graph (small, slower per iteration).
        element_derivatives: differentiate each shooting step's (each collocation
            element's) equations once per mode and step length and scatter them
            (`tfcontact.ocp.nodes.RepeatedRows`) instead of letting CasADi differentiate
            every inlined copy; likewise the contact's rows at the nodes and the path rows
            (unless they depend on the time). A piece whose length a switch time sets gets
            its step length as a variable, and the node states enter the running cost as
            variables (the same values at a solution). Off by default: round-off
            differs, and the re-solves' IPOPT paths depend on it (the pipeline's exact
            re-solve, `tfcontact.scenes.pipeline.ExactResolve`, turns it on).
        threads: threads that evaluate the element derivatives (CasADi's thread map).
        ldl: solve with M(q) and the contact's Delassus matrix by their LDL^T (no
            pivoting: both are positive definite) instead of CasADi's symbolic QR; the
            monoped's two-step RK4 shooting Hessian takes 147k instead of 306k
            instructions in stick. Off by default (another IPOPT path).
        painleve_margin: at every contact node W_nn -+ mu W_nt >= this [1/kg] (0: no
            rows): the contact stays away from the Painleve region.
        touchdown_rate: at each touchdown the impulse flow's normal rate
            r_n = W_nn - s mu W_nt >= this fraction of W_nn (`touchdown_rows`; 0: only
            r_n >= 1e-3 [1/kg]). Near r_n = 0 a landing of vanishing normal velocity stops
            any sliding, and an optimiser drawn there lands grazing: the monoped over
            terrain holes landed at v_n = -0.012 m/s with v_t = 4.4 m/s and r_n at 1e-3,
            and the exact replay missed the ground (benchmarks/monoped_bench.md). TF-9's
            verified landings have r_n / W_nn = 0.04-0.05.
        cone_margins: the continuation of the stick cone |lambda_t| <= c mu lambda_n, each
            NLP warm started from the last. With a slip phase only c = 1: the stick force
            reaches the cone's edge where the slip starts.
        flight_gap: a relaxed plan's contact counts as open above this gap [m] ...
        contact_gap: ... and as closed again below this one [m].
        switch_margin: phase switches keep this fraction of a control interval from its
            boundaries (no zero-length pieces).
        tol, max_iter: IPOPT's.
        blas_threads: threads of IPOPT's BLAS during the solve (`tfcontact.native.
            blas_threads`, restored after; None: as
            set). The measured chains ran with 2 (the default on a 2-core machine).
        lift_offs_at_control_jumps: `contact_phases` moves each lift-off straight from
            stick to the nearest control jump k T / N, where the re-solve can model it
            (else such a lift-off needs a slip phase before it).
        end_state_tolerance, gap_tolerance, cone_tolerance: the verification's.
        terminal_tolerance: the largest violation of the problem's terminal constraint at
            the plan's end that the verification passes (the NLP may leave terminal
            equalities to the last phase's dynamics, `terminal_rows_not_held`).
    """

    substeps: int | tuple[int, ...] = 16
    steps_per_node: int = 1
    integrator: str = "rk4"
    radau_stages: int = 3
    expand: bool = True
    element_derivatives: bool = False
    threads: int = 1
    ldl: bool = False
    baumgarte: float = 20.0
    painleve_margin: float = 0.05
    touchdown_rate: float = 0.0
    cone_margins: tuple[float, ...] = (1.0,)
    flight_gap: float = 5e-3
    contact_gap: float = 1e-3
    switch_margin: float = 1e-3
    tol: float = 1e-9
    max_iter: int = 3000
    blas_threads: int | None = 2
    lift_offs_at_control_jumps: bool = False
    # the verification's tolerances of a time-freezing plan
    end_state_tolerance: float = VerifyOptions.end_state_tolerance
    gap_tolerance: float = VerifyOptions.gap_tolerance
    cone_tolerance: float = VerifyOptions.cone_tolerance
    terminal_tolerance: float = 1e-6

    def __post_init__(self) -> None:
        if isinstance(self.substeps, tuple):
            if not self.substeps:
                raise InvalidInput("`substeps` is an empty tuple")
            for n in self.substeps:
                positive_int(n, "substeps")
        else:
            positive_int(self.substeps, "substeps")
        positive_int(self.steps_per_node, "steps_per_node")
        positive_int(self.max_iter, "max_iter")
        positive_int(self.radau_stages, "radau_stages")
        positive_int(self.threads, "threads")
        for name in ("expand", "element_derivatives", "ldl"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInput(f"`{name}` must be True or False, got "
                                   f"{getattr(self, name)!r}")
        if self.integrator not in ("rk4", "radau"):
            raise InvalidInput(f"`integrator` must be 'rk4' or 'radau', got {self.integrator!r}")
        if self.integrator == "radau" and self.steps_per_node != 1:
            raise InvalidInput("`steps_per_node` is RK4's; with integrator='radau' the "
                               "elements per interval are `substeps`")
        if self.blas_threads is not None:
            positive_int(self.blas_threads, "blas_threads")
        if not isinstance(self.lift_offs_at_control_jumps, bool):
            raise InvalidInput(f"`lift_offs_at_control_jumps` must be True or False, got "
                               f"{self.lift_offs_at_control_jumps!r}")
        if not self.cone_margins or not all(0 < c <= 1 for c in self.cone_margins):
            raise InvalidInput(f"`cone_margins` must be numbers in (0, 1], got "
                               f"{self.cone_margins!r}")
        if not 0 < self.contact_gap < self.flight_gap:
            raise InvalidInput(f"need 0 < contact_gap < flight_gap, got {self.contact_gap}, "
                               f"{self.flight_gap}")
        if not 0 < self.switch_margin < 0.5:
            raise InvalidInput(f"`switch_margin` must lie in (0, 0.5), got "
                               f"{self.switch_margin}")
        for name in ("tol", "end_state_tolerance", "gap_tolerance", "cone_tolerance",
                     "terminal_tolerance"):
            if not getattr(self, name) > 0:
                raise InvalidInput(f"`{name}` must be positive, got {getattr(self, name)}")
        if not 0 <= self.touchdown_rate < 1:
            raise InvalidInput(f"`touchdown_rate` must lie in [0, 1) (a fraction of W_nn), "
                               f"got {self.touchdown_rate}")

    def substeps_per_interval(self, n_intervals: int) -> tuple[int, ...]:
        """`substeps` for each of `n_intervals` control intervals."""
        if not isinstance(self.substeps, tuple):
            return (self.substeps,) * n_intervals
        if len(self.substeps) != n_intervals:
            raise InvalidInput(f"`substeps` gives {len(self.substeps)} counts for "
                               f"{n_intervals} control intervals")
        return self.substeps


def refined_substeps(substeps: tuple[int, ...], local_defects, tolerance: float,
                     factor: int = 2) -> tuple[int, ...]:
    """A mesh refined where a plan's local defects exceed their share of the tolerance:
    `factor` x the elements of each interval whose defect exceeds tolerance / N (or that
    the reference could not replay, nan), the others kept. The defects then sum to within
    the tolerance once each interval is within its share."""
    defects = np.asarray(local_defects, dtype=float)
    if defects.shape != (len(substeps),):
        raise InvalidInput(f"{defects.size} local defects for {len(substeps)} intervals")
    share = tolerance / len(substeps)
    return tuple(int(n * factor) if not d <= share else int(n)
                 for n, d in zip(substeps, defects, strict=True))


@dataclass(frozen=True)
class Phase:
    """One phase of a contact sequence: `mode` ("stick", "slip+", "slip-" or "flight") from
    `start` to `end` [s]."""

    mode: str
    start: float
    end: float


@dataclass(frozen=True, eq=False)
class PolishedPlan:
    """A plan with the exact hybrid dynamics along a fixed contact sequence.

    Attributes:
        phases: the contact sequence with the polished switch times.
        t, x: the nodes' physical times [s] and states (q, v), (n_nodes, 2 n_q) (RK4: the
            shooting nodes; Radau: every stage point);
            a touchdown has two nodes at its time (before and after the impact).
        u: physical controls per interval, (N, n_u).
        boundary_states: (q, v) at the control-interval boundaries, (N + 1, 2 n_q).
        contact_forces: (lambda_n, lambda_t) [N] at the stick nodes, (n, 2).
        impact_impulses: (Lambda_n, Lambda_t) [N s] per touchdown, (n, 2).
        cost: the objective.
        ipopt_status: IPOPT's return status of the last NLP; iterations: over all NLPs.
        solve_time: seconds (build and solves); verification: the independent checks.
        integrator, substeps: the options' integrator and nodes or elements per interval.
        timing: where the solve's time went and the NLP's size (None: not measured).
    """

    phases: tuple[Phase, ...]
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    boundary_states: np.ndarray
    contact_forces: np.ndarray
    impact_impulses: np.ndarray
    cost: float
    ipopt_status: str
    iterations: int
    solve_time: float
    verification: Verification
    history: tuple[tuple[float, str, int], ...] = field(default=())
    integrator: str = "rk4"
    substeps: tuple[int, ...] = ()
    timing: NlpTiming | None = None

    @property
    def solved(self) -> bool:
        return self.ipopt_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")

    @property
    def status(self) -> str:
        if not self.solved:
            return "nlp_failed"
        return "converged" if self.verification.passed else "verification_failed"

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def summary(self) -> str:
        switches = ", ".join(f"{p.mode} {p.start:.4f}-{p.end:.4f} s" for p in self.phases)
        steps = "; ".join(f"c = {c:g}: {s}, {n} it." for c, s, n in self.history)
        return "\n".join([
            (f"polish: {self.status} (IPOPT {self.ipopt_status}, {self.iterations} "
             f"iterations, {self.solve_time:.1f} s; {steps})"),
            f"polish: {self.integrator}, {_mesh(self.substeps, self.integrator)} per control "
            "interval",
            f"polish: objective {self.cost:.6g}; phases {switches}",
            *([] if self.timing is None else [f"polish: {self.timing.summary()}"]),
            f"polish: {self.verification.summary()}",
        ])


def _mesh(substeps: tuple[int, ...], integrator: str) -> str:
    unit = "elements" if integrator == "radau" else "nodes"
    if len(set(substeps)) <= 1:
        return f"{substeps[0] if substeps else '?'} {unit}"
    return f"{unit} " + " ".join(str(n) for n in substeps)


def contact_phases(result: ContactResult, options: PolishOptions | None = None
                   ) -> tuple[Phase, ...]:
    """The stick and flight phases of a time-freezing plan: stick while the gap stays below
    `flight_gap`, flight from the last sample before it rises above it until it falls
    below `contact_gap` again (one contact). For `polish_contact` a lift-off needs a slip
    phase before it or a start at a control jump (see `TRANSITIONS`;
    `PolishOptions.lift_offs_at_control_jumps` moves it to the nearest one)."""
    options = options or PolishOptions()
    system = result.physical.system
    cls = system.cls
    _check_system(cls)
    t = result.physical.t
    gaps = np.asarray(cls.function("gaps")(result.physical.y[:, system.q_index].T)).ravel()
    horizon = result.problem.horizon
    if gaps[0] > options.contact_gap:
        raise InvalidInput(f"the plan starts with its contact open (gap {gaps[0]:.3g} m); "
                           "the polish starts in stick")
    modes, starts = [STICK], [0.0]
    for k in range(1, len(t)):
        if modes[-1] == STICK and gaps[k] > options.flight_gap:
            modes.append(FLIGHT)
            starts.append(float(t[k - 1]))
        elif modes[-1] == FLIGHT and gaps[k] < options.contact_gap and t[k] < horizon - 1e-9:
            modes.append(STICK)
            starts.append(float(t[k]))
    if options.lift_offs_at_control_jumps:
        # A lift-off straight from stick needs a control jump (`TRANSITIONS`): the nearest
        # one k T / N, if it keeps the phases in order.
        step = horizon / result.problem.n_intervals
        for i in range(1, len(modes)):
            snapped = round(starts[i] / step) * step
            upper = starts[i + 1] if i + 1 < len(starts) else horizon
            if modes[i] == FLIGHT and modes[i - 1] == STICK and starts[i - 1] < snapped < upper:
                starts[i] = float(snapped)
    ends = starts[1:] + [horizon]
    return tuple(Phase(m, s, e) for m, s, e in zip(modes, starts, ends, strict=True))


def _check_system(cls) -> None:
    if cls.n_contacts != 1:
        raise InvalidInput(f"the polish handles one contact, the system has {cls.n_contacts}")
    contact = cls.contacts[0]
    if not contact.has_friction or contact.n_tangents != 1:
        raise InvalidInput("the polish handles one frictional planar contact (one tangent "
                           f"direction); contact {contact.name!r} has {contact.n_tangents}")


class HybridDynamics:
    """The hybrid system's CasADi functions in x = (q, v) and u, for one frictional planar
    contact: `rhs[mode]` (stick with Baumgarte gain `alpha` [1/s], "slip+", "slip-",
    flight), the stick `force` (lambda_n, lambda_t) [N], `slip_force[mode]` (lambda_n,
    W_nn - s mu W_nt), `free_normal`, `gap`, `velocity` (v_n, v_t), `delassus` and
    `impact` (the post-impact state with J v+ = 0 and its impulse [N s]); `rk4` and
    `step` integrate a mode."""

    def __init__(self, cls, alpha: float = 20.0, *, ldl: bool = False) -> None:
        q, v, u = cls.q, cls.v, cls.u
        # M(q)'s sparse LDL^T and the Delassus matrix's: about half QR's derivatives
        solve_delassus = spd_solve if ldl else ca.solve
        contact = cls.contacts[0]
        jac = ca.horzcat(contact.normal, contact.tangents)  # J = [n B], (n_v, 2)
        drift = ca.jacobian(ca.mtimes(jac.T, v), q) @ v  # (dJ/dt)^T v
        vel = ca.mtimes(jac.T, v)
        # Baumgarte: the contact's drift off gap = 0, v_n = 0 (and v_t = 0 in stick) decays
        stab = ca.vertcat(2 * alpha * vel[0] + alpha**2 * contact.gap, alpha * vel[1])
        if ldl:
            minv_f, minv_j = cls.solve_mass(cls.forces), cls.solve_mass(jac)
        else:
            minv_f = ca.solve(cls.mass_matrix, cls.forces)
            minv_j = ca.solve(cls.mass_matrix, jac)
        delassus = ca.mtimes(jac.T, minv_j)
        lam = solve_delassus(delassus, -(ca.mtimes(jac.T, minv_f) + drift + stab))
        x = ca.vertcat(q, v)
        self.mu = contact.mu
        self.rhs = {STICK: ca.Function("stick", [x, u], [ca.vertcat(v, minv_f + minv_j @ lam)]),
                    FLIGHT: ca.Function("flight", [x, u], [ca.vertcat(v, minv_f)])}
        self.slip_force = {}
        for name, sign in (("slip+", 1.0), ("slip-", -1.0)):
            direction = ca.vertcat(1.0, -sign * self.mu)  # (lambda_n, lambda_t) / lambda_n
            rate = ca.mtimes(delassus[0, :], direction)  # W_nn - s mu W_nt
            lam_n = -(ca.mtimes(jac[:, 0].T, minv_f) + drift[0] + stab[0]) / rate
            a = minv_f + minv_j @ direction * lam_n
            fname = "slip_pos" if sign > 0 else "slip_neg"
            self.rhs[name] = ca.Function(fname, [x, u], [ca.vertcat(v, a)])
            self.slip_force[name] = ca.Function(fname + "_force", [x, u], [lam_n, rate])
        self.force = ca.Function("force", [x, u], [lam])
        # the contact's normal acceleration without contact force (>= 0: it opens)
        self.free_normal = ca.Function(
            "free_normal", [x, u], [ca.mtimes(jac[:, 0].T, minv_f) + drift[0]])
        self.gap = ca.Function("gap", [x], [contact.gap])
        self.velocity = ca.Function("velocity", [x], [vel])  # (v_n, v_t)
        # x -> what each mode's dynamics keep from the mode's start: the gap and the
        # normal velocity in contact, and the tangential velocity too in stick
        held = {STICK: ca.vertcat(contact.gap, vel), "slip+": ca.vertcat(contact.gap, vel[0]),
                "slip-": ca.vertcat(contact.gap, vel[0]), FLIGHT: ca.SX(0, 1)}
        self.held = {mode: ca.Function("held", [x], [value]) for mode, value in held.items()}
        self.delassus = ca.Function("delassus", [x], [delassus])
        impulse = -solve_delassus(delassus, vel)
        self.impact = ca.Function("impact", [x], [ca.vertcat(q, v + minv_j @ impulse), impulse])
        self._rk4: dict = {}

    def rk4(self, mode: str, steps: int) -> ca.Function:
        """`steps` RK4 steps of length h / steps as one SX function (x, u, h) -> x+."""
        key = (mode, steps)
        if key not in self._rk4:
            x = ca.SX.sym("x", self.rhs[mode].size1_in(0))
            u = ca.SX.sym("u", self.rhs[mode].size1_in(1))
            h = ca.SX.sym("h")
            end = x
            for _ in range(steps):
                end = self.step(mode, end, u, h / steps)
            self._rk4[key] = ca.Function(f"rk4_{mode.replace('+', 'p').replace('-', 'm')}"
                                         f"_{steps}", [x, u, h], [end])
        return self._rk4[key]

    def shooting(self, mode: str, steps: int) -> ca.Function:
        """`shooting_function` of `rk4(mode, steps)`, built once."""
        key = ("shooting", mode, steps)
        if key not in self._rk4:
            self._rk4[key] = shooting_function(self.rk4(mode, steps),
                                               f"shooting_{len(self._rk4)}")
        return self._rk4[key]

    def collocation(self, mode: str, tableau) -> ca.Function:
        """`collocation_function` of `rhs[mode]`, built once."""
        key = ("collocation", mode, tableau.stages)
        if key not in self._rk4:
            self._rk4[key] = collocation_function(self.rhs[mode], tableau,
                                                  f"collocation_{len(self._rk4)}")
        return self._rk4[key]

    def step(self, mode: str, x, u, h):
        f = self.rhs[mode]
        k1 = f(x, u)
        k2 = f(x + h / 2 * k1, u)
        k3 = f(x + h / 2 * k2, u)
        k4 = f(x + h * k3, u)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def terminal_rows_not_held(terminal: ca.Function, held: ca.Function,
                           x_end: np.ndarray) -> np.ndarray:
    """Rows P (orthonormal, m' x m) of the m terminal equalities c(x_T) = b to impose as
    P (c(x_T) - b) = 0: the combinations of them the final phase's dynamics do not hold
    already. A contact that ends the plan closed keeps its gap (and its velocity) from
    its touchdown or the start: where c = b also fixes the gap (the monoped's q(T) = goal
    standing), asking it again makes the rows dependent, and IPOPT's multipliers grow with
    the mesh (4e11 measured on the refined monoped; the collocation holds the gap to its
    drift). Each held quantity whose gradient at `x_end` lies in the span of c's is
    dropped from c; the verification still checks the whole terminal constraint at the
    plan's end (`PolishOptions.terminal_tolerance`)."""
    x = ca.SX.sym("x", terminal.size1_in(0))
    jac_c = np.atleast_2d(np.asarray(ca.Function("jac_c", [x], [ca.jacobian(terminal(x), x)])(
        x_end)))
    jac_h = np.atleast_2d(np.asarray(ca.Function("jac_h", [x], [ca.jacobian(held(x), x)])(
        x_end)))
    implied = []
    for h in jac_h if held.numel_out(0) else ():
        w = np.linalg.lstsq(jac_c.T, h, rcond=None)[0]
        if np.linalg.norm(jac_c.T @ w - h) <= 1e-9 * max(np.linalg.norm(h), 1.0):
            implied.append(w)  # c = b implies this held quantity's value (to first order)
    m = jac_c.shape[0]
    if not implied:
        return np.eye(m)
    basis, singular, _ = np.linalg.svd(np.array(implied).T)
    rank = int(np.sum(singular > 1e-9 * singular[0]))
    return basis[:, rank:].T


def touchdown_rows(w, v_n, v_t, sign: float, mu, cone_margin=1.0,
                   rate: float = 0.0) -> list[tuple]:
    """Pairs (a, b), each meaning a >= b, under which an inelastic planar impact with
    Delassus matrix w and contact velocities (v_n < 0, v_t) ends in stick, by the
    reference's impulse flow (`tfcontact.verify.reference`): slip at
    lambda_t = -s mu lambda_n (s the sign of v_t) until v_t stops, before v_n does; then
    stick. With the rates r_n = W_nn - s mu W_nt > 0 and r_t = s (s mu W_tt - W_tn) > 0 of
    v_n and |v_t| per unit lambda_n: |v_t| r_n <= -v_n r_t, and |W_tn| <= mu W_tt for the
    stick that follows. Inside the Painleve region (r_n <= 0) the flow also ends in stick
    (the slip always stops there); r_n, r_t >= 1e-3 leave those landings out, and with
    `rate` > 0 a last row r_n >= rate W_nn keeps the landing that far from them. Numbers or
    CasADi expressions. (Written as the measured runs wrote them: an algebraically equal
    rewrite moved IPOPT's path to the iteration cap.)"""
    rate_n = w[0, 0] - sign * mu * w[0, 1]
    rate_t = sign * (sign * mu * w[1, 1] - w[1, 0])
    return [(sign * v_t, 0), (rate_n, 1e-3), (rate_t, 1e-3),
            (-v_n * rate_t, sign * v_t * rate_n),
            (cone_margin * mu * w[1, 1] - w[1, 0], 0), (cone_margin * mu * w[1, 1] + w[1, 0], 0),
            *([(rate_n, rate * w[0, 0])] if rate > 0 else [])]


def guess_from_result(result: ContactResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, u) of a time-freezing plan as a guess of `polish_contact`: its physical
    trajectory's times and states x = (q, v) (frozen pieces dropped) and its controls."""
    phys = result.physical
    return phys.t, phys.y[:, state_indices(result.system)], result.u


def polish_contact(problem: ContactProblem, phases: tuple[Phase, ...],
                   options: PolishOptions | None = None, *,
                   guess: ContactResult | tuple[np.ndarray, np.ndarray, np.ndarray],
                   verbose: bool = True) -> PolishedPlan:
    """Re-solve a contact OCP along a contact sequence with the exact hybrid dynamics
    (module docstring), warm started from a guess, and verify the plan.

    Args:
        problem: the `ContactProblem` (its time-freezing system supplies the hybrid
            dynamics; its bounds, path and terminal constraints and cost are kept).
        phases: the contact sequence, starting in stick, its changes in `TRANSITIONS`.
        options: `PolishOptions`.
        guess: a time-freezing plan (`ContactResult`, converged or not), or (t, x, u) of
            an earlier polished plan: node times [s], states (n, 2 n_q), controls (N, n_u).
        verbose: print one line per NLP (and the most violated rows of a failed one) and
            the summary.

    Returns:
        A `PolishedPlan`; `success` only if IPOPT solved the last NLP and the plan passed
        the checks.
    """
    phases = tuple(phases)
    if phases[0].mode != STICK:
        raise InvalidInput(f"the phases must start in stick, got {phases[0].mode!r}")
    for before, after in itertools.pairwise(phases):
        if (before.mode, after.mode) not in TRANSITIONS:
            raise InvalidInput(f"no {before.mode!r} -> {after.mode!r} change at "
                               f"{after.start:.4g} s: the re-solve models {sorted(TRANSITIONS)}"
                               " (a foot lifts off through slip)")
    options = options or PolishOptions()
    system = problem.system
    cls = system.cls
    _check_system(cls)
    dyn = HybridDynamics(cls, options.baumgarte, ldl=options.ldl)
    radau = options.integrator == "radau"
    tableau = RadauIIA(options.radau_stages).tableau() if radau else None
    n_q, n_u = cls.n_q, cls.n_u
    n_int, horizon = problem.n_intervals, problem.horizon
    dt = horizon / n_int
    for before, after in itertools.pairwise(phases):
        on_grid = abs(after.start / dt - round(after.start / dt)) < 1e-9
        if (before.mode, after.mode) == (STICK, FLIGHT) and not (
                on_grid and 0 < round(after.start / dt) < n_int):
            raise InvalidInput(f"a lift-off straight from stick (at {after.start:.4g} s) must be "
                               f"at a control jump k T / N (T / N = {dt:g} s); inside an "
                               "interval the foot lifts off through slip")
    substeps = options.substeps_per_interval(n_int)
    start = time.perf_counter()

    if isinstance(guess, ContactResult):
        guess = guess_from_result(guess)
    if not (isinstance(guess, tuple) and len(guess) == 3):
        raise InvalidInput("`guess` must be a ContactResult or a tuple (t, x, u) of node "
                           f"times, states and controls, got {type(guess).__name__}")
    guess_t, guess_x, guess_u = guess
    functions = NodeFunctions.of(problem)
    y_of, path, path_fn = functions.y_of, functions.path, functions.path_fn
    running, terminal_cost = functions.running, functions.terminal_cost
    terminal, terminal_fn = functions.terminal, functions.terminal_fn

    opti = ca.Opti()
    repeated = RepeatedRows(opti) if options.element_derivatives else None
    controls = opti.variable(n_int, n_u) if n_u else ca.MX(n_int, 0)
    margin = opti.parameter()
    if n_u:
        opti.subject_to(opti.bounded(np.tile(problem.u_lower, (n_int, 1)), controls,
                                     np.tile(problem.u_upper, (n_int, 1))))
        opti.set_initial(controls, np.clip(guess_u, problem.u_lower, problem.u_upper))
    # The control grid is fixed, k T / N (a restriction where the time-freezing OCP fixes
    # only t(T) = T: free durations let RK4 take long steps, and the optimiser used their
    # error). The switch times are kept inside the control interval their guess lies in.
    grid = [k * dt for k in range(n_int + 1)]
    grid_guess = np.array(grid)
    switches = []
    switch_interval = []
    fractions = []
    grid_lift_offs = {}  # control interval k -> index j in phases[1:] of a flight from k T / N
    for j, (before, phase) in enumerate(itertools.pairwise(phases)):
        if (before.mode, phase.mode) == (STICK, FLIGHT):
            k = round(phase.start / dt)
            grid_lift_offs[k] = j
            switches.append((grid[k], grid_guess[k]))  # fixed: no switch variable
            switch_interval.append(-1)
            fractions.append(None)
            continue
        k = int(np.clip(np.searchsorted(grid_guess, phase.start, side="right") - 1, 0, n_int - 1))
        fraction = opti.variable()
        m = options.switch_margin
        f_guess = float(np.clip((phase.start - grid_guess[k])
                                / (grid_guess[k + 1] - grid_guess[k]), m, 1 - m))
        opti.subject_to(opti.bounded(m, fraction, 1 - m))
        opti.set_initial(fraction, f_guess)
        if switch_interval and switch_interval[-1] == k:  # two switches in one interval: in order
            opti.subject_to(fraction - fractions[-1] >= m)
        fractions.append(fraction)
        s = grid[k] + fraction * (grid[k + 1] - grid[k])
        switches.append((s, grid_guess[k] + f_guess * (grid_guess[k + 1] - grid_guess[k])))
        switch_interval.append(k)

    # The slip sign of each touchdown, from the guess's tangential velocity just before it.
    touchdown_signs = {}
    for j, phase in enumerate(phases[1:]):
        if phase.mode == STICK and phases[j].mode == FLIGHT:
            before = interpolate(guess_t, guess_x, max(phase.start - 1e-3, 0.0))
            v_t = float(np.asarray(dyn.velocity(before)).ravel()[1])
            touchdown_signs[j] = 1.0 if v_t >= 0 else -1.0
    x0 = np.concatenate([problem.q0, problem.v0])
    x = opti.variable(2 * n_q)
    opti.subject_to(x == x0)
    opti.set_initial(x, x0)
    nodes = [(ca.MX(0.0), x)]  # (time, state)
    boundary = [x]
    stick_forces, impulses = [], []
    cost = 0
    mode_index = 0

    # With element derivatives, a node's path rows (if free of the time) and its contact
    # rows are repeated rows too: one function each, differentiated once.
    path_rows = None if repeated is None else functions.path_rows()
    contact_functions = {}

    def contact_function(mode):
        if mode not in contact_functions:
            xs, us, ms = ca.SX.sym("x", 2 * n_q), ca.SX.sym("u", n_u), ca.SX.sym("margin")
            contact_functions[mode] = bounded_rows(
                f"contact_{mode.replace('+', 'p').replace('-', 'm')}", [xs, us, ms],
                contact_row_values(xs, us, mode, ms))
        return contact_functions[mode]

    def contact_row_values(x, u, mode, margin):
        """(lower, value, upper) of the contact's rows in `mode`."""
        if mode == STICK:
            lam = dyn.force(x, u)
            return [(0.0, lam[0], np.inf),
                    (0.0, margin * dyn.mu * lam[0] - lam[1], np.inf),
                    (0.0, margin * dyn.mu * lam[0] + lam[1], np.inf)]
        if mode == FLIGHT:
            return [(0.0, dyn.gap(x), np.inf)]
        sign = 1.0 if mode == "slip+" else -1.0
        lam_n, rate = dyn.slip_force[mode](x, u)
        return [(0.0, lam_n, np.inf),
                (1e-2, rate, np.inf),  # no Painleve: a unique normal force
                (0.0, sign * dyn.velocity(x)[1], np.inf)]

    def constrain_node(x, t, u, mode):
        lower = np.concatenate([problem.q_lower, problem.v_lower])
        upper = np.concatenate([problem.q_upper, problem.v_upper])
        finite = np.isfinite(lower) | np.isfinite(upper)
        if finite.any():
            opti.subject_to(opti.bounded(lower[finite], x[[int(i) for i in np.flatnonzero(finite)]],
                                         upper[finite]))
        if path_rows is not None:
            function, lower, upper = path_rows
            repeated.bounded(lower, function, upper, x, u)
        elif path_fn is not None:
            opti.subject_to(opti.bounded(np.broadcast_to(path.lower, path.expression.shape[0]),
                                         path_fn(y_of(x, t), u),
                                         np.broadcast_to(path.upper, path.expression.shape[0])))
        if mode != FLIGHT and options.painleve_margin > 0:
            # a unique contact force for either slip direction (W_nn - mu |W_nt| >= delta)
            w = dyn.delassus(x)
            opti.subject_to(w[0, 0] - dyn.mu * w[0, 1] >= options.painleve_margin)
            opti.subject_to(w[0, 0] + dyn.mu * w[0, 1] >= options.painleve_margin)
        contact_rows(x, u, mode)

    def contact_rows(x, u, mode):
        if mode == STICK:
            stick_forces.append((x, u))
        if repeated is not None:
            function, lower, upper = contact_function(mode)
            repeated.bounded(lower, function, upper, x, u, margin)
            return
        for lower, value, _ in contact_row_values(x, u, mode, margin):
            opti.subject_to(value >= lower)

    for k in range(n_int):
        u_k = controls[k, :].T
        if k in grid_lift_offs:  # the control jump opens the contact
            opti.subject_to(dyn.free_normal(x, u_k) >= 0)
            mode_index = grid_lift_offs[k] + 1
        elif k > 0 and phases[mode_index].mode != FLIGHT:
            # the contact holds on both sides of the control jump: its rows with the new
            # control too (else the foot may lift off at the jump while the plan sticks)
            contact_rows(x, u_k, phases[mode_index].mode)
        inside = [j for j, ki in enumerate(switch_interval) if ki == k]
        cuts = ([(grid[k], grid_guess[k], None)]
                + [(switches[j][0], switches[j][1], j) for j in inside]
                + [(grid[k + 1], grid_guess[k + 1], None)])
        for (ta, ga, _), (tb, gb, jb) in itertools.pairwise(cuts):
            mode = phases[mode_index].mode
            n_steps = max(1 if radau else 2,
                          round(substeps[k] * (gb - ga)
                                / max(grid_guess[k + 1] - grid_guess[k], 1e-12)))
            h = (tb - ta) / n_steps
            if isinstance(h, ca.MX):
                opti.subject_to(h <= 1.5 * dt / substeps[k])  # no long steps
                if repeated is not None:  # a variable, so that the steps are repeated rows
                    h_steps = opti.variable()
                    opti.subject_to(h_steps == h)
                    opti.set_initial(h_steps, (gb - ga) / n_steps)
                    h = h_steps
            for i in range(n_steps):
                if radau:  # one collocation element; its last stage is its end (c_s = 1)
                    t0 = ta + i * h
                    stages = []
                    for j in range(tableau.stages):
                        z = opti.variable(2 * n_q)
                        opti.set_initial(z, interpolate(
                            guess_t, guess_x, ga + (i + tableau.c[j]) * (gb - ga) / n_steps,
                            left_limit=True))
                        stages.append(z)
                    if repeated is not None:
                        repeated.zero(dyn.collocation(mode, tableau), x, *stages, u_k, h)
                        residuals = [None] * len(stages)
                    else:
                        residuals = collocation_residuals(dyn.rhs[mode], tableau, x, stages,
                                                          u_k, h)
                    for j, (z, residual) in enumerate(zip(stages, residuals, strict=True)):
                        if residual is not None:
                            opti.subject_to(residual == 0)
                        cost = cost + h * tableau.b[j] * running(
                            y_of(z, t0 + tableau.c[j] * h), u_k)
                        # a piece's last node at its end time exactly (ta + n h may differ
                        # from tb in the last bit; a touchdown's two nodes share one time)
                        last = i == n_steps - 1 and j == tableau.stages - 1
                        nodes.append((tb if last else t0 + tableau.c[j] * h, z))
                        constrain_node(z, t0 + tableau.c[j] * h, u_k, mode)
                    x = stages[-1]
                    continue
                x_start = x
                x = opti.variable(2 * n_q)
                if repeated is not None:
                    repeated.zero(dyn.shooting(mode, options.steps_per_node), x_start, u_k, h, x)
                    x_next = x
                else:
                    if options.expand:
                        x_next = x_start
                        for _ in range(options.steps_per_node):  # RK4 steps between nodes
                            x_next = dyn.step(mode, x_next, u_k, h / options.steps_per_node)
                    else:
                        x_next = dyn.rk4(mode, options.steps_per_node)(x_start, u_k, h)
                    opti.subject_to(x == x_next)
                cost = cost + h / 2 * (running(y_of(x_start, ta + i * h), u_k)
                                       + running(y_of(x_next, ta + (i + 1) * h), u_k))
                t_guess = ga + (i + 1) * (gb - ga) / n_steps
                opti.set_initial(x, interpolate(guess_t, guess_x, t_guess, left_limit=True))
                nodes.append((tb if i == n_steps - 1 else ta + (i + 1) * h, x))
                constrain_node(x, ta + (i + 1) * h, u_k, mode)
            if jb is None:
                continue
            following = phases[jb + 1].mode
            if mode == STICK:  # to slip
                sign = 1.0 if following == "slip+" else -1.0
                lam = dyn.force(x, u_k)  # the stick force reaches the cone's edge
                opti.subject_to(lam[1] + sign * dyn.mu * lam[0] == 0)
            elif mode != FLIGHT:  # slip to flight: lift-off
                opti.subject_to(dyn.slip_force[mode](x, u_k)[0] == 0)
            else:  # flight to stick
                opti.subject_to(dyn.gap(x) == 0)  # touchdown ...
                # ... and an impact whose impulse flow ends in stick
                vel = dyn.velocity(x)
                for big, small in touchdown_rows(dyn.delassus(x), vel[0], vel[1],
                                                 touchdown_signs[jb], dyn.mu, margin,
                                                 options.touchdown_rate):
                    opti.subject_to(big >= small)
                post, impulse = dyn.impact(x)  # the post-impact state: J v+ = 0
                impulses.append(impulse)
                x = opti.variable(2 * n_q)
                opti.subject_to(x == post)
                opti.set_initial(x, interpolate(guess_t, guess_x, gb))
                nodes.append((tb, x))
                constrain_node(x, tb, u_k, STICK)
            mode_index = jb + 1
        boundary.append(x)
    y_end = y_of(x, horizon)
    if terminal_fn is not None:
        n_rows = terminal.expression.shape[0]
        lower = np.broadcast_to(np.asarray(terminal.lower, dtype=float), n_rows)
        upper = np.broadcast_to(np.asarray(terminal.upper, dtype=float), n_rows)
        value = terminal_fn(y_end)
        equal = np.flatnonzero(lower == upper)
        other = np.flatnonzero(lower != upper)
        if other.size:
            opti.subject_to(opti.bounded(lower[other], value[other.tolist()], upper[other]))
        if equal.size:
            xs = ca.SX.sym("x", 2 * n_q)
            kept = terminal_rows_not_held(
                ca.Function("terminal_x", [xs], [terminal_fn(y_of(xs, horizon))[equal.tolist()]]),
                dyn.held[phases[-1].mode], interpolate(guess_t, guess_x, horizon))
            if kept.shape[0]:  # (none when the stance holds every terminal equality)
                opti.subject_to(ca.mtimes(kept, value[equal.tolist()] - lower[equal]) == 0)
    opti.minimize(cost + terminal_cost(y_end))
    derivatives = ({} if repeated is None
                   else repeated.derivative_options(options.threads))
    # `stop` lives as long as the solver: CasADi holds only a borrowed reference to it
    stop = ipopt_solver(opti, {"print_time": False, "record_time": True,
                               "expand": options.expand, **derivatives},
                        {"tol": options.tol, "max_iter": options.max_iter, "print_level": 0,
                         "sb": "yes"})
    history = []
    status, iterations = "", 0
    values = None
    build_time = time.perf_counter() - start
    evaluation_time = ipopt_time = 0.0
    for c in options.cone_margins:
        opti.set_value(margin, c)
        if verbose:
            report_progress(stop)
        sol, building, in_ipopt, evaluations = solve_timed(opti, options.blas_threads)
        build_time += building if not history else 0.0  # the first solve builds the solver
        ipopt_time += in_ipopt
        evaluation_time += evaluations
        stats = sol.stats()
        status = str(stats.get("return_status", "unknown"))
        n_it = int(stats.get("iter_count", 0))
        iterations += n_it
        history.append((c, status, n_it))
        if verbose:
            print(f"  polish  cone margin {c:g}: {status}, {n_it} iterations, objective "
                  f"{float(sol.value(opti.f)):.6g}", flush=True)
        values = sol
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level") and verbose:
            g = np.asarray(sol.value(opti.g)).ravel()
            lbg = np.asarray(sol.value(opti.lbg)).ravel()
            ubg = np.asarray(sol.value(opti.ubg)).ravel()
            viol = np.maximum(lbg - g, g - ubg)
            for i in np.argsort(-viol)[:12]:
                print(f"    violation {viol[i]:.3e} at g[{i}] of {g.size}: "
                      f"{opti.debug.g_describe(int(i))[:150]}", flush=True)
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            break
        opti.set_initial(sol.value_variables())
        opti.set_initial(opti.lam_g, sol.value(opti.lam_g))
    sol = values
    u_value = np.asarray(sol.value(controls)).reshape(n_int, n_u) if n_u else np.zeros((n_int, 0))
    node_x = np.array([np.asarray(sol.value(xn)).ravel() for _, xn in nodes])
    times = np.array([float(sol.value(tn)) if isinstance(tn, ca.MX) else float(tn)
                      for tn, _ in nodes])
    switch_values = [float(sol.value(s)) if isinstance(s, ca.MX) else float(s)
                     for s, _ in switches]
    clocks = grid_guess
    boundary_x = np.array([np.asarray(sol.value(b)).ravel() for b in boundary])
    forces = np.array([np.asarray(dyn.force(sol.value(xs), sol.value(us))).ravel()
                       for xs, us in stick_forces]).reshape(-1, 2)
    impact_values = np.array([np.asarray(sol.value(i)).ravel() for i in impulses]).reshape(-1, 2)
    ends = switch_values + [horizon]
    starts = [0.0] + switch_values
    polished_phases = tuple(Phase(p.mode, s, e)
                            for p, s, e in zip(phases, starts, ends, strict=True))
    solve_time = time.perf_counter() - start
    verification = _verify(problem, clocks=clocks, boundary_x=boundary_x, u=u_value,
                           node_t=times, node_x=node_x, dyn=dyn, forces=forces,
                           impulses=impact_values, options=options)
    plan = PolishedPlan(
        phases=polished_phases, t=times, x=node_x, u=u_value, boundary_states=boundary_x,
        contact_forces=forces, impact_impulses=impact_values, cost=float(sol.value(opti.f)),
        ipopt_status=status, iterations=iterations, solve_time=solve_time,
        verification=verification, history=tuple(history), integrator=options.integrator,
        substeps=substeps, timing=NlpTiming(build_time, ipopt_time, evaluation_time,
                                            int(opti.nx), int(opti.ng)))
    if verbose:
        print(plan.summary(), flush=True)
    return plan


def verify_polished(problem: ContactProblem, phases: tuple[Phase, ...], t: np.ndarray,
                    x: np.ndarray, u: np.ndarray, boundary_states: np.ndarray,
                    options: PolishOptions | None = None) -> Verification:
    """The checks of `polish_contact` on a polished plan given by its arrays (a plan read
    back from disk, or one changed by hand): the exact reference replays each control
    interval from the plan's own state, the gaps are measured at the nodes, the friction
    cone on the stick forces and touchdown impulses recomputed from the nodes' states and
    controls (`polish_contact` checks those its NLP held: the same values), the node
    times must not decrease and must end at the horizon.

    Args:
        problem: the `ContactProblem` the plan solves.
        phases: its contact sequence (the polished switch times).
        t, x: node times [s] and states (q, v), (n_nodes, 2 n_q); a touchdown has two
            nodes at its time.
        u: controls per interval, (N, n_u); boundary_states: (q, v) at the interval
            boundaries, (N + 1, 2 n_q).
        options: `PolishOptions` (its tolerances and Baumgarte gain).

    Raises:
        InvalidInput: arrays of the wrong shape for the problem.
    """
    options = options or PolishOptions()
    cls = problem.system.cls
    _check_system(cls)
    n_int, n_x = problem.n_intervals, 2 * cls.n_q
    t, x, u = np.asarray(t, dtype=float), np.asarray(x, dtype=float), np.asarray(u, dtype=float)
    boundary_states = np.asarray(boundary_states, dtype=float)
    expected = {"u": (u, (n_int, cls.n_u)), "boundary_states": (boundary_states, (n_int + 1, n_x)),
                "x": (x, (len(t), n_x))}
    for name, (value, shape) in expected.items():
        if value.shape != shape:
            raise InvalidInput(f"`{name}` has shape {value.shape}; the problem needs {shape}")
    dyn = HybridDynamics(cls, options.baumgarte, ldl=options.ldl)
    forces, impulses = contact_values(t, x, u, tuple(phases), dyn, problem.horizon)
    clocks = np.arange(n_int + 1) * problem.horizon / n_int
    return _verify(problem, clocks=clocks, boundary_x=boundary_states, u=u, node_t=t,
                   node_x=x, dyn=dyn, forces=forces, impulses=impulses, options=options)


def contact_values(t: np.ndarray, x: np.ndarray, u: np.ndarray, phases: tuple[Phase, ...],
                   dyn: HybridDynamics, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    """(stick forces (n, 2) [N], touchdown impulses (m, 2) [N s]) of a plan's nodes: the
    stick force at both ends of every segment between two nodes inside a stick phase, with
    that segment's control (at a control jump both controls, as the re-solve's rows hold
    them), and the impulse of each touchdown (two nodes at one time)."""
    starts = np.array([p.start for p in phases])
    dt = horizon / len(u)
    forces, impulses = [], []
    for i in range(len(t) - 1):
        if t[i + 1] == t[i]:
            impulses.append(np.asarray(dyn.impact(x[i])[1]).ravel())
            continue
        middle = 0.5 * (t[i] + t[i + 1])
        if phases[int(np.searchsorted(starts, middle)) - 1].mode != STICK:
            continue
        u_k = u[min(int(middle / dt), len(u) - 1)]
        forces += [np.asarray(dyn.force(x[j], u_k)).ravel() for j in (i, i + 1)]
    return np.array(forces).reshape(-1, 2), np.array(impulses).reshape(-1, 2)


def _verify(problem: ContactProblem, *, clocks: np.ndarray, boundary_x: np.ndarray,
            u: np.ndarray, node_t: np.ndarray, node_x: np.ndarray, dyn: HybridDynamics,
            forces: np.ndarray, impulses: np.ndarray, options: PolishOptions) -> Verification:
    """The replay checks of `verify_plan` on the polished plan, plus its gaps, cone and
    node times (non-decreasing, the last at the horizon: there is no clock state, the
    plan runs in physical time)."""
    n_int, horizon = problem.n_intervals, problem.horizon
    plan = ReplayedPlan(cls=problem.system.cls, x0=np.concatenate([problem.q0, problem.v0]),
                        clocks=clocks, states=boundary_x,
                        controls=u, horizon=horizon)
    notes: list[str] = []
    window = LOCAL_DEFECT_IMPACT_WINDOW * horizon / n_int
    try:
        deviation, method, reference_end = reference_deviation(plan, boundary_x[-1], window)
    except TfcontactError as error:
        deviation, method, reference_end = float("inf"), f"reference stopped ({error})", None
    defects = local_defects(plan, [(k, k + 1) for k in range(n_int)], options.gap_tolerance)
    end_ok, defect_sum, amplification = end_state_check(
        plan, options.end_state_tolerance, deviation, defects, reference_end, notes)
    gaps = np.asarray(dyn.gap(node_x.T)).ravel()
    min_gap = float(gaps.min())
    # Forces [N] in the cone at the stick nodes, impulses [N s] at the touchdowns.
    both = np.vstack([forces, impulses]) if len(impulses) else forces
    cone = friction_cone_violation(both, [dyn.mu], [1])
    largest = float(np.max(np.abs(both[:, 0]), initial=0.0))
    notes.append(f"cone checked on {len(forces)} stick nodes (forces, N) and {len(impulses)} "
                 f"touchdown impulses (N s); tolerance {options.cone_tolerance:g} x the "
                 f"largest normal value {largest:.3g}")
    node_t = np.asarray(node_t, dtype=float)
    monotone = bool(np.all(np.diff(node_t) >= 0.0))
    end_error = abs(float(node_t[-1]) - horizon)
    terminal = terminal_violation(problem, boundary_x[-1])
    terminal_ok = terminal <= options.terminal_tolerance
    if not terminal_ok:
        notes.append(f"the terminal constraint is violated by {terminal:.3g} at T (tolerance "
                     f"{options.terminal_tolerance:g})")
    passed = (end_ok and terminal_ok and min_gap >= -options.gap_tolerance
              and cone <= options.cone_tolerance * max(largest, 1e-12)
              and monotone and end_error <= CLOCK_TOLERANCE * horizon)
    return Verification(
        passed=bool(passed), method=method, end_state_deviation=deviation, min_gap=min_gap,
        friction_cone_violation=cone, clock_monotone=monotone, clock_end_error=end_error,
        tolerances={"end_state": options.end_state_tolerance, "gap": options.gap_tolerance,
                    "cone": options.cone_tolerance},
        notes=tuple(notes), dissipation_violation=float("nan"), local_defects=defects,
        defect_sum=defect_sum, open_loop_amplification=amplification,
        open_loop_unstable=bool(end_ok and deviation > options.end_state_tolerance))


def terminal_violation(problem: ContactProblem, x_end: np.ndarray) -> float:
    """The largest violation of `problem.terminal` at the end state (q, v) `x_end` with
    the clock at the horizon; 0 without a terminal constraint."""
    terminal = problem.terminal
    if terminal is None or terminal.expression.numel() == 0:
        return 0.0
    system = problem.system
    y = system_states(system, x_end, np.array([problem.horizon]))
    values = np.asarray(ca.Function("terminal", [system.y], [terminal.expression])(y[0]))
    return bound_violation(values.reshape(1, -1), terminal.lower, terminal.upper)


def node_samples(plan: PolishedPlan, cls, baumgarte: float = PolishOptions.baumgarte
                 ) -> dict[str, np.ndarray]:
    """Per node of a polished plan: its phase mode, the control that drives it, the gap and
    normal velocity, the contact force (lambda_n, lambda_t) [N] (stick: the stick force,
    slip: lambda_t = -s mu lambda_n, flight: 0) and the impulse (Lambda_n, Lambda_t) [N s]
    of a touchdown at its post-impact node (0 elsewhere). A node's mode and control are
    those of the segment that ends at it (the first node: the first phase's and
    control's); a post-impact node is in the stick phase that starts there."""
    dyn = HybridDynamics(cls, baumgarte)
    t, x, u = plan.t, plan.x, plan.u
    n_int = len(u)
    horizon = plan.phases[-1].end
    dt = horizon / n_int
    starts = np.array([p.start for p in plan.phases])
    modes, controls = [], []
    forces = np.zeros((len(t), 2))
    impulses = np.zeros((len(t), 2))
    for i in range(len(t)):
        if i > 0 and t[i] == t[i - 1]:  # the post-impact node of a touchdown
            at = t[i]
            impulses[i] = np.asarray(dyn.impact(x[i - 1])[1]).ravel()
        else:
            at = t[0] if i == 0 else 0.5 * (t[i - 1] + t[i])
        phase = plan.phases[max(int(np.searchsorted(starts, at, side="right")) - 1, 0)]
        k = min(int(at / dt), n_int - 1)
        modes.append(phase.mode)
        controls.append(u[k])
        if phase.mode == STICK:
            forces[i] = np.asarray(dyn.force(x[i], u[k])).ravel()
        elif phase.mode != FLIGHT:
            sign = 1.0 if phase.mode == "slip+" else -1.0
            lam_n = float(dyn.slip_force[phase.mode](x[i], u[k])[0])
            forces[i] = (lam_n, -sign * dyn.mu * lam_n)
    velocities = np.asarray(dyn.velocity(x.T)).T.reshape(len(t), 2)
    return {"mode": np.array(modes), "u": np.array(controls).reshape(len(t), -1),
            "gap": np.asarray(dyn.gap(x.T)).ravel(), "normal_velocity": velocities[:, 0],
            "force": forces, "impulse": impulses}
