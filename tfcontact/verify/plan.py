"""The checks of a time-freezing plan (`check_time_freezing_plan`), given as arrays
(`TimeFreezingPlan`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.fesd.tableau import Tableau
from tfcontact.mpcc import Homotopy, Ipopt
from tfcontact.timefreezing import FROZEN_RATE_TOL, PhysicalTrajectory, TimeFreezingSystem
from tfcontact.verify.checks import (
    SLIP_THRESHOLD,
    clock_checks,
    collocation_impulses,
    coulomb_split,
    friction_cone_violation,
    impulse_freedom,
    maximal_dissipation_violation,
    painleve_note,
)
from tfcontact.verify.options import VerifyOptions
from tfcontact.verify.replay import ReplayedPlan, defect_segments, end_state_check, local_defects
from tfcontact.verify.result import Verification


def state_indices(system: TimeFreezingSystem) -> list[int]:
    """The entries (q, v) of the time-freezing state y, in that order."""
    return (list(range(system.q_index.start, system.q_index.stop))
            + list(range(system.v_index.start, system.v_index.stop)))


@dataclass(frozen=True, eq=False)
class TimeFreezingPlan:
    """What the checks read of a time-freezing plan computed by FESD collocation.

    The numerical time tau has E finite elements, N_FE per control interval, N control
    intervals; y = the time-freezing state (q, v, the clock t, ...).

    Attributes:
        system: the time-freezing system the plan was solved with (its CLS is the
            original system the checks use; with speed of time and cost state).
        start: the start state x0 = (q0, v0), (2 n_q,).
        horizon: the physical horizon T [s]; tau_horizon: the numerical one [s].
        tau: (E + 1,) element boundary times [s]; x: (E + 1, n_y) states there.
        x_stages: (E, s, n_y) stage states; h: (E,) element lengths [s].
        tableau: the collocation `Tableau` (A, b) of the plan's scheme.
        x_intervals: (N + 1, n_y) states at the control-interval boundaries.
        u: (N, n_u + 1) controls per interval, the physical ones and the speed of time.
        n_finite_elements: N_FE.
        physical: the plan in physical time (`to_physical_time`).
        homotopy, nlp: the MPCC settings the plan was solved with (`FesdReplay` uses them).

    Raises:
        InvalidInput: arrays whose shapes do not fit together.
    """

    system: TimeFreezingSystem
    start: np.ndarray
    horizon: float
    tau_horizon: float
    tau: np.ndarray
    x: np.ndarray
    x_stages: np.ndarray
    h: np.ndarray
    tableau: Tableau
    x_intervals: np.ndarray
    u: np.ndarray
    n_finite_elements: int
    physical: PhysicalTrajectory
    homotopy: Homotopy
    nlp: Ipopt

    def __post_init__(self) -> None:
        n_el, n_int = len(self.h), len(self.u)
        n_y = self.system.n_y
        expected = {"tau": (self.tau.shape, (n_el + 1,)), "x": (self.x.shape, (n_el + 1, n_y)),
                    "x_stages": (self.x_stages.shape[::2], (n_el, n_y)),
                    "x_intervals": (self.x_intervals.shape, (n_int + 1, n_y))}
        for name, (shape, wanted) in expected.items():
            if shape != wanted:
                raise InvalidInput(f"`{name}` has shape {shape}, expected {wanted} "
                                   f"({n_el} elements, {n_int} intervals, n_y = {n_y})")
        if n_el != n_int * self.n_finite_elements:
            raise InvalidInput(f"{n_el} finite elements for {n_int} intervals of "
                               f"`n_finite_elements` = {self.n_finite_elements}")

    @property
    def state_indices(self) -> list[int]:
        """The entries (q, v) of y."""
        return state_indices(self.system)

    @property
    def end_state(self) -> np.ndarray:
        """(q, v) at the end of the plan."""
        return self.x[-1, self.state_indices]

    @property
    def running(self) -> np.ndarray:
        """(E,) the finite elements where the clock runs (the others are frozen pieces)."""
        clock = self.system.clock_index
        return np.diff(self.x[:, clock]) > FROZEN_RATE_TOL * np.diff(self.tau)

    def replayed(self) -> ReplayedPlan:
        """The plan's physical controls between its clock values at the control-interval
        boundaries (k T / N with the stagewise clock constraint), for the replays."""
        return ReplayedPlan(
            cls=self.system.cls, x0=self.start,
            clocks=self.x_intervals[:, self.system.clock_index],
            states=self.x_intervals[:, self.state_indices],
            controls=self.u[:, :self.system.cls.n_u], horizon=self.horizon)

    def local_defects(self, gap_tolerance: float) -> tuple[float, ...]:
        """The local defects (`tfcontact.verify.local_defects`), the segments cut at the
        control-interval boundaries that hold a physical state (`defect_segments`); a
        restart may lie `gap_tolerance` [m] inside an obstacle."""
        replayed = self.replayed()
        return local_defects(replayed, defect_segments(replayed.clocks, ~self.running),
                             gap_tolerance)


def check_time_freezing_plan(plan: TimeFreezingPlan,
                             options: VerifyOptions | None = None) -> Verification:
    """The independent checks of a time-freezing plan (see `Verification`).

    Re-simulates the plan's physical controls (`options.replay`: the event-detecting
    reference of the original system with impacts, the event-driven multi-contact
    simulator for several frictional inelastic contacts, or the FESD simulator on a finer
    grid) and compares the end states (with the reference, an open-loop unstable plan may pass
    on its local defects instead, see `end_state_check`); checks the gaps on the plan, the
    friction cone of the contact impulses recovered from the momentum balance on the
    plan's collocation polynomials (M v' - f_v t' = J^T lambda, using the CLS's own M, f_v
    and contact directions, not the time-freezing modes), Coulomb's maximal dissipation of
    those impulses where a closed contact slips (B^T v at the elements' starts, stages and
    ends) and the clock.

    Main args:
        plan: the `TimeFreezingPlan`.
        options: the `VerifyOptions` (default: `VerifyOptions()`).

    Raises:
        TfcontactError: `ExactReplay()` where its simulator does not apply or stops,
            `MultiContactReplay()` where it does not apply (a multi-contact simulation
            that stops is judged where it left the plan, `departure_check`, its status
            in the notes).
    """
    options = options if options is not None else VerifyOptions()
    system = plan.system
    cls = system.cls
    notes: list[str] = []
    running = plan.running
    outcome = options.replay.run(plan, options.gap_tolerance, notes)
    deviation, method, defects = outcome.deviation, outcome.method, outcome.local_defects
    # Gaps on the physical plan only: inside a frozen piece an elastic auxiliary spring
    # runs *inside* the obstacle by construction (the clock stands still there).
    gap_fn = cls.function("gaps")
    gaps = plan.physical.gaps
    stage_q = plan.x_stages[running][:, :, system.q_index].reshape(-1, system.q_index.stop
                                                                   - system.q_index.start)
    stage_gaps = np.asarray(gap_fn(stage_q.T)).T if stage_q.size else gaps
    min_gap = float(min(gaps.min(), stage_gaps.min()))

    # Contact impulses from the momentum balance on the plan's collocation polynomials.
    n_u = cls.n_u
    n_fe = plan.n_finite_elements
    u = np.repeat(plan.u[:, :n_u], n_fe, axis=0)
    mass = cls.function("mass")
    forces = cls.function("forces")
    normals = cls.function("normals")
    tangents = [cls.function(f"tangents_{i}") for i in range(cls.n_contacts)]

    def jac(qk: np.ndarray) -> np.ndarray:
        # Only closed contacts (gap within tolerance) can push: the columns of open ones
        # are zero, so their impulses are 0 and opposite walls cannot cancel each other.
        cols = []
        nrm = np.asarray(normals(qk))
        closed = np.asarray(gap_fn(qk)).ravel() <= options.gap_tolerance
        for i in range(cls.n_contacts):
            cols.append(nrm[:, i : i + 1] * closed[i])
            if cls.contacts[i].n_tangents:
                cols.append(np.asarray(tangents[i](qk)) * closed[i])
        return np.hstack(cols)

    tableau = plan.tableau
    impulses, fit = collocation_impulses(
        plan.x[:-1], plan.x_stages, plan.h, tableau.A, tableau.b, u,
        (system.q_index, system.v_index, system.clock_index),
        mass_matrix=lambda qk: np.asarray(mass(qk)),
        smooth_force=lambda qk, vk, uk: np.asarray(forces(qk, vk, uk)).reshape(-1),
        contact_jacobian=jac,
    )
    mu, n_tangents = [c.mu for c in cls.contacts], [c.n_tangents for c in cls.contacts]
    normal_columns = np.cumsum([0] + [1 + c.n_tangents for c in cls.contacts])[:-1]
    # The tolerance's scale from the minimum-norm impulses: the split below cannot raise it.
    largest_normal = float(np.max(impulses[:, normal_columns], initial=0.0))
    impulse_tolerance = options.cone_tolerance * max(largest_normal, 1e-12)
    notes.append(f"friction-cone tolerance: {options.cone_tolerance:g} x the largest normal "
                 f"impulse {largest_normal:.3g} N s")
    # The slip B_i^T v of each contact at every sample of every element; an open contact
    # has no friction to check, so its slip is zeroed and the check skips it.
    samples = np.concatenate([plan.x[:-1, None], plan.x_stages, plan.x[1:, None]], axis=1)
    flat = samples.reshape(-1, samples.shape[-1])
    q_samples, v_samples = flat[:, system.q_index], flat[:, system.v_index]
    closed = np.asarray(gap_fn(q_samples.T)).T <= options.gap_tolerance
    slips = [np.zeros((len(flat), 0))]
    for i, contact in enumerate(cls.contacts):
        if contact.n_tangents:
            slip_i = np.array([np.asarray(tangents[i](qk)).T @ vk
                               for qk, vk in zip(q_samples, v_samples, strict=True)])
            slips.append(slip_i * closed[:, i : i + 1])
    slip = np.hstack(slips).reshape(*samples.shape[:2], sum(c.n_tangents for c in cls.contacts))
    painleve = painleve_note(cls, q_samples, closed)
    if painleve:
        notes.append(painleve)
    # Statically indeterminate contacts: Coulomb's law holds if SOME split of the impulse
    # that the momentum balance admits obeys it (`coulomb_split`); single contacts keep theirs.
    impulses = coulomb_split(impulses, impulse_freedom(plan.x_stages, plan.h, tableau.b,
                                                       system.q_index, jac),
                             mu, n_tangents, slip)
    cone = friction_cone_violation(impulses, mu, n_tangents)
    dissipation, n_slipping = maximal_dissipation_violation(impulses, slip, mu, n_tangents)
    notes.append(f"maximal dissipation checked on {n_slipping} slipping element-contacts "
                 f"(|B^T v| > {SLIP_THRESHOLD:g} m/s throughout, one direction)")
    monotone, clock_error = clock_checks(plan.x[:, system.clock_index], plan.horizon,
                                         options.clock_tolerance)
    # What the closed contacts cannot explain is the discretisation error of the plan (or a
    # force the model lacks); report it on the same relative scale as the cone check.
    unexplained = float(np.max(fit, initial=0.0))
    if unexplained > impulse_tolerance:
        notes.append(f"momentum balance not explained by the contacts up to "
                     f"{unexplained:.2e} N s")
    tolerances = {"end_state": options.end_state_tolerance, "gap": options.gap_tolerance,
                  "cone": options.cone_tolerance, "dissipation": options.cone_tolerance,
                  "clock": options.clock_tolerance}
    end_state_ok, defect_sum, amplification = end_state_check(
        plan.replayed(), options.end_state_tolerance, deviation, defects,
        outcome.reference_end, notes, outcome.replay_end, outcome.stopped, outcome.parted)
    passed = (end_state_ok and min_gap >= -options.gap_tolerance
              and cone <= impulse_tolerance and dissipation <= impulse_tolerance
              and monotone and clock_error <= options.clock_tolerance)
    return Verification(
        passed=bool(passed),
        method=method,
        end_state_deviation=deviation, min_gap=min_gap, friction_cone_violation=cone,
        clock_monotone=monotone, clock_end_error=clock_error, tolerances=tolerances,
        notes=tuple(notes), dissipation_violation=dissipation, local_defects=defects,
        defect_sum=defect_sum, open_loop_amplification=amplification,
        open_loop_unstable=bool(end_state_ok and deviation > options.end_state_tolerance),
    )
