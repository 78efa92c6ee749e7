"""Replays of a plan's controls with the exact-impact reference, and what they measure.

A plan is replayed open loop from its start (`reference_deviation`: the end-state
deviation), and restarted from its own state at each control-interval boundary that holds
a physical state (`local_defects`: where the plan itself is wrong). When the open-loop
replay parts from the plan but the local defects are small, the replay's sensitivity to a
kick of its start velocities (`open_loop_sensitivity`) tells whether the dynamics amplify
the plan's local errors (`end_state_check`). The plan is given as arrays
(`ReplayedPlan`), whatever method computed it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tfcontact.errors import SolveFailed, TfcontactError
from tfcontact.timefreezing import ComplementarityLagrangianSystem
from tfcontact.verify.reference import replay_controls

START_ROUNDOFF = 1e-9
"""A plan's start may lie this far inside an obstacle [m] in its open-loop replay: the
round-off of a start put on the ground by hand (a task's joint angles and surface height
written to ten digits left finger_edu's tip 5e-12 m inside its table)."""


@dataclass(frozen=True, eq=False)
class ReplayedPlan:
    """What the replay checks read of a plan: its physical controls on a grid of clock
    values, its states there and its start.

    Attributes:
        cls: the original system (impacts, friction).
        x0: the start state (q0, v0).
        clocks: physical times of the control-interval boundaries, (N + 1,).
        states: the plan's (q, v) at those boundaries, (N + 1, 2 n_q).
        controls: the physical controls per interval, (N, n_u).
        horizon: the physical horizon T [s].
    """

    cls: ComplementarityLagrangianSystem
    x0: np.ndarray
    clocks: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    horizon: float

    def replay(self, x0: np.ndarray | None = None):
        """The controls replayed by the event-detecting reference from x0 (default: the
        plan's start), which may lie `START_ROUNDOFF` inside an obstacle."""
        return replay_controls(self.cls, self.x0 if x0 is None else x0, self.clocks,
                               self.controls, self.horizon, rtol=1e-10, atol=1e-11,
                               start_gap_tolerance=START_ROUNDOFF)


def reference_deviation(plan: ReplayedPlan, end_state: np.ndarray,
                         window: float = 0.0) -> tuple[float, str, np.ndarray]:
    """End-state deviation of the plan from the event-detecting reference simulation, the
    method's description and the reference's state at T. An impact of the reference
    within `window` of T counts on either side of it."""
    reference = plan.replay()
    if reference.status != "success":
        raise SolveFailed(f"reference simulation stopped: {reference.message}", reference)
    deviation, side = reference.deviation_at(plan.horizon, end_state, window)
    times = np.round(reference.impact_times, 4).tolist()
    method = (f"event-detecting reference (DOP853, exact impacts), {len(times)} impacts at "
              f"t = {times} s")
    if reference.end_impacts:
        method += f", and one at T (the plan ends {side or 'before'} it)"
    return deviation, method, reference.x[-1]


LOCAL_DEFECT_IMPACT_WINDOW = 0.01
"""An impact within this fraction of a control interval of a segment's end counts on
either side of it in the local defects (`Verification.local_defects`)."""

SENSITIVITY_KICK = 1e-3
"""The open-loop amplification replays start with every velocity moved by this fraction of
the end-state tolerance (`Verification.open_loop_amplification`)."""


def defect_segments(clocks: np.ndarray, frozen: np.ndarray) -> list[tuple[int, int]]:
    """The (first, last + 1) control intervals of the local defects' segments.

    A segment starts at a boundary that holds a physical state and runs to the next one.
    A boundary with frozen finite elements on both sides is in the middle of an impact (no
    physical state equals it), and one the clock has not moved to since the segment's
    start adds nothing to check: the segment runs on past both.
    """
    n_int = len(clocks) - 1
    by_interval = frozen.reshape(n_int, -1)
    mid_impact = np.zeros(n_int + 1, dtype=bool)
    mid_impact[1:-1] = by_interval[:-1, -1] & by_interval[1:, 0]
    segments: list[tuple[int, int]] = []
    start = 0
    for k in range(1, n_int + 1):
        still = clocks[k] - clocks[start] <= 1e-12
        if k < n_int and (mid_impact[k] or still):
            continue
        if k == n_int and still and segments:  # the plan ends frozen: extend the last one
            start = segments.pop()[0]
        segments.append((start, k))
        start = k
    return segments


def local_defects(plan: ReplayedPlan, segments: list[tuple[int, int]],
                   gap_tolerance: float) -> tuple[float, ...]:
    """Per control interval: the deviation at its end of the reference restarted from the
    plan's own state at its segment's start (`defect_segments`) and run with the plan's
    controls; nan where the segment runs on, inf where the reference could not simulate
    it (a jam, a start it rejects)."""
    clocks, states = plan.clocks, plan.states
    defects = np.full(len(clocks) - 1, np.nan)
    for first, end in segments:
        duration = clocks[end] - clocks[first]
        if duration <= 1e-12:
            continue  # the whole plan frozen: nothing physical to compare
        # Run a little past the segment's end, so that an impact the plan puts on the
        # boundary and the reference just after it is compared on both sides.
        window = LOCAL_DEFECT_IMPACT_WINDOW * duration / (end - first)
        try:
            local = replay_controls(plan.cls, states[first],
                                    clocks[first:end + 1] - clocks[first],
                                    plan.controls[first:end], float(duration + window),
                                    rtol=1e-10, atol=1e-11, start_gap_tolerance=gap_tolerance,
                                    max_rhs_evaluations=200_000 * (end - first))
        except TfcontactError:
            local = None
        if local is None or local.status != "success":
            defects[end - 1] = np.inf
            continue
        defects[end - 1] = local.deviation_at(duration, states[end], window)[0]
    return tuple(float(d) for d in defects)


ReplayEnd = Callable[[np.ndarray], "np.ndarray | None"]
"""A replay of the plan's controls from another start x0 -> its state at T; what
`end_state_check` kicks. None: the replay stopped (a jam: counted as infinitely
sensitive); raising `TfcontactError`: it could not be measured (the check then fails)."""


ReplayTo = Callable[[np.ndarray, int], "np.ndarray | None"]
"""A replay of the plan's controls from another start x0 up to control-interval boundary
k -> its state there; None and raising as for `ReplayEnd`."""


@dataclass(frozen=True, eq=False)
class StoppedReplay:
    """An open-loop replay that stopped before T (it chattered, hit its event cap or its
    budget), as far as it got: what `end_state_check` reads of it (also of a replay that
    ran to T, at the boundaries before T: its `parted`).

    Attributes:
        stop_time: where it stopped [s].
        deviations: its deviation (inf norm) from the plan's state at each control-interval
            boundary it passed, boundary 0 first, (k + 1,).
        states: its state at those boundaries, (k + 1, 2 n_q).
        replay_to: the same replay from another start up to a boundary (`ReplayTo`).
    """

    stop_time: float
    deviations: np.ndarray
    states: np.ndarray
    replay_to: ReplayTo


def exact_replay_end(plan: ReplayedPlan) -> ReplayEnd:
    """The exact-impact reference's `ReplayEnd` of `plan`."""
    def end(x0: np.ndarray) -> np.ndarray | None:
        try:
            replayed = plan.replay(x0)
        except TfcontactError:
            return None
        return replayed.x[-1] if replayed.status == "success" else None
    return end


def open_loop_sensitivity(plan: ReplayedPlan, reference_end: np.ndarray,
                          kick: float, replay_end: ReplayEnd | None = None) -> float:
    """How far the replay's end state moves when every start velocity moves by +-kick
    (the larger of the two; inf if a kicked replay stops, nan if one could not be
    measured). `replay_end`: the replay that is kicked (default: the exact-impact
    reference, `exact_replay_end`)."""
    replay_end = exact_replay_end(plan) if replay_end is None else replay_end
    n_q = plan.cls.n_q
    moved = []
    for sign in (1.0, -1.0):
        x0 = plan.x0.copy()
        x0[n_q:] += sign * kick
        try:
            end = replay_end(x0)
        except TfcontactError:
            return float("nan")
        if end is None:
            return float("inf")
        moved.append(float(np.max(np.abs(end - reference_end))))
    return max(moved)


def end_state_check(plan: ReplayedPlan, tolerance: float, deviation: float,
                     local_defects: tuple[float, ...], reference_end: np.ndarray | None,
                     notes: list[str], replay_end: ReplayEnd | None = None,
                     stopped: StoppedReplay | None = None,
                     parted: StoppedReplay | None = None) -> tuple[bool, float, float]:
    """(passed, sum of the local defects, open-loop amplification) of the end-state check.

    The open-loop replay from x0 passes within `tolerance`. Otherwise the plan still
    passes when the dynamics, not the plan, make the replay part from it: the local
    defects sum to within the tolerance (the replay could end at most that far away if
    the dynamics did not amplify errors), and the replay's measured sensitivity to a kick
    of its start velocities (end moved / kick), times the defects' sum, reaches the
    deviation. `replay_end` is the replay kicked (default: the exact-impact reference);
    `reference_end` its end from the plan's start (None: no replay to kick).

    A replay that stopped before T (`stopped`, with no `reference_end`) is judged where
    it left the plan (`departure_check`): a replay that has already parted from the plan
    may chatter where the plan does not go. So is a replay that ran to T when a kicked
    replay stops on its way there (the amplification to T cannot be measured), given that
    replay at the boundaries before T (`parted`, as `stopped_replay` reads it): on a
    planar solo12's gait the replay ran to T 1.0 from the plan with local defects summing
    to 2.1e-3, and a kicked replay stopped after the feet had parted from the plan's.
    """
    tol = tolerance
    defects = np.asarray(local_defects, dtype=float)
    checked = defects[~np.isnan(defects)]
    defect_sum = float(checked.sum()) if checked.size else float("nan")
    if deviation <= tol:
        return True, defect_sum, float("nan")
    if not defect_sum <= tol:
        return False, defect_sum, float("nan")
    if reference_end is None:
        if stopped is None:
            return False, defect_sum, float("nan")
        passed, amplification = departure_check(plan, tol, defects, stopped, notes)
        return passed, defect_sum, amplification
    lead = (f"open-loop replay {deviation:.2e} from the plan, local defects sum to "
            f"{defect_sum:.2e}")
    passed, amplification = amplified(plan, tol, deviation, defect_sum, reference_end,
                                      replay_end, notes, lead)
    if np.isnan(amplification) and parted is not None:
        notes.pop()  # the kick to T could not be measured: judged where the replay left
        passed, amplification = departure_check(
            plan, tol, defects, parted, notes,
            lead=f"{lead}; a replay with kicked start velocities stopped before T, so the "
                 "plan is judged where the open-loop replay left it")
    return passed, defect_sum, amplification


def amplified(plan: ReplayedPlan, tolerance: float, deviation: float, defect_sum: float,
              reference: np.ndarray, replay: ReplayEnd | None, notes: list[str],
              lead: str) -> tuple[bool, float]:
    """(passed, amplification): whether the replay's measured sensitivity to a kick of its
    start velocities (`open_loop_sensitivity` about `reference`, the replay's state where
    it is compared), times `defect_sum`, reaches `deviation`; the note starts with `lead`."""
    kick = SENSITIVITY_KICK * tolerance
    sensitivity = open_loop_sensitivity(plan, reference, kick, replay)
    amplification = sensitivity / kick
    if np.isnan(sensitivity):
        notes.append(f"{lead}; a replay with kicked start velocities stopped, so the "
                     "amplification is not measured and the end-state check fails")
        return False, amplification
    explained = amplification * defect_sum >= deviation
    notes.append(
        f"{lead}; start velocities kicked by {kick:.0e} move the replay there by "
        f"{sensitivity:.2e} (x{amplification:.3g}): "
        + ("the dynamics amplify the plan's local errors (open-loop unstable), the "
           "end-state check passes on the local defects" if explained else
           "that does not account for the deviation, the end-state check fails"))
    return bool(explained), amplification

def departure_check(plan: ReplayedPlan, tolerance: float, local_defects: np.ndarray,
                    stopped: StoppedReplay, notes: list[str], lead: str | None = None
                    ) -> tuple[bool, float]:
    """(passed, open-loop amplification) of the end-state check of a replay that stopped
    before T, made at the first control-interval boundary k where it was already more
    than `tolerance` from the plan: the replay's sensitivity to a kick of its start
    velocities up to boundary k, times the local defects of the intervals before k, must
    reach its deviation there. From k on the replay no longer follows the plan, so where
    it stopped says nothing about the plan; the plan after k is still checked by its
    local defects (the caller requires all of them to sum to within the tolerance). A
    replay that stopped while still within the tolerance fails: the plan's own motion
    may be what it could not simulate. `lead`: the note's start (default: where the
    replay stopped)."""
    tol = tolerance
    beyond = np.flatnonzero(stopped.deviations > tol)
    stop = lead or f"the open-loop replay stopped at t = {stopped.stop_time:.4g} s"
    if not beyond.size:
        largest = float(np.max(stopped.deviations, initial=0.0))
        notes.append(f"{stop}, within {largest:.2e} of the plan at each of the "
                     f"{len(stopped.deviations)} control-interval boundaries it passed: the "
                     "plan's own motion may be what it could not simulate, the end-state "
                     "check fails")
        return False, float("nan")
    k = int(beyond[0])
    if k == 0:
        notes.append(f"{stop}; it started {stopped.deviations[0]:.2e} from the plan's first "
                     "state, the end-state check fails")
        return False, float("nan")
    before = local_defects[:k]
    before_sum = float(np.sum(before[~np.isnan(before)]))
    return amplified(
        plan, tol, float(stopped.deviations[k]), before_sum, stopped.states[k],
        lambda x0: stopped.replay_to(x0, k), notes,
        f"{stop}{', after leaving the plan' if lead is None else ''}: "
        f"{stopped.deviations[k]:.2e} from it at "
        f"t = {plan.clocks[k]:.4g} s (boundary {k}), where the local defects before sum "
        f"to {before_sum:.2e}")
