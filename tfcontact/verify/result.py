"""The outcome of the independent checks of one plan (`Verification`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np


@dataclass(frozen=True)
class Verification:
    """The outcome of the independent checks of one plan.

    Attributes:
        passed: every check below within its tolerance. The end state passes when the
            open-loop replay ends within its tolerance, or, for a plan whose dynamics
            amplify errors, when `defect_sum` is within it and `open_loop_amplification`
            times `defect_sum` reaches the replay's deviation.
        method: how the plan was re-simulated.
        end_state_deviation: ||x_plan(T) - x_resimulated(T)|| (inf norm) [state units].
        min_gap: the smallest contact gap over the plan [m]; penetration is negative.
        friction_cone_violation: max over contacts and sample intervals of
            max(|Lambda_t| - mu Lambda_n, -Lambda_n, 0) for the contact impulses
            Lambda recovered from the velocity change [N s].
        clock_monotone: the clock never runs backwards.
        clock_end_error: |t(T_numerical) - T_physical| [s].
        tolerances: the tolerance of each check, by name.
        notes: what was not or could not be checked.
        dissipation_violation: max over the elements where a contact slips of
            ||Lambda_t + mu Lambda_n d|| (d the unit slip direction), Coulomb's maximal
            dissipation (see `maximal_dissipation_violation`) [N s]; nan: not checked.
        local_defects: per control interval k, the deviation at its end of the exact
            reference restarted from the plan's own state at the interval's start (inf
            norm) [state units]: where the plan itself is wrong, free of the open-loop
            growth of errors that the end-state deviation also measures. A boundary
            inside an impact holds no physical state: the restart there is skipped and
            the interval's entry is nan, the next entry covers both intervals. inf: the
            reference could not simulate the interval; empty: not computed.
        defect_sum: the sum of the local defects (nan: none computed; inf: one could
            not be simulated). Without amplification of errors by the dynamics, the
            open-loop replay would end at most this far from the plan.
        open_loop_amplification: measured only when the open-loop replay fails and
            `defect_sum` is within the end-state tolerance: how far the replay's end
            moves when every start velocity is kicked by 1e-3 x the tolerance (the larger
            of + and -), divided by the kick [-]; nan: not measured. The end state passes
            if amplification x `defect_sum` reaches the open-loop deviation: the plan is
            locally right and open-loop unstable (a legged robot balancing on a point
            foot, a hopper after several impacts). For a replay that stopped before T
            (`end_state_deviation` inf), measured up to the control-interval boundary
            where it left the plan (`departure_check`).
        open_loop_unstable: the end-state check passed that way (on `defect_sum`), not on
            the open-loop replay.
    """

    passed: bool
    method: str
    end_state_deviation: float
    min_gap: float
    friction_cone_violation: float
    clock_monotone: bool
    clock_end_error: float
    tolerances: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    dissipation_violation: float = float("nan")
    local_defects: tuple[float, ...] = ()
    defect_sum: float = float("nan")
    open_loop_amplification: float = float("nan")
    open_loop_unstable: bool = False

    def to_dict(self) -> dict:
        out = asdict(self)
        out["notes"] = list(self.notes)
        out["local_defects"] = list(self.local_defects)
        return out

    def summary(self) -> str:
        tol = self.tolerances
        flag = "PASSED" if self.passed else "FAILED"
        route = ""
        if self.open_loop_unstable:
            route = ("; open-loop unstable, passed on the local defects"
                     if np.isfinite(self.end_state_deviation) else
                     "; the replay left the plan, then stopped: open-loop unstable, passed "
                     "on the local defects")
        return (
            f"verification {flag} ({self.method}): end-state deviation "
            f"{self.end_state_deviation:.2e} (tol {tol.get('end_state', float('nan')):.0e}"
            f"{route}), "
            f"min gap {self.min_gap:+.2e} m (tol -{tol.get('gap', float('nan')):.0e}), "
            f"friction-cone violation {self.friction_cone_violation:.2e} N s, "
            f"maximal-dissipation violation {self.dissipation_violation:.2e} N s, "
            f"clock {'monotone' if self.clock_monotone else 'NOT monotone'}, "
            f"clock end error {self.clock_end_error:.2e} s{self._defect_text()}"
        )

    def _defect_text(self) -> str:
        defects = np.asarray(self.local_defects, dtype=float)
        if not np.any(np.isfinite(defects)):
            return ""
        k = int(np.nanargmax(defects))
        text = (f"; largest local defect {defects[k]:.2e} (interval {k + 1} of "
                f"{defects.size}), sum {self.defect_sum:.2e}")
        if not np.isnan(self.open_loop_amplification):
            text += f"; open-loop amplification {self.open_loop_amplification:.3g}"
        return text
