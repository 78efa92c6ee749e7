"""The exact re-solve of a plan with several contacts along a fixed sequence of stances.

The homotopy of `solve_contact` discovers which feet are down when; its relaxed plan
(complementarity residual 1e-4) still holds a light leg on the ground after its torques
let go and touches down a few milliseconds off (benchmarks/legged.md), so the reference
restarted from its states parts from it. `resolve_stances` keeps the sequence of stances
(which contacts are closed) and re-solves the OCP as a smooth NLP with the original
system's dynamics, contact-accurate by construction:

* a stance S (the closed contacts, each sticking): M a = f + J_S lambda with
  J_S^T a + (dJ_S/dt)^T v = -(stabilisation) (index-reduced, Baumgarte: the normal rows
  2 alpha v_n + alpha^2 gap, the tangential ones alpha v_t); at every node
  lambda_n,i >= `min_normal_force` and the cone ||lambda_t,i|| <= c mu_i lambda_n,i (c:
  `cone_margin`; or its inscribed pyramid, `cone_facets`), the
  open contacts' gaps >= 0 (not at a contact's own touchdown or lift-off node, where the
  rows would be degenerate: `StanceOptions.open_slip_gains`);
* a touchdown of contacts D (a stance S -> S + D) at a free time inside the control
  interval its guess lies in: gap_i = 0 for i in D and the inelastic impact of all the
  closed contacts S + D ending in stick, J^T v+ = 0 with the impulse
  Lambda = -(J^T M^-1 J)^-1 J^T v-, each Lambda_n,i >= 0 and in its cone: the solution of
  the velocity-level impact LCP of the multi-contact reference
  (`tfcontact.verify.multicontact`) when every contact ends at rest;
* a lift-off of contacts L (S -> S - L) at a control jump k T / N: with the new control
  the remaining stance's dynamics give each lifting contact a normal acceleration
  n_i^T a + (dn_i/dt)^T v >= 0 (the acceleration LCP then opens it). Inside a control
  interval a sticking contact's force reaches zero only with its tangential force, which
  the rigid model does not give (as in `tfcontact.ocp.polish`);
* inside a stance the contact rows hold with both controls at each control jump.

Controls are piecewise constant on the fixed grid k T / N; every piece between two
switches is integrated by RK4 (multiple shooting, `nodes` per interval and
`steps_per_node` RK4 steps between two nodes) or by Radau IIA collocation, whose stages
take a and lambda as expressions of (x, u) or, opt-in (`StanceOptions.inverse_dynamics`),
as variables bound by the stance's equations (no M^-1 in the NLP). The plan is
checked by the multi-contact reference (the open-loop replay, local defects per control
interval, the amplification of a kicked replay), the gaps and the cone at the nodes.

Friction in slip is not modelled: every closed contact sticks (no-slip feet). The single
frictional planar contact with slip phases is `tfcontact.ocp.polish`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import (
    InvalidInput,
    SolveFailed,
    nonnegative_number,
    one_of,
    optional_positive,
    positive_int,
)
from tfcontact.fesd.tableau import RadauIIA, lagrange_weights
from tfcontact.mpcc import BARRIERS
from tfcontact.ocp.contact import ContactProblem, ContactResult
from tfcontact.ocp.goals import EndHeight
from tfcontact.ocp.nodes import (
    CAPPED,
    NlpTiming,
    NodeFunctions,
    RepeatedRows,
    bounded_rows,
    collocation_function,
    collocation_residuals,
    collocation_rows,
    interpolate,
    ipopt_solver,
    report_progress,
    shooting_function,
    solve_timed,
    spd_solve,
)
from tfcontact.verify import (
    EvaluationBudget,
    MultiContactOptions,
    ReplayedPlan,
    Verification,
    VerifyOptions,
    end_state_check,
    multicontact_local_defects,
    replay_multicontact,
    state_indices,
    stopped_replay,
)

SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Feasible_Point_Found")
"""IPOPT's statuses of a solved stance NLP. Feasible_Point_Found: a square problem (no
degree of freedom left, e.g. every control fixed by its bounds) whose restoration phase
reached its constraints: its one feasible point is its solution."""
INFEASIBLE = "Infeasible_Problem_Detected"
STEP_ERROR = "Error_In_Step_Computation"
RESTART_VELOCITY_TOLERANCE = 1e-6
"""The multi-contact reference's velocity tolerance [m/s] for a stance plan: a contact
velocity this small counts as zero at a mode change (and is projected to zero). A closed
contact's velocity is zero in the plan to the integrator's accuracy only: a bolt restart
whose standing foot moved up at 1.4e-7 m/s (the simulator's default tolerance 1e-7) flew
and landed back 200 times at its start; with 1e-6 it stood, 3e-6 from the plan."""
RESTART_PUSH = 1e-9
"""A capped stance NLP solved again starts from its iterate with the barrier parameter
and IPOPT's warm-start pushes at this value (as `tfcontact.mpcc.Ipopt.warm_start_push`)."""
STALL_FEASIBILITY = 1e-6
"""A stalled stance NLP (`StanceOptions.stall_iterations`) stops only while its
constraints hold to this [the rows' units] and its complementarity to the barrier too."""
STALL_OBJECTIVE_CHANGE = 1e-6
"""... and while its objective changes by at most this, relative to max(1, |f|)."""
STALL_DUAL_INFEASIBILITY = 1e-2
"""... and while its dual infeasibility (the Lagrangian's gradient) is at most this."""
SINGULAR_DELASSUS = 1e10
"""A stance whose Delassus matrix has a larger condition number is refused."""


@dataclass(frozen=True)
class StanceOptions:
    """Settings of `resolve_stances`.

    Args:
        nodes: shooting nodes (RK4) or collocation elements (Radau) per control interval
            (a piece of an interval cut by a touchdown gets its share, at least 2 nodes or
            1 element).
        steps_per_node: RK4 steps from one node to the next.
        integrator: "radau" (default): Radau IIA collocation with `radau_stages` stages
            (order 2 s - 1), every stage state a variable with the node rows; or "rk4":
            explicit RK4 multiple shooting, each node's steps one SX function. Radau
            evaluates one right-hand side per stage instead of 4 steps_per_node: bolt's
            walk took 0.47 s per iteration against RK4's 0.85 (3 elements against 4 x 2
            steps per interval), a two-legged step 38 s against 127 s.
        baumgarte: alpha [1/s] of the closed contacts' stabilisation.
        cone_margin: c of the node rows ||lambda_t|| <= c mu lambda_n. Below 1 for 3-D
            contacts: the reference's mode decisions use a pyramid of 16 facets, 1.9 %
            smaller than the cone.
        cone_facets: None: a 3-D contact's node row is the circular cone
            (c mu lambda_n)^2 - ||lambda_t||^2 >= 0, whose gradient vanishes at zero force
            (a lifting or lightly loaded foot), where no constraint qualification holds;
            an even number n >= 4: the n linear rows of the inscribed pyramid,
            c mu cos(pi / n) lambda_n - d_k . lambda_t >= 0 for the facets' normals d_k
            (solo12's jump along a fixed schedule: 196 IPOPT iterations with 4 facets
            against 1136 with the circle; benchmarks/legged.md). Impulses too.
        min_normal_force: lambda_n >= this [N] for every closed contact at every node
            (not the impulses). A plan left free puts lightly loaded feet on the floor of
            the cone, where the reference's mode decision turns on round-off (solo12's
            crouch: 0.0-0.3 N per foot at the cone's edge; the reference let a foot lift
            and three slip).
        touchdown_speed: None, or a speed s >= 0 [m/s]: each contact touching down
            approaches with n_i^T v- <= -s. A touchdown at zero approach speed is an
            ill-conditioned event (its time moves by the gap's error over the speed):
            solo12's free-flailing flight brought a foot to its touchdown node moving up
            at 1.4 m/s (its gap negative just before, between two collocation points), and
            the reference landed it 3 ms early.
        interior_rows: Radau: the closed contacts' rows (their cones and
            `min_normal_force`) also at this many points between each two consecutive
            collocation points of every element, on the element's collocation polynomial.
            The rows hold at the collocation points only, and an optimiser presses the
            forces against them there: solo12's landing with six elements per control
            interval kept lambda_n >= 1 N at its points but fell to 0.62 N with
            |lambda_t| / lambda_n = 0.80 > mu between two of them, and the reference
            slipped that foot (benchmarks/legged.md). The open contacts' gap rows there
            too made that NLP creep (stopped after 500 IPOPT iterations; 92 without
            them). Not with `inverse_dynamics` (its forces are variables at the
            collocation points only).
        flight_gap, contact_gap: `stance_schedule` opens a contact above `flight_gap` [m]
            and closes it again below `contact_gap` [m].
        end_standing: `stance_schedule` drops every lift-off with no touchdown after it:
            each contact once down (at the start or a touchdown) ends down, closed from its
            last touchdown (or the start) to T, for a task that ends standing. A relaxed
            plan may lift its feet once the goals are met (solo12's jump: a flight from
            0.55 s, the feet 2-3 cm up at T), and the re-solve keeps what it is given.
        switch_margin: touchdowns keep this fraction of a control interval from its ends.
            With 0.002 bolt's walks found cheaper plans, but one put a touchdown 0.1 ms
            before a lift-off, and the reference failed it (benchmarks/legged.md).
        open_slip_gains: per contact K [m/s^2] or None; a contact with K gets the rows
            ||v_t||^2 <= K gap at the nodes where it is open: it does not skim the ground
            (at zero gap it moves along the normal only). Without them bolt's swing foot
            slid along the ground at zero gap, a contact the stance does not model, and
            the reference's restarts parted from the plan by up to 3.6. Not at a contact's
            own switch nodes (its touchdown's gap = 0, its lift-off), where the row would
            force v_t = 0 with a vanishing gradient: with it there bolt's one-step walk took
            562 IPOPT iterations, without it 113 (benchmarks/legged.md). Empty: no rows.
            A task's no-slip contacts get their `no_slip_gain` (`StanceResolve`).
        swing_heights: per contact h [m] or None; a contact with h keeps, in each of its
            swings (open from a lift-off, or from the start, to its next touchdown or T)
            in which the guess rises above h, gap >= h at the node where the guess is
            highest: the re-solve keeps the steps the discovery found instead of trading
            them for a skim (bolt's reduced walk: the discovery lifted the right foot above
            5 cm, the re-solve without these rows 2 cm; benchmarks/legged.md). Empty: no
            rows.
        swing_middle: also a swing in which the guess stays below h gets the row, at its
            node nearest the swing's middle: a contact sequence given as data, whose guess
            (a base reference, the legs at their start) lifts no foot, still steps rather
            than skims. False: a swing the guess does not lift keeps no row (a discovery's
            shuffle is not made a step).
        end_height_rows: the problem's end-height goals (`EndHeight`: a contact ends
            resting on a surface at a height) as terminal rows |z_low(T) - height| <=
            tolerance / 2. The terminal gap row alone is met by any surface: biped-step's
            re-solve, from a discovery that ended both feet on the step, ended them on the
            ground before it (benchmarks/legged.md).
        swing_fallback: when IPOPT finds the NLP with swing-height rows locally
            infeasible, solve it once more without them (`StancePlan.swing_rows_dropped`;
            the task's goals then decide). The rows ask of the exact plan what a relaxed
            guess did, which its hop can leave out of reach: bolt's short walk from a
            perturbed start, infeasible with them, was verified and did its task without
            (benchmarks/legged.md).
        inverse_dynamics: the stance dynamics in inverse-dynamics form (Radau only; RK4
            needs the explicit a(x, u)): every stage state gets its acceleration a and the
            closed contacts' forces lambda as NLP variables with the rows
            M(q) a = f + J_S lambda and J_S^T a + (dJ_S/dt)^T v = -(stabilisation), so no
            expression holds M^-1 or the Delassus matrix's inverse, and the NLP is
            expanded into one SX graph. Opt-in: on bolt's walks an iteration took 0.15 s
            against the explicit form's 0.52 s (whose Hessian alone took 0.32 s), but
            IPOPT needed far more of them: 245 iterations (144 s) explicit against more
            than 2000 for a one-step walk (benchmarks/legged.md).
        lifted_forces: the closed contacts' forces lambda of every stage state as NLP
            variables (Radau only), its acceleration a = M^-1 (f + J_S lambda) (one M(q)
            solve, no Delassus inverse) and the rows J_S^T a + (dJ_S/dt)^T v =
            -(stabilisation); the cone rows are then rows in lambda. Between the explicit
            form (lambda an expression of (x, u)) and `inverse_dynamics` (a variable too):
            on solo12's four-foot stance an element's Hessian took 1.6M instructions
            against the explicit form's 4.8M, and a node's cone rows none against 1.2M
            (benchmarks/legged.md).
        element_derivatives: differentiate each collocation element's (each shooting
            step's) equations, the contacts' rows at a node and the path rows (unless they
            depend on the time) once per stance and scatter them
            (`tfcontact.ocp.nodes.RepeatedRows`) instead of CasADi's derivatives of the
            whole NLP; a piece whose length a touchdown time sets gets its step length as
            a variable. The explicit form only (the lifted rows of `inverse_dynamics` are
            CasADi's). On by default (measured side by side: bolt's one-step walk the same
            83 iterations in 8.4 s against 15.1 s; biped-walk the same plan in 659
            iterations and 155 s against 531 and 264 s, 0.41 against 0.62 GB;
            benchmarks/legged.md). Round-off differs, and with it IPOPT's path.
        threads: threads that evaluate the element derivatives (CasADi's thread map).
        discovery_residual: None, the stance re-solve follows a converged discovery only;
            a number r > 0: also a discovery whose homotopy stopped short (nlp_failed or
            not_converged) when its last solved NLP's complementarity residual is at most r
            (its stances read from that iterate). The re-solve enforces the stances'
            complementarity exactly and the reference verifies its plan, so the discovery
            only proposes the sequence; its status stays in the plan's summary. A task
            file's `[resolve] discovery_residual` also stops its discovery there
            (`Homotopy.accept_residual`).
        tol, max_iter: IPOPT's.
        stall_iterations: 0 (off), or n >= 1: IPOPT also stops, as solved to an acceptable
            level, after n consecutive iterations at which the constraints hold to
            `STALL_FEASIBILITY`, the objective changes by at most `STALL_OBJECTIVE_CHANGE`
            (relative) and the dual infeasibility is at most `STALL_DUAL_INFEASIBILITY`: a
            feasible plan whose optimality IPOPT cannot certify (its dual infeasibility
            stalls at 1e-3 with the barrier at its floor, the Hessian regularised). The
            plan's physics is the reference's to judge, not IPOPT's optimality: a planar
            solo12's two-hop pronk crept with its objective falling 1e-6 per iteration from
            iteration 450 to past 950 (`tol` 1e-8 never reached); its iterate at 450 was
            verified (local defects <= 3.7e-4; benchmarks/legged.md).
        barrier: IPOPT's update of the barrier parameter (`mu_strategy`), "monotone"
            (IPOPT's default) or "adaptive". Measured on the trot's two swings
            (benchmarks/legged.md): the explicit form 109 iterations monotone against 140
            adaptive (objective 0.0138 against 0.0041); with `lifted_forces` the monotone
            barrier stalls at mu = 0.1 while the adaptive one converges (203 iterations, the
            same plan as the explicit form's adaptive one); on solo12's jump adaptive gives
            the lifted form no gain (430 iterations against 482).
        capped_restarts: solves of the same NLP again, each from the last one's primal-dual
            iterate, after IPOPT stopped at `max_iter` (each up to `max_iter` more).
        step_error_restarts: the same after IPOPT stopped with Error_In_Step_Computation
            (its regularisation of the KKT matrix ran out; a restart begins with its state
            fresh). Measured on biped-step's re-solve: IPOPT stopped so after 1010
            iterations at an iterate that already passed the reference.
        blas_threads: threads of IPOPT's BLAS during the solve (None: as set).
        end_state_tolerance, gap_tolerance, cone_tolerance: the verification's.
        budget: model evaluations of the multi-contact reference for the replay and all
            restarts together (`MultiContactReplay.budget`).
        contact_tolerance: the reference's (`MultiContactOptions.contact_tolerance`): a
            gap at most this [m] counts as closed at an impact or a mode change, so that
            contacts within it take part in one impact. A plan that lands several feet at
            one instant closes their gaps together to its integrator's accuracy only; the
            reference's feet then arrive microseconds apart, sequential impacts of fewer
            contacts with other outcomes (solo12's four-foot landing: 1 us apart, joint
            velocities after them 12 rad/s from the plan's; with 1e-6 m one impact, 8e-3).
    """

    nodes: int = 3
    steps_per_node: int = 2
    integrator: str = "radau"
    radau_stages: int = 3
    baumgarte: float = 20.0
    cone_margin: float = 0.98
    cone_facets: int | None = None
    min_normal_force: float = 0.0
    touchdown_speed: float | None = None
    interior_rows: int = 0
    flight_gap: float = 5e-3
    contact_gap: float = 1e-3
    end_standing: bool = False
    switch_margin: float = 0.02
    open_slip_gains: tuple[float | None, ...] = ()
    swing_heights: tuple[float | None, ...] = ()
    swing_middle: bool = False
    swing_fallback: bool = True
    end_height_rows: bool = True
    inverse_dynamics: bool = False
    lifted_forces: bool = False
    element_derivatives: bool = True
    threads: int = 2
    discovery_residual: float | None = None
    tol: float = 1e-8
    max_iter: int = 3000
    stall_iterations: int = 0
    barrier: str = "monotone"
    capped_restarts: int = 0
    step_error_restarts: int = 1
    blas_threads: int | None = 2
    end_state_tolerance: float = VerifyOptions.end_state_tolerance
    gap_tolerance: float = VerifyOptions.gap_tolerance
    cone_tolerance: float = VerifyOptions.cone_tolerance
    budget: int = 500_000
    contact_tolerance: float = MultiContactOptions.contact_tolerance

    def __post_init__(self) -> None:
        if self.integrator not in ("rk4", "radau"):
            raise InvalidInput(f"`integrator` must be 'rk4' or 'radau', got {self.integrator!r}")
        for name in ("swing_fallback", "swing_middle", "end_height_rows", "end_standing"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInput(f"`{name}` must be True or False, got "
                                   f"{getattr(self, name)!r}")
        if not isinstance(self.inverse_dynamics, bool):
            raise InvalidInput(f"`inverse_dynamics` must be True or False, got "
                               f"{self.inverse_dynamics!r}")
        if self.inverse_dynamics and self.integrator == "rk4":
            raise InvalidInput("`inverse_dynamics` needs integrator='radau' (RK4 integrates "
                               "the explicit form a(x, u))")
        if not isinstance(self.lifted_forces, bool):
            raise InvalidInput(f"`lifted_forces` must be True or False, got "
                               f"{self.lifted_forces!r}")
        if self.lifted_forces and (self.integrator == "rk4" or self.inverse_dynamics):
            raise InvalidInput("`lifted_forces` needs integrator='radau' and not "
                               "inverse_dynamics (which lifts the forces already)")
        one_of(self.barrier, BARRIERS, "barrier")
        if not isinstance(self.element_derivatives, bool):
            raise InvalidInput(f"`element_derivatives` must be True or False, got "
                               f"{self.element_derivatives!r}")
        for name in ("nodes", "steps_per_node", "radau_stages", "max_iter", "budget",
                     "threads"):
            positive_int(getattr(self, name), name)
        for name in ("capped_restarts", "step_error_restarts", "stall_iterations"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise InvalidInput(f"`{name}` must be an integer >= 0, got {value!r}")
        if self.blas_threads is not None:
            positive_int(self.blas_threads, "blas_threads")
        optional_positive(self.discovery_residual, "discovery_residual")
        if not 0 < self.cone_margin <= 1:
            raise InvalidInput(f"`cone_margin` must lie in (0, 1], got {self.cone_margin}")
        if (isinstance(self.interior_rows, bool) or not isinstance(self.interior_rows, int)
                or self.interior_rows < 0):
            raise InvalidInput(f"`interior_rows` must be an integer >= 0, got "
                               f"{self.interior_rows!r}")
        if self.interior_rows and (self.integrator != "radau" or self.inverse_dynamics):
            raise InvalidInput("`interior_rows` needs integrator='radau' with the explicit "
                               "form (inverse_dynamics=False): the rows lie on an element's "
                               "collocation polynomial")
        if self.touchdown_speed is not None:
            nonnegative_number(self.touchdown_speed, "touchdown_speed")
        if self.cone_facets is not None:
            positive_int(self.cone_facets, "cone_facets")
            if self.cone_facets < 4 or self.cone_facets % 2:
                raise InvalidInput(f"`cone_facets` must be None (the circular cone) or an "
                                   f"even number >= 4, got {self.cone_facets}")
        nonnegative_number(self.min_normal_force, "min_normal_force")
        if not 0 < self.contact_gap < self.flight_gap:
            raise InvalidInput(f"need 0 < contact_gap < flight_gap, got {self.contact_gap}, "
                               f"{self.flight_gap}")
        if not 0 < self.switch_margin < 0.5:
            raise InvalidInput(f"`switch_margin` must lie in (0, 0.5), got "
                               f"{self.switch_margin}")
        if not isinstance(self.open_slip_gains, tuple) or not all(
                k is None or (isinstance(k, int | float) and k > 0)
                for k in self.open_slip_gains):
            raise InvalidInput(f"`open_slip_gains` must be a tuple of gains > 0 or None, "
                               f"got {self.open_slip_gains!r}")
        if not isinstance(self.swing_heights, tuple) or not all(
                h is None or (isinstance(h, int | float) and not isinstance(h, bool)
                              and 0 < h < math.inf) for h in self.swing_heights):
            raise InvalidInput(f"`swing_heights` must be a tuple of heights > 0 [m] or None, "
                               f"got {self.swing_heights!r}")
        for name in ("baumgarte", "tol", "end_state_tolerance", "gap_tolerance",
                     "cone_tolerance", "contact_tolerance"):
            if not getattr(self, name) > 0:
                raise InvalidInput(f"`{name}` must be positive, got {getattr(self, name)}")


@dataclass(frozen=True)
class Stance:
    """The contacts `closed` (indices into the system's contacts, each sticking) from
    `start` to `end` [s]."""

    closed: tuple[int, ...]
    start: float
    end: float


def stall_stop(iterations: int) -> dict[str, float | int]:
    """IPOPT's acceptable-level options that stop a stalled NLP after `iterations`
    (`StanceOptions.stall_iterations`; 0: none, IPOPT's defaults)."""
    if not iterations:
        return {}
    return {"acceptable_iter": iterations, "acceptable_tol": STALL_DUAL_INFEASIBILITY,
            "acceptable_dual_inf_tol": STALL_DUAL_INFEASIBILITY,
            "acceptable_constr_viol_tol": STALL_FEASIBILITY,
            "acceptable_compl_inf_tol": STALL_FEASIBILITY,
            "acceptable_obj_change_tol": STALL_OBJECTIVE_CHANGE}


def stance_schedule(t: np.ndarray, gaps: np.ndarray, horizon: float, n_intervals: int,
                    options: StanceOptions | None = None) -> tuple[Stance, ...]:
    """The stances of a plan's samples: a contact is closed while its gap stays below
    `flight_gap`; it opens at the control jump k T / N nearest to its last sample before
    the gap rises above it (a lift-off of `resolve_stances` is at a control jump), and
    closes again at its first sample below `contact_gap` (a touchdown). A flight with no
    control jump between the contact's closing before it (its touchdown, or the start)
    and its touchdown cannot be modelled (its lift-off has no jump to go to): the contact
    stays closed across it (a relaxed plan's chatter; the rule before gave it a spurious
    flight and stance). With `options.end_standing` a lift-off with no touchdown after it
    is dropped: the contact stays closed to T.

    Args:
        t: sample times [s], (n,); gaps: the contacts' gaps [m] there, (n, n_contacts).

    Raises:
        InvalidInput: a touchdown and a lift-off that fall together, or a contact whose
            changes the control jumps cannot keep apart from the other contacts'.
    """
    options = options or StanceOptions()
    t = np.asarray(t, dtype=float)
    gaps = np.asarray(gaps, dtype=float).reshape(len(t), -1)
    step = horizon / n_intervals
    closed0, touchdowns, lift_offs = [], [], []  # (time, contact)
    for i in range(gaps.shape[1]):
        down = bool(gaps[0, i] <= options.contact_gap)
        if down:
            closed0.append(i)
        closing = 0.0 if down else None  # when the contact last closed
        lift_off = None  # the sample before its pending lift-off
        for k in range(1, len(t)):
            if down and gaps[k, i] > options.flight_gap:
                lift_off, down = float(t[k - 1]), False
            elif not down and gaps[k, i] < options.contact_gap and t[k] < horizon - 1e-9:
                down, lifted, lift_off = True, lift_off, None
                if lifted is not None:
                    if not _jump_between(closing, float(t[k]), step, n_intervals):
                        continue  # an unmodelled flight: closed across it
                    lift_offs.append((lifted, i))
                touchdowns.append((float(t[k]), i))
                closing = float(t[k])
        if lift_off is not None and not options.end_standing:
            lift_offs.append((lift_off, i))
    changes: dict[float, tuple[set[int], set[int]]] = {}  # time -> (closes, opens)
    for at, i in touchdowns:
        changes.setdefault(at, (set(), set()))[0].add(i)
    for at, i in lift_offs:
        # the nearest control jump that keeps the lift-off on its side of every
        # touchdown (else the gait changes: a flight phase where one foot still stood)
        if round(at / step) >= n_intervals:
            continue  # at the end: the contact stays closed to T
        low, high = math.floor(at / step), math.ceil(at / step)
        candidates = sorted({max(low, 1), min(max(high, 1), n_intervals - 1)},
                            key=lambda jump: abs(jump * step - at))
        jump = next((j for j in candidates
                     if all((td < at) == (td < j * step) for td, _ in touchdowns)),
                    candidates[0])
        lift = jump * step
        if lift in changes and changes[lift][0]:
            # a touchdown sampled at this very control jump: it goes just after the
            # lift-off (inside the next interval) or just before it, in the samples'
            # order; the re-solve moves it freely inside its interval. The contact's
            # own touchdown there (a tap: down at the jump's sample, up after it) is
            # before its lift-off.
            touchdown_at = next(td for td, _ in touchdowns if td == lift)
            after = at <= touchdown_at and i not in changes[lift][0]
            nudged = lift + (1e-6 if after else -1e-6) * step
            changes[nudged] = changes.pop(lift)
        changes.setdefault(lift, (set(), set()))[1].add(i)
    stances = [Stance(tuple(closed0), 0.0, horizon)]
    for at in sorted(changes):
        closes, opens = changes[at]
        if closes and opens:
            raise InvalidInput(f"contacts {sorted(closes)} touch down and {sorted(opens)} lift "
                               f"off together at {at:.4g} s: give them apart")
        current = set(stances[-1].closed)
        if closes & current or not opens <= current:
            raise InvalidInput(f"contacts {sorted(closes | opens)} change twice within one "
                               f"control interval near {at:.4g} s")
        closed = tuple(sorted((current | closes) - opens))
        stances[-1] = Stance(stances[-1].closed, stances[-1].start, at)
        stances.append(Stance(closed, at, horizon))
    return tuple(stances)


def _jump_between(begin: float, end: float, step: float, n_intervals: int) -> bool:
    """Whether a control jump j step (0 < j < N) lies strictly between begin and end."""
    first = max(math.floor(begin / step + 1e-9) + 1, 1)
    return first <= n_intervals - 1 and first * step < end - 1e-12


def swings(stances: Sequence[Stance], contact: int, horizon: float
           ) -> list[tuple[float, float]]:
    """The (begin, end) times [s] in which `contact` is open: from a lift-off (or the
    start) to its next touchdown (or the horizon)."""
    found, begin = [], None
    for s in stances:
        if contact in s.closed and begin is not None:
            found.append((begin, s.start))
            begin = None
        elif contact not in s.closed and begin is None:
            begin = s.start
    if begin is not None:
        found.append((begin, horizon))
    return found


def schedule_of(result: ContactResult, options: StanceOptions | None = None
                ) -> tuple[Stance, ...]:
    """`stance_schedule` of a time-freezing plan's physical samples."""
    phys = result.physical
    cls = result.system.cls
    x = phys.y[:, state_indices(result.system)]
    gaps = np.asarray(cls.function("gaps")(x[:, :cls.n_q].T)).T
    return stance_schedule(phys.t, gaps, result.problem.horizon, result.problem.n_intervals,
                           options)


class StanceDynamics:
    """The hybrid system's CasADi functions in x = (q, v) and u, per stance (a tuple of
    closed contacts, all sticking): `rhs(S)`, the contact forces `force(S)` (per closed
    contact lambda_n then lambda_t), the `opening(S, i)` normal acceleration of an open
    contact i under stance S, the `impact(S)` ending with every contact of S at rest
    (post-impact state and impulses), and `gaps` of every contact."""

    def __init__(self, cls, alpha: float = 20.0) -> None:
        if cls.v.numel() != cls.n_q:
            raise InvalidInput("the stance re-solve needs n_q = n_v (no quaternion base)")
        self.cls = cls
        self.alpha = alpha
        q, v, u = cls.q, cls.v, cls.u
        self._x = ca.vertcat(q, v)
        self._u = u
        self._minv_f = cls.solve_mass(cls.forces)
        self.columns = []  # per contact: J_i = [n_i B_i] (frictionless: n_i)
        for c in cls.contacts:
            self.columns.append(ca.horzcat(c.normal, c.tangents) if c.has_friction
                                else c.normal)
        self.mu = [c.mu for c in cls.contacts]
        self.gaps = ca.Function("gaps", [self._x], [ca.vertcat(*[c.gap for c in cls.contacts])])
        self.normal_velocities = ca.Function("normal_velocities", [self._x], [ca.vertcat(*[
            ca.mtimes(c.normal.T, v) for c in cls.contacts])])  # n_i^T v per contact
        self.slip_squared = ca.Function("slip_squared", [self._x], [ca.vertcat(*[
            ca.sumsqr(ca.mtimes(c.tangents.T, v)) if c.n_tangents else ca.SX(0.0)
            for c in cls.contacts])])  # ||v_t||^2 per contact
        self._cache: dict = {}

    def _terms(self, closed: tuple[int, ...]):
        cls, q, v = self.cls, self.cls.q, self.cls.v
        jac = ca.horzcat(*[self.columns[i] for i in closed])
        vel = ca.mtimes(jac.T, v)
        drift = ca.jacobian(vel, q) @ v
        stab = []
        for i in closed:
            vel_i = ca.mtimes(self.columns[i].T, v)
            stab.append(2 * self.alpha * vel_i[0] + self.alpha**2 * cls.contacts[i].gap)
            stab += [self.alpha * vel_i[j] for j in range(1, vel_i.shape[0])]
        minv_j = cls.solve_mass(jac)
        delassus = ca.mtimes(jac.T, minv_j)
        return jac, vel, drift, ca.vertcat(*stab), minv_j, delassus

    def _held(self, closed: tuple[int, ...], acc: ca.SX) -> ca.SX:
        """J_S^T a + (dJ_S/dt)^T v + stab: zero where the acceleration a keeps the closed
        contacts closed and sticking (the rows of the forms with a or lambda lifted)."""
        jac, _, drift, stab, _, _ = self._terms(closed)
        return ca.mtimes(jac.T, acc) + drift + stab

    def _stance(self, closed: tuple[int, ...]) -> dict:
        if closed in self._cache:
            return self._cache[closed]
        x, u, v = self._x, self._u, self.cls.v
        name = "s" + "_".join(str(i) for i in closed) if closed else "flight"
        if not closed:
            acc = self._minv_f
            funcs = {"rhs": ca.Function(f"rhs_{name}", [x, u], [ca.vertcat(v, acc)]),
                     "acc": acc, "force": None, "impact": None}
        else:
            jac, vel, drift, stab, minv_j, delassus = self._terms(closed)
            lam = spd_solve(delassus, -(ca.mtimes(jac.T, self._minv_f) + drift + stab))
            acc = self._minv_f + minv_j @ lam
            impulse = -spd_solve(delassus, vel)
            funcs = {"rhs": ca.Function(f"rhs_{name}", [x, u], [ca.vertcat(v, acc)]),
                     "acc": acc,
                     "force": ca.Function(f"force_{name}", [x, u], [lam]),
                     "delassus": ca.Function(f"delassus_{name}", [x], [delassus]),
                     "impact": ca.Function(f"impact_{name}", [x],
                                           [ca.vertcat(self.cls.q, v + minv_j @ impulse),
                                            impulse])}
        self._cache[closed] = funcs
        return funcs

    def rhs(self, closed: tuple[int, ...]) -> ca.Function:
        return self._stance(closed)["rhs"]

    def force(self, closed: tuple[int, ...]) -> ca.Function:
        """(x, u) -> the closed contacts' forces [N], per contact lambda_n then lambda_t."""
        return self._stance(closed)["force"]

    def acceleration(self, closed: tuple[int, ...]) -> ca.Function:
        """(x, u) -> the acceleration a of stance `closed` (explicit form)."""
        key = (closed, "acceleration")
        if key not in self._cache:
            self._cache[key] = ca.Function("acceleration", [self._x, self._u],
                                           [self._stance(closed)["acc"]])
        return self._cache[key]

    def inverse(self, closed: tuple[int, ...]) -> ca.Function:
        """(x, u, a, lambda) -> (M a - f - J_S lambda, J_S^T a + (dJ_S/dt)^T v + stab):
        zero where a and lambda are stance `closed`'s acceleration and forces (the
        inverse-dynamics form: linear in a and lambda, no M^-1)."""
        key = (closed, "inverse")
        if key not in self._cache:
            cls = self.cls
            a = ca.SX.sym("a", cls.n_q)
            lam = ca.SX.sym("lambda", sum(self.sizes(closed)))
            rows = ca.mtimes(cls.mass_matrix, a) - cls.forces
            if closed:
                jac = self._terms(closed)[0]
                rows = ca.vertcat(rows - ca.mtimes(jac, lam), self._held(closed, a))
            self._cache[key] = ca.Function("inverse", [self._x, self._u, a, lam], [rows])
        return self._cache[key]

    def delassus(self, closed: tuple[int, ...]) -> ca.Function:
        """x -> J_S^T M^-1 J_S of a stance with closed contacts."""
        return self._stance(closed)["delassus"]

    def impact(self, closed: tuple[int, ...]) -> ca.Function:
        """x- -> (x+, impulses [N s]) of an inelastic impact leaving S at rest."""
        return self._stance(closed)["impact"]

    def opening(self, closed: tuple[int, ...], i: int) -> ca.Function:
        """(x, u) -> contact i's normal acceleration n_i^T a + (dn_i/dt)^T v under stance
        `closed` (>= 0: it opens)."""
        key = (closed, "opening", i)
        if key not in self._cache:
            value = self.normal_acceleration(i)(self._x, self._stance(closed)["acc"])
            self._cache[key] = ca.Function(f"opening_{i}", [self._x, self._u], [value])
        return self._cache[key]

    def normal_acceleration(self, i: int) -> ca.Function:
        """(x, a) -> contact i's normal acceleration n_i^T a + (dn_i/dt)^T v."""
        key = ("normal_acceleration", i)
        if key not in self._cache:
            q, v = self.cls.q, self.cls.v
            normal = self.cls.contacts[i].normal
            a = ca.SX.sym("a", self.cls.n_q)
            value = ca.mtimes(normal.T, a) + ca.jacobian(ca.mtimes(normal.T, v), q) @ v
            self._cache[key] = ca.Function(f"normal_acceleration_{i}", [self._x, a], [value])
        return self._cache[key]

    def sizes(self, closed: tuple[int, ...]) -> list[int]:
        """Force components of each closed contact (1 + its tangents)."""
        return [self.columns[i].shape[1] for i in closed]

    def rk4(self, closed: tuple[int, ...], steps: int) -> ca.Function:
        """`steps` RK4 steps of length h / steps under stance `closed` as one SX function
        (x, u, h) -> x+ (called from the NLP's MX graph: expanding every node's steps into
        one SX graph took more than 15 GB for bolt)."""
        key = (closed, "rk4", steps)
        if key not in self._cache:
            f = self.rhs(closed)
            x = ca.SX.sym("x", self._x.shape[0])
            u = ca.SX.sym("u", self._u.shape[0])
            h = ca.SX.sym("h")
            end = x
            for _ in range(steps):
                k1 = f(end, u)
                k2 = f(end + h / (2 * steps) * k1, u)
                k3 = f(end + h / (2 * steps) * k2, u)
                k4 = f(end + h / steps * k3, u)
                end = end + h / (6 * steps) * (k1 + 2 * k2 + 2 * k3 + k4)
            self._cache[key] = ca.Function(f"rk4_{len(self._cache)}", [x, u, h], [end])
        return self._cache[key]

    def shooting(self, closed: tuple[int, ...], steps: int) -> ca.Function:
        """`shooting_function` of `rk4(closed, steps)`, built once."""
        key = (closed, "shooting", steps)
        if key not in self._cache:
            self._cache[key] = shooting_function(self.rk4(closed, steps),
                                                 f"shooting_{len(self._cache)}")
        return self._cache[key]

    def lifted(self, closed: tuple[int, ...]) -> ca.Function:
        """(x, u, lambda) -> ((v, a), J_S^T a + (dJ_S/dt)^T v + stab) with
        a = M^-1 (f + J_S lambda): the forces-lifted form of stance `closed` (one M(q)
        solve, no Delassus inverse); its second output is zero where lambda is the stance's
        force."""
        key = (closed, "lifted")
        if key not in self._cache:
            jac = self._terms(closed)[0]
            lam = ca.SX.sym("lambda", jac.shape[1])
            acc = self.cls.solve_mass(self.cls.forces + ca.mtimes(jac, lam))
            self._cache[key] = ca.Function(
                f"lifted_{len(self._cache)}", [self._x, self._u, lam],
                [ca.vertcat(self.cls.v, acc), self._held(closed, acc)])
        return self._cache[key]

    def lifted_collocation(self, closed: tuple[int, ...], tableau) -> ca.Function:
        """(x, z_1..z_s, lambda_1..lambda_s, u, h) -> one Radau element's collocation
        equations under `lifted(closed)` and the stance's rows at each stage, zero at a
        solution; built once."""
        key = (closed, "lifted_collocation", tableau.stages)
        if key not in self._cache:
            n_x, n_lam = self._x.shape[0], sum(self.sizes(closed))
            x = ca.SX.sym("x", n_x)
            stages = [ca.SX.sym(f"z{j}", n_x) for j in range(tableau.stages)]
            forces = [ca.SX.sym(f"lambda{j}", n_lam) for j in range(tableau.stages)]
            u, h = ca.SX.sym("u", self._u.shape[0]), ca.SX.sym("h")
            terms = [self.lifted(closed)(z, u, lam)
                     for z, lam in zip(stages, forces, strict=True)]
            rows = collocation_rows(tableau, x, stages, [slope for slope, _ in terms], h)
            self._cache[key] = ca.Function(
                f"lifted_collocation_{len(self._cache)}", [x, *stages, *forces, u, h],
                [ca.vertcat(*rows, *[row for _, row in terms])])
        return self._cache[key]

    def collocation(self, closed: tuple[int, ...], tableau) -> ca.Function:
        """`collocation_function` of `rhs(closed)`, built once."""
        key = (closed, "collocation", tableau.stages)
        if key not in self._cache:
            self._cache[key] = collocation_function(self.rhs(closed), tableau,
                                                    f"collocation_{len(self._cache)}")
        return self._cache[key]


def interior_weights(collocation_points, count: int) -> np.ndarray:
    """Weights (count s, s + 1) of the interior points of a collocation element: `count`
    equally spaced points between each two consecutive points of 0, c_1, ..., c_s
    (fractions of the element), each row the Lagrange basis through those points there, so
    that a row's weights times (x_start, stage_1, ..., stage_s) is the collocation
    polynomial's state at that point."""
    nodes = np.concatenate([[0.0], np.asarray(collocation_points, dtype=float)])
    points = [a + (b - a) * m / (count + 1) for a, b in itertools.pairwise(nodes)
              for m in range(1, count + 1)]
    return np.array([lagrange_weights(nodes, tau) for tau in points])


def cone_rows(values, sizes: list[int], mu: list[float], closed: tuple[int, ...],
              margin: float, keep_normal: bool = False, facets: int | None = None,
              floor: float = 0.0) -> list:
    """Expressions >= 0 that hold the closed contacts' forces (or impulses) in their cones:
    lambda_n - floor >= 0 and (c mu lambda_n)^2 - ||lambda_t||^2 >= 0, or with `facets`
    the inscribed pyramid's c mu cos(pi / n) lambda_n - d_k . lambda_t >= 0 for the n
    facets' normals d_k (planar: c mu lambda_n -+ lambda_t >= 0). Where the linear rows
    imply lambda_n >= 0 (c mu > 0, planar or a pyramid) and `floor` is 0, no row
    lambda_n >= 0: at a vanishing force or impulse, a soft landing's, the rows were all
    active and dependent; `keep_normal` keeps it, for measuring violations. Numbers or
    CasADi expressions."""
    rows = []
    offset = 0
    for size, i in zip(sizes, closed, strict=True):
        normal = values[offset]
        implied = margin * mu[i] > 0 and (size == 2 or (size == 3 and facets is not None))
        if keep_normal or floor > 0 or not implied:
            rows.append(normal - floor)
        if size == 2:
            rows += [margin * mu[i] * normal - values[offset + 1],
                     margin * mu[i] * normal + values[offset + 1]]
        elif size == 3 and facets is not None:
            inner = margin * mu[i] * math.cos(math.pi / facets)
            for k in range(facets):
                angle = 2 * math.pi * k / facets
                rows.append(inner * normal - math.cos(angle) * values[offset + 1]
                            - math.sin(angle) * values[offset + 2])
        elif size == 3:
            tangential = values[offset + 1:offset + 3]
            rows.append((margin * mu[i] * normal) ** 2 - ca.sumsqr(tangential))
        offset += size
    return rows


@dataclass(frozen=True, eq=False)
class StancePlan:
    """A plan with the exact hybrid dynamics along a fixed sequence of stances.

    Attributes:
        stances: the sequence with the re-solved touchdown times.
        t, x: node times [s] and states (q, v), (n_nodes, 2 n_q); a touchdown has two
            nodes at its time (before and after the impact).
        u: controls per interval, (N, n_u); boundary_states: (q, v) at the control
            jumps, (N + 1, 2 n_q).
        cost, ipopt_status, iterations, solve_time (build and solve [s]),
        verification: the multi-contact reference's checks.
        swing_rows_dropped: the swing-height rows made the NLP infeasible and this plan
            was solved without them (`StanceOptions.swing_fallback`); iterations and
            solve_time count both solves.
        timing: where the solve's time went and the NLP's size (None: not measured; of
            the last NLP when the swing rows were dropped).
    """

    stances: tuple[Stance, ...]
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    boundary_states: np.ndarray
    cost: float
    ipopt_status: str
    iterations: int
    solve_time: float
    verification: Verification
    swing_rows_dropped: bool = False
    timing: NlpTiming | None = None

    @property
    def solved(self) -> bool:
        return self.ipopt_status in SOLVED

    @property
    def status(self) -> str:
        if not self.solved:
            return "nlp_failed"
        return "converged" if self.verification.passed else "verification_failed"

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def summary(self) -> str:
        stances = ", ".join(f"{list(s.closed)} {s.start:.4f}-{s.end:.4f} s"
                            for s in self.stances)
        return "\n".join([
            f"stances: {self.status} (IPOPT {self.ipopt_status}, {self.iterations} "
            f"iterations, {self.solve_time:.1f} s), objective {self.cost:.6g}",
            f"stances: closed contacts {stances}",
            *(["stances: the swing-height rows made the NLP infeasible; solved without "
               "them"] if self.swing_rows_dropped else []),
            *([] if self.timing is None else [f"stances: {self.timing.summary()}"]),
            f"stances: {self.verification.summary()}",
        ])


def sequence_changes(stances: Sequence[Any], horizon: float, n_intervals: int
                     ) -> tuple[dict[int, int], list[int]]:
    """Check the changes of a contact sequence and sort them: each change either closes
    contacts (a touchdown, at a free time) or opens them (a lift-off, at a control jump
    k T / N inside the horizon). `stances`: objects with `start` [s] and `closed` (contact
    indices, or a task's frame names: the messages name what they hold).

    Returns:
        lift_offs: control jump k -> index of the stance the lift-off starts.
        touchdowns: indices of the stances started by a touchdown.
    """
    dt = horizon / n_intervals
    lift_offs: dict[int, int] = {}
    touchdowns: list[int] = []
    for j, (before, after) in enumerate(itertools.pairwise(stances), start=1):
        closes = set(after.closed) - set(before.closed)
        opens = set(before.closed) - set(after.closed)
        if bool(closes) == bool(opens):
            raise InvalidInput(
                f"the stance at {after.start:g} s must either close contacts (a touchdown) "
                f"or open them (a lift-off), not {'both' if closes else 'neither'}: "
                f"{list(before.closed)} -> {list(after.closed)}; put one change after the "
                "other")
        if closes:
            touchdowns.append(j)
            continue
        k = round(after.start / dt)
        if abs(after.start - k * dt) > 1e-9 * horizon or not 0 < k < n_intervals:
            raise InvalidInput(
                f"the lift-off of {sorted(opens)} at {after.start:g} s is not at a control "
                f"jump k T / N inside the horizon (T / N = {dt:g} s): move it to one, e.g. "
                f"{min(max(k, 1), n_intervals - 1) * dt:g} s")
        lift_offs[k] = j
    return lift_offs, touchdowns


def resolve_stances(problem: ContactProblem, stances: tuple[Stance, ...],
                    options: StanceOptions | None = None, *,
                    guess: ContactResult | tuple[np.ndarray, np.ndarray, np.ndarray],
                    verbose: bool = True) -> StancePlan:
    """Re-solve a contact OCP along a sequence of stances with the exact hybrid dynamics
    (module docstring), warm started from a guess, and verify it with the multi-contact
    reference.

    Args:
        problem: the `ContactProblem` (its system supplies the dynamics; its bounds, path
            and terminal constraints and cost are kept).
        stances: the sequence (`stance_schedule`, `schedule_of`); consecutive stances
            differ by touchdowns (contacts added) or lift-offs (removed, at a control
            jump), not both.
        guess: a time-freezing plan or (t, x, u): node times [s], states (n, 2 n_q) and
            controls (N, n_u).
        verbose: print the NLP's outcome and the summary.
    """
    options = options or StanceOptions()
    stances = tuple(stances)
    system = problem.system
    cls = system.cls
    n_q, n_u = cls.n_q, cls.n_u
    n_int, horizon = problem.n_intervals, problem.horizon
    dt = horizon / n_int
    lift_offs, touchdowns = sequence_changes(stances, horizon, n_int)
    # the first stance's contacts stick from t = 0: they must touch at the start
    start_gaps = np.asarray(cls.function("gaps")(problem.q0), dtype=float).ravel()
    apart = [i for i in stances[0].closed if abs(start_gaps[i]) > options.contact_gap]
    if apart:
        raise InvalidInput(
            f"the first stance closes contacts {apart}, but the start has them "
            f"{', '.join(f'{start_gaps[i]:.3g}' for i in apart)} m from the ground "
            f"(more than contact_gap = {options.contact_gap:g} m): start with them on the "
            "ground, or open them in the first stance (a touchdown later)")
    start = time.perf_counter()
    dyn = StanceDynamics(cls, options.baumgarte)
    tableau = (RadauIIA(options.radau_stages).tableau() if options.integrator == "radau"
               else None)
    if isinstance(guess, ContactResult):
        phys = guess.physical
        guess = (phys.t, phys.y[:, state_indices(guess.system)], guess.u)
    guess_t, guess_x, guess_u = (np.asarray(a, dtype=float) for a in guess)
    for s in stances:  # the forces of a stance must be unique (not a box on two corners)
        if not s.closed:
            continue
        w = np.asarray(dyn.delassus(s.closed)(interpolate(guess_t, guess_x,
                                                            0.5 * (s.start + s.end))))
        if np.linalg.cond(w) > SINGULAR_DELASSUS:
            raise InvalidInput(
                f"the contacts {list(s.closed)} closed together are statically indeterminate "
                f"(their Delassus matrix is singular, condition {np.linalg.cond(w):.1e}): the "
                "stance re-solve needs contact constraints independent of each other (legs "
                "with joints, not a rigid body on two corners)")
    functions = NodeFunctions.of(problem)
    y_of, path, path_fn = functions.y_of, functions.path, functions.path_fn
    running, terminal_cost = functions.running, functions.terminal_cost
    terminal, terminal_fn = functions.terminal, functions.terminal_fn
    lower, upper = functions.lower, functions.upper
    bounded = [int(i) for i in np.flatnonzero(np.isfinite(lower) | np.isfinite(upper))]
    gains = options.open_slip_gains or (None,) * cls.n_contacts
    heights = options.swing_heights or (None,) * cls.n_contacts
    for name, given in (("open_slip_gains", gains), ("swing_heights", heights)):
        if len(given) != cls.n_contacts:
            raise InvalidInput(f"`{name}` has {len(given)} entries for {cls.n_contacts} "
                               "contacts")

    opti = ca.Opti()
    repeated = (RepeatedRows(opti)
                if options.element_derivatives and not options.inverse_dynamics else None)
    controls = opti.variable(n_int, n_u) if n_u else ca.MX(n_int, 0)
    if n_u:
        opti.subject_to(opti.bounded(np.tile(problem.u_lower, (n_int, 1)), controls,
                                     np.tile(problem.u_upper, (n_int, 1))))
        opti.set_initial(controls, np.clip(guess_u, problem.u_lower, problem.u_upper))
    grid = [k * dt for k in range(n_int + 1)]
    # each touchdown: a free fraction of the control interval its guess lies in
    switch_at: dict[int, list[tuple[ca.MX, int]]] = {}
    switch_times: dict[int, ca.MX] = {}
    for j in touchdowns:
        k = int(np.clip(math.floor(stances[j].start / dt), 0, n_int - 1))
        m = options.switch_margin
        fraction = opti.variable()
        opti.subject_to(opti.bounded(m, fraction, 1 - m))
        opti.set_initial(fraction, float(np.clip(stances[j].start / dt - k, m, 1 - m)))
        if switch_at.get(k):
            opti.subject_to(fraction - switch_at[k][-1][0] >= m)
        switch_at.setdefault(k, []).append((fraction, j))
        switch_times[j] = grid[k] + fraction * dt

    def lifted_force(x, u, closed):
        """lambda of stance `closed` at the node x under u as NLP variables (none for a
        flight), initialised by the explicit form at the node's initial guess."""
        if not closed:
            return ca.MX(0, 1)
        lam = opti.variable(sum(dyn.sizes(closed)))
        x_init, u_init = (opti.value(e, opti.initial()) for e in (x, u))
        opti.set_initial(lam, dyn.force(closed)(x_init, u_init))
        return lam

    def lifted_terms(x, u, closed):
        """(a, lambda) of stance `closed` at the node x under u in the inverse-dynamics
        form: NLP variables bound by its rows, initialised by the explicit form at the
        node's initial guess."""
        a = opti.variable(n_q)
        lam = lifted_force(x, u, closed)
        opti.subject_to(dyn.inverse(closed)(x, u, a, lam) == 0)
        x_init, u_init = (opti.value(e, opti.initial()) for e in (x, u))
        opti.set_initial(a, dyn.acceleration(closed)(x_init, u_init))
        return a, lam

    # With element derivatives, a node's path rows (if free of the time) and its contacts'
    # rows are repeated rows: one function each (per stance and switching contacts).
    path_rows = None if repeated is None else functions.path_rows()
    contact_functions: dict = {}

    def constrain_node(x, t, u, closed, force=None, switching=frozenset()):
        if bounded:
            opti.subject_to(opti.bounded(lower[bounded], x[bounded], upper[bounded]))
        if path_rows is not None:
            function, low, up = path_rows
            repeated.bounded(low, function, up, x, u)
        elif path_fn is not None:
            size = path.expression.shape[0]
            opti.subject_to(opti.bounded(np.broadcast_to(path.lower, size),
                                         path_fn(y_of(x, t), u),
                                         np.broadcast_to(path.upper, size)))
        contact_rows(x, u, closed, force, switching)

    def open_rows(x, closed, switching) -> list:
        """The open contacts' rows at node x as expressions >= 0 (`contact_rows`)."""
        open_ = [i for i in range(cls.n_contacts) if i not in closed and i not in switching]
        rows = [dyn.gaps(x)[open_]] if open_ else []
        for i in open_:
            if gains[i] is not None:  # no skimming: v_t = 0 where the gap is zero
                rows.append(gains[i] * dyn.gaps(x)[i] - dyn.slip_squared(x)[i])
        return rows

    def contact_rows(x, u, closed, force=None, switching=frozenset()):
        """The stance's rows at node x. `switching`: open contacts at their switch (the
        node of a touchdown's gap_i = 0 before its impact, or of a lift-off), whose open
        rows are left out there: gap_i >= 0 would repeat the touchdown's equality, and
        at zero gap K gap_i - ||v_t||^2 >= 0 holds only with v_t = 0, a row whose gradient
        in v vanishes there (its multiplier unbounded: IPOPT's convergence suffers)."""
        if repeated is not None and force is None:
            key = (tuple(closed), frozenset(switching))
            if key not in contact_functions:
                xs, us = ca.SX.sym("x", 2 * n_q), ca.SX.sym("u", n_u)
                rows = open_rows(xs, closed, switching)
                if closed:
                    rows += cone_rows(dyn.force(closed)(xs, us), dyn.sizes(closed), dyn.mu,
                                      closed, options.cone_margin,
                                      facets=options.cone_facets,
                                      floor=options.min_normal_force)
                contact_functions[key] = bounded_rows(
                    f"contact_rows_{len(contact_functions)}", [xs, us],
                    [(0.0, row, np.inf) for row in rows])
            function, low, up = contact_functions[key]
            if function.numel_out(0):
                repeated.bounded(low, function, up, x, u)
            return
        for row in open_rows(x, closed, switching):
            opti.subject_to(row >= 0)
        if closed:
            if force is not None:
                lam = force
            elif options.inverse_dynamics:
                lam = lifted_terms(x, u, closed)[1]
            else:
                lam = dyn.force(closed)(x, u)
            for row in cone_rows(lam, dyn.sizes(closed), dyn.mu, closed,
                                 options.cone_margin, facets=options.cone_facets,
                                 floor=options.min_normal_force):
                opti.subject_to(row >= 0)

    interior_functions: dict = {}
    interior = (interior_weights(tableau.c, options.interior_rows)
                if tableau is not None and options.interior_rows else None)

    def interior_contact_rows(x_start, stages, u, closed):
        """The closed contacts' rows at the interior points of one element, its states
        from the collocation polynomial through x_start and the stage states."""
        if not closed:
            return
        key = tuple(closed)
        if key not in interior_functions:
            xs = [ca.SX.sym(f"x{j}", 2 * n_q) for j in range(len(stages) + 1)]
            us = ca.SX.sym("u", n_u)
            rows = []
            for weights in interior:
                z = sum(w * xj for w, xj in zip(weights, xs, strict=True))
                rows += cone_rows(dyn.force(closed)(z, us), dyn.sizes(closed), dyn.mu,
                                  closed, options.cone_margin, facets=options.cone_facets,
                                  floor=options.min_normal_force)
            interior_functions[key] = bounded_rows(
                f"interior_rows_{len(interior_functions)}", [*xs, us],
                [(0.0, row, np.inf) for row in rows])
        function, low, up = interior_functions[key]
        if repeated is not None:
            repeated.bounded(low, function, up, x_start, *stages, u)
        else:
            opti.subject_to(opti.bounded(low, function(x_start, *stages, u), up))

    x0 = np.concatenate([problem.q0, problem.v0])
    x = opti.variable(2 * n_q)
    opti.subject_to(x == x0)
    opti.set_initial(x, x0)
    nodes = [(0.0, x)]
    boundary = [x]
    cost = 0
    current = 0  # the stance in force
    for k in range(n_int):
        u_k = controls[k, :].T
        if k in lift_offs:  # the control jump opens contacts: they accelerate away
            j = lift_offs[k]
            lifting = set(stances[j - 1].closed) - set(stances[j].closed)
            if options.inverse_dynamics:
                acc, lam = lifted_terms(x, u_k, stances[j].closed)
                openings = [dyn.normal_acceleration(i)(x, acc) for i in lifting]
            else:
                lam = None
                openings = [dyn.opening(stances[j].closed, i)(x, u_k) for i in lifting]
            for opening in openings:
                opti.subject_to(opening >= 0)
            current = j
            contact_rows(x, u_k, stances[current].closed, lam, frozenset(lifting))
        elif k > 0:  # the stance holds on both sides of the control jump
            contact_rows(x, u_k, stances[current].closed)
        cuts = ([(grid[k], grid[k], None)]
                + [(switch_times[j], stances[j].start, j) for _, j in switch_at.get(k, [])]
                + [(grid[k + 1], grid[k + 1], None)])
        for (ta, ga, _), (tb, gb, jb) in itertools.pairwise(cuts):
            closed = stances[current].closed
            # the contacts touching down at this piece's end
            landing = (frozenset() if jb is None
                       else frozenset(stances[jb].closed) - frozenset(closed))
            n_steps = max(1 if tableau is not None else 2,
                          round(options.nodes * (gb - ga) / dt))
            h = (tb - ta) / n_steps
            if repeated is not None and isinstance(h, ca.MX):
                h_steps = opti.variable()  # a variable: the steps are then repeated rows
                opti.subject_to(h_steps == h)
                opti.set_initial(h_steps, (gb - ga) / n_steps)
                h = h_steps
            for i in range(n_steps):
                t0 = ta + i * h
                if tableau is not None:  # one collocation element, its last stage its end
                    stages = []
                    for j in range(tableau.stages):
                        z = opti.variable(2 * n_q)
                        opti.set_initial(z, interpolate(
                            guess_t, guess_x, ga + (i + tableau.c[j]) * (gb - ga) / n_steps,
                            left_limit=True))
                        stages.append(z)
                    if options.inverse_dynamics:
                        terms = [lifted_terms(z, u_k, closed) for z in stages]
                        residuals = collocation_rows(
                            tableau, x, stages, [ca.vertcat(z[n_q:], a)
                                                 for z, (a, _) in zip(stages, terms,
                                                                      strict=True)], h)
                        forces = [lam for _, lam in terms]
                    elif options.lifted_forces and closed:
                        forces = [lifted_force(z, u_k, closed) for z in stages]
                        function = dyn.lifted_collocation(closed, tableau)
                        if repeated is not None:
                            repeated.zero(function, x, *stages, *forces, u_k, h)
                        else:
                            opti.subject_to(function(x, *stages, *forces, u_k, h) == 0)
                        residuals = [None] * len(stages)
                    elif repeated is not None:
                        repeated.zero(dyn.collocation(closed, tableau), x, *stages, u_k, h)
                        residuals = [None] * len(stages)
                        forces = [None] * len(stages)
                    else:
                        residuals = collocation_residuals(dyn.rhs(closed), tableau, x,
                                                          stages, u_k, h)
                        forces = [None] * len(stages)
                    for j, (z, residual) in enumerate(zip(stages, residuals, strict=True)):
                        if residual is not None:
                            opti.subject_to(residual == 0)
                        t_stage = t0 + tableau.c[j] * h
                        cost = cost + h * tableau.b[j] * running(y_of(z, t_stage), u_k)
                        last = i == n_steps - 1 and j == tableau.stages - 1
                        nodes.append((tb if last else t_stage, z))
                        constrain_node(z, t_stage, u_k, closed, forces[j],
                                       landing if last else frozenset())
                    if interior is not None:
                        interior_contact_rows(x, stages, u_k, closed)
                    x = stages[-1]
                    continue
                x_start = x
                x = opti.variable(2 * n_q)
                if repeated is not None:
                    repeated.zero(dyn.shooting(closed, options.steps_per_node), x_start, u_k,
                                  h, x)
                    x_next = x
                else:
                    x_next = dyn.rk4(closed, options.steps_per_node)(x_start, u_k, h)
                    opti.subject_to(x == x_next)
                cost = cost + h / 2 * (running(y_of(x_start, t0), u_k)
                                       + running(y_of(x_next, t0 + h), u_k))
                opti.set_initial(x, interpolate(guess_t, guess_x,
                                                 ga + (i + 1) * (gb - ga) / n_steps,
                                                 left_limit=True))
                t_node = tb if i == n_steps - 1 else t0 + h
                nodes.append((t_node, x))
                constrain_node(x, t_node, u_k, closed, None,
                               landing if i == n_steps - 1 else frozenset())
            if jb is None:
                continue
            # a touchdown: the new contacts reach the ground, all closed ones end at rest
            after = stances[jb].closed
            for i in set(after) - set(closed):
                opti.subject_to(dyn.gaps(x)[i] == 0)
                if options.touchdown_speed is not None:
                    opti.subject_to(dyn.normal_velocities(x)[i] <= -options.touchdown_speed)
            post, impulse = dyn.impact(after)(x)
            for row in cone_rows(impulse, dyn.sizes(after), dyn.mu, after,
                                 options.cone_margin, facets=options.cone_facets):
                opti.subject_to(row >= 0)
            x = opti.variable(2 * n_q)
            opti.subject_to(x == post)
            opti.set_initial(x, interpolate(guess_t, guess_x, gb + 1e-6))
            nodes.append((tb, x))
            current = jb
            constrain_node(x, tb, u_k, after)
        boundary.append(x)
    if any(h is not None for h in heights):
        node_t = np.array([float(opti.value(tn, opti.initial())) if isinstance(tn, ca.MX)
                           else float(tn) for tn, _ in nodes])
        guess_q = np.array([interpolate(guess_t, guess_x, at)[:n_q] for at in node_t])
        guess_gaps = np.asarray(cls.function("gaps")(guess_q.T)).T.reshape(len(node_t), -1)
        for i, h in enumerate(heights):
            if h is None:
                continue
            for begin, end in swings(stances, i, horizon):
                inside = np.flatnonzero((node_t > begin) & (node_t < end))
                if not inside.size:
                    continue
                if guess_gaps[inside, i].max() >= h:
                    at = inside[np.argmax(guess_gaps[inside, i])]
                elif options.swing_middle:
                    at = inside[np.argmin(np.abs(node_t[inside] - (begin + end) / 2))]
                else:
                    continue
                opti.subject_to(dyn.gaps(nodes[at][1])[i] >= h)
    y_end = y_of(x, horizon)
    for goal in problem.goals if options.end_height_rows else ():
        if isinstance(goal, EndHeight):  # half the goal's tolerance: a margin for its check
            opti.subject_to(opti.bounded(goal.height - goal.tolerance / 2,
                                         goal.lowest(x[:n_q]),
                                         goal.height + goal.tolerance / 2))
    if terminal_fn is not None:
        size = terminal.expression.shape[0]
        opti.subject_to(opti.bounded(np.broadcast_to(terminal.lower, size), terminal_fn(y_end),
                                     np.broadcast_to(terminal.upper, size)))
    opti.minimize(cost + terminal_cost(y_end))
    # the lifted NLP expands into one SX graph cheaply (bolt's walk: 0.5 GB); the explicit
    # form's did not (more than 15 GB with RK4: `StanceDynamics.rk4`)
    plugin = {"print_time": False, "record_time": True, "expand": options.inverse_dynamics,
              **({} if repeated is None else repeated.derivative_options(options.threads))}
    ipopt = {"tol": options.tol, "max_iter": options.max_iter, "mu_strategy": options.barrier,
             "print_level": 0, "sb": "yes", **stall_stop(options.stall_iterations)}
    iterations = 0
    build_time = time.perf_counter() - start
    evaluation_time = ipopt_time = 0.0
    restarts_left = {CAPPED: options.capped_restarts, STEP_ERROR: options.step_error_restarts}
    while True:
        stop = ipopt_solver(opti, plugin, ipopt)  # kept: CasADi borrows it
        if verbose:
            report_progress(stop)
        sol, building, in_ipopt, evaluations = solve_timed(opti, options.blas_threads)
        build_time += building  # each solve builds its solver
        ipopt_time += in_ipopt
        evaluation_time += evaluations
        stats = sol.stats()
        status = str(stats.get("return_status", "unknown"))
        iterations += int(stats.get("iter_count", 0))
        if not restarts_left.get(status):
            break
        restarts_left[status] -= 1
        # the same NLP again from this primal-dual iterate, IPOPT's state (barrier, filter,
        # regularisation) fresh: a cold restart pushed the iterate back into the interior
        # (bolt's walk: objective 3.2 -> 6.8)
        if verbose:
            print(f"stances: IPOPT stopped ({status}); solving again from its iterate "
                  f"({restarts_left[status]} more such restarts allowed)", flush=True)
        opti.set_initial(sol.value_variables())
        opti.set_initial(opti.lam_g, sol.value(opti.lam_g))
        ipopt.update(warm_start_init_point="yes", mu_init=RESTART_PUSH,
                     warm_start_bound_push=RESTART_PUSH, warm_start_mult_bound_push=RESTART_PUSH)
    if (status == INFEASIBLE and options.swing_fallback
            and any(h is not None for h in heights)):
        first = time.perf_counter() - start
        if verbose:
            print("stances: the swing-height rows made the NLP infeasible; solving it "
                  "again without them", flush=True)
        again = resolve_stances(problem, stances, dataclasses.replace(options,
                                                                      swing_heights=()),
                                guess=guess, verbose=verbose)
        return dataclasses.replace(again, swing_rows_dropped=True,
                                   iterations=again.iterations + iterations,
                                   solve_time=again.solve_time + first)
    u_value = (np.asarray(sol.value(controls)).reshape(n_int, n_u) if n_u
               else np.zeros((n_int, 0)))
    node_x = np.array([np.asarray(sol.value(xn)).ravel() for _, xn in nodes])
    times = np.array([float(sol.value(tn)) if isinstance(tn, ca.MX) else float(tn)
                      for tn, _ in nodes])
    boundary_x = np.array([np.asarray(sol.value(b)).ravel() for b in boundary])
    solved_stances = []
    for j, s in enumerate(stances):
        begin = float(sol.value(switch_times[j])) if j in switch_times else s.start
        solved_stances.append(Stance(s.closed, begin, s.end))
    solved_stances = tuple(Stance(s.closed, s.start, nxt.start) for s, nxt in
                           zip(solved_stances, solved_stances[1:], strict=False)) + (
        Stance(solved_stances[-1].closed, solved_stances[-1].start, horizon),)
    solve_time = time.perf_counter() - start
    verification = verify_stances(problem, solved_stances, times, node_x, u_value,
                                  boundary_x, options)
    plan = StancePlan(stances=solved_stances, t=times, x=node_x, u=u_value,
                      boundary_states=boundary_x, cost=float(sol.value(opti.f)),
                      ipopt_status=status, iterations=iterations, solve_time=solve_time,
                      verification=verification,
                      timing=NlpTiming(build_time, ipopt_time, evaluation_time, int(opti.nx),
                                       int(opti.ng)))
    if verbose:
        print(plan.summary(), flush=True)
    return plan


def verify_stances(problem: ContactProblem, stances: tuple[Stance, ...], t: np.ndarray,
                   x: np.ndarray, u: np.ndarray, boundary_states: np.ndarray,
                   options: StanceOptions | None = None) -> Verification:
    """The checks of a stance plan given by its arrays: the multi-contact reference
    replays the controls open loop from the start and restarts on each control interval
    from the plan's state (local defects; an open-loop unstable plan passes on them with
    the kicked replay's amplification, `end_state_check`; a replay that stopped, or whose
    kicked replays stop on their way to T, is judged where it left the plan,
    `departure_check`); the gaps at the nodes; the
    closed contacts' forces in their cones (recomputed from the nodes' states and
    controls) and the node times non-decreasing up to the horizon."""
    options = options or StanceOptions()
    cls = problem.system.cls
    n_int, horizon = problem.n_intervals, problem.horizon
    t, x, u = (np.asarray(a, dtype=float) for a in (t, x, u))
    boundary_states = np.asarray(boundary_states, dtype=float)
    if boundary_states.shape != (n_int + 1, 2 * cls.n_q) or u.shape != (n_int, cls.n_u):
        raise InvalidInput(f"`boundary_states` {boundary_states.shape} and `u` {u.shape} do "
                           f"not fit the problem ({n_int + 1}, {2 * cls.n_q}), "
                           f"({n_int}, {cls.n_u})")
    clocks = np.arange(n_int + 1) * horizon / n_int
    x0 = np.concatenate([problem.q0, problem.v0])
    replayed = ReplayedPlan(cls=cls, x0=x0, clocks=clocks, states=boundary_states,
                            controls=u, horizon=horizon)
    simulation = MultiContactOptions(start_gap_tolerance=max(options.gap_tolerance, 1e-12),
                                     velocity_tolerance=RESTART_VELOCITY_TOLERANCE,
                                     contact_tolerance=options.contact_tolerance)
    budget = EvaluationBudget(options.budget)
    notes: list[str] = []
    sim = replay_multicontact(cls, x0, clocks, u, horizon,
                              options=budget.options(simulation))
    budget.spend(sim.n_rhs)
    defects = multicontact_local_defects(replayed, [(k, k + 1) for k in range(n_int)],
                                         options.gap_tolerance, simulation, budget)
    if budget.skipped:
        notes.append(f"the reference used up its budget of {options.budget} model "
                     f"evaluations: {budget.skipped} local-defect restarts not run")
    dyn = StanceDynamics(cls, options.baumgarte)
    settle = dyn.impact(stances[0].closed) if stances[0].closed else None

    def replay_to(start: np.ndarray, boundary: int) -> np.ndarray:
        if settle is not None:
            # a kicked start velocity as the contacts down at the start take it (the
            # inelastic impact leaving them at rest): a kick that moves a standing foot
            # into or off the ground is no perturbation of the plan's motion, and the
            # reference chattered on solo12's four feet until it stopped
            start = np.asarray(settle(start)[0], dtype=float).ravel()
        kicked = replay_multicontact(cls, start, clocks[:boundary + 1], u[:boundary],
                                     horizon if boundary == n_int else float(clocks[boundary]),
                                     options=EvaluationBudget(options.budget).options(
                                         simulation))
        if not kicked.success:
            raise SolveFailed(f"kicked multi-contact replay stopped: {kicked.message}", kicked)
        return kicked.final_state()

    stopped = parted = None
    if sim.success:
        deviation = sim.deviation_at(horizon, boundary_states[-1])
        reference_end = sim.final_state()
        times = np.round([imp.time for imp in sim.impacts], 4).tolist()
        method = (f"event-driven multi-contact reference (DOP853, contact LCPs, inelastic "
                  f"frictional impacts), {len(times)} impacts at t = {times} s, "
                  f"{len(sim.events)} contact-mode changes")
        # where it left the plan, should a kicked replay to T stop (`end_state_check`)
        parted = stopped_replay(sim, replayed, replay_to)
    else:
        deviation, reference_end = math.inf, None
        method = "event-driven multi-contact reference (stopped)"
        notes.append(f"multi-contact reference stopped at t = {sim.t[-1]:.6g} s: "
                     f"{sim.message}")
        stopped = stopped_replay(sim, replayed, replay_to)

    end_ok, defect_sum, amplification = end_state_check(
        replayed, options.end_state_tolerance, deviation, defects, reference_end, notes,
        lambda start: replay_to(start, n_int), stopped, parted)
    min_gap = float(np.min(np.asarray(dyn.gaps(x.T))))
    # the closed contacts' forces at both ends of each segment between two nodes
    starts = np.array([s.start for s in stances])
    worst, largest = 0.0, 0.0
    dt = horizon / n_int
    for i in range(len(t) - 1):
        if t[i + 1] <= t[i]:
            continue
        middle = 0.5 * (t[i] + t[i + 1])
        closed = stances[int(np.searchsorted(starts, middle)) - 1].closed
        if not closed:
            continue
        u_k = u[min(int(middle / dt), n_int - 1)]
        for j in (i, i + 1):
            lam = np.asarray(dyn.force(closed)(x[j], u_k)).ravel()
            rows = cone_rows(lam, dyn.sizes(closed), dyn.mu, closed, 1.0, keep_normal=True)
            worst = max(worst, -min(float(r) for r in rows))
            largest = max(largest, float(np.max(np.abs(lam))))
    node_t = t
    monotone = bool(np.all(np.diff(node_t) >= 0.0))
    end_error = abs(float(node_t[-1]) - horizon)
    cone_ok = worst <= options.cone_tolerance * max(largest, 1e-12)
    notes.append(f"cone and normal forces checked at the nodes: worst violation {worst:.2e}"
                 f" against the largest force {largest:.3g} N")
    passed = (end_ok and min_gap >= -options.gap_tolerance and cone_ok and monotone
              and end_error <= 1e-9 * horizon)
    return Verification(
        passed=bool(passed), method=method, end_state_deviation=deviation, min_gap=min_gap,
        friction_cone_violation=worst, clock_monotone=monotone, clock_end_error=end_error,
        tolerances={"end_state": options.end_state_tolerance, "gap": options.gap_tolerance,
                    "cone": options.cone_tolerance},
        notes=tuple(notes), dissipation_violation=float("nan"), local_defects=defects,
        defect_sum=defect_sum, open_loop_amplification=amplification,
        open_loop_unstable=bool(end_ok and deviation > options.end_state_tolerance))


def node_values(plan: StancePlan, cls, baumgarte: float = StanceOptions.baumgarte
                ) -> dict[str, np.ndarray]:
    """Per node of a stance plan: `closed` (n, n_contacts) which contacts are closed, the
    control `u` that drives it, `gap` and `normal_velocity` per contact, and per contact
    the `force` (lambda_n, lambda_t...) [N] of the stance (zero when open) and the
    `impulse` (Lambda_n, Lambda_t...) [N s] of a touchdown at its post-impact node, both
    padded to (n, n_contacts, 3). A node's stance and control are those of the segment
    that ends at it (the first node: the first stance's and control's); a post-impact
    node is in the stance that starts there."""
    dyn = StanceDynamics(cls, baumgarte)
    t, x, u = plan.t, plan.x, plan.u
    n, n_c = len(t), cls.n_contacts
    n_int = len(u)
    horizon = plan.stances[-1].end
    dt = horizon / n_int
    starts = np.array([s.start for s in plan.stances])
    closed_mask = np.zeros((n, n_c), dtype=bool)
    controls = np.zeros((n, u.shape[1]))
    forces = np.zeros((n, n_c, 3))
    impulses = np.zeros((n, n_c, 3))

    def scatter(target: np.ndarray, values, closed: tuple[int, ...]) -> None:
        values = np.asarray(values, dtype=float).ravel()
        offset = 0
        for size, i in zip(dyn.sizes(closed), closed, strict=True):
            target[i, :size] = values[offset:offset + size]
            offset += size

    for k in range(n):
        touchdown = k > 0 and t[k] == t[k - 1]
        at = t[0] if k == 0 else (t[k] if touchdown else 0.5 * (t[k - 1] + t[k]))
        closed = plan.stances[max(int(np.searchsorted(starts, at, side="right")) - 1, 0)].closed
        controls[k] = u[min(int(at / dt), n_int - 1)]
        closed_mask[k, list(closed)] = True
        if touchdown:
            scatter(impulses[k], dyn.impact(closed)(x[k - 1])[1], closed)
        if closed:
            scatter(forces[k], dyn.force(closed)(x[k], controls[k]), closed)
    velocities = np.asarray(dyn.normal_velocities(x.T)).T
    return {"closed": closed_mask, "u": controls,
            "gap": np.asarray(dyn.gaps(x.T)).T.reshape(n, n_c),
            "normal_velocity": velocities.reshape(n, n_c), "force": forces,
            "impulse": impulses}
