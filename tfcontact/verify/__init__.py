"""tfcontact.verify: independent checks of a plan against the ORIGINAL rigid-body system.

A plan is computed on a time-freezing reformulation; these checks use only the original
complementarity Lagrangian system (M(q), smooth forces, gaps, contact directions, exact
impacts), never the time-freezing modes, so that an error in those modes shows up here.

* `simulate_impacts`, `replay_controls`: an event-detecting simulator of the original
  system with exact impacts (`tfcontact.verify.reference`).
* the physical checks (`tfcontact.verify.checks`): contact impulses recovered from the
  momentum balance (`contact_impulses`, `collocation_impulses`), the friction cone, Coulomb's
  maximal dissipation, the clock, Painleve's ill-posed contacts.
* replays of a plan's controls (`tfcontact.verify.replay`): the open-loop end-state
  deviation, the local defects per control interval, the open-loop amplification.
* `Verification`: the outcome of the checks of one plan.

Layering: `tfcontact.verify` reads the time-freezing layer (the CLS) and nothing above it;
`tfcontact.ocp` calls it, and it never imports `tfcontact.ocp`.
"""

from tfcontact.verify.checks import (
    SLIP_THRESHOLD,
    clock_checks,
    collocation_impulses,
    contact_impulses,
    friction_cone_violation,
    maximal_dissipation_violation,
    painleve_note,
)
from tfcontact.verify.reference import (
    END_GAP_TOLERANCE,
    ReferenceImpact,
    ReferenceSimulation,
    StackedFunction,
    planar_impulse_flow,
    replay_controls,
    simulate_impacts,
)
from tfcontact.verify.replay import (
    LOCAL_DEFECT_IMPACT_WINDOW,
    SENSITIVITY_KICK,
    ReplayedPlan,
    defect_segments,
    end_state_check,
    local_defects,
    open_loop_sensitivity,
    reference_deviation,
)
from tfcontact.verify.result import Verification

__all__ = [
    "END_GAP_TOLERANCE",
    "LOCAL_DEFECT_IMPACT_WINDOW",
    "SENSITIVITY_KICK",
    "SLIP_THRESHOLD",
    "ReferenceImpact",
    "ReferenceSimulation",
    "ReplayedPlan",
    "StackedFunction",
    "Verification",
    "clock_checks",
    "collocation_impulses",
    "contact_impulses",
    "defect_segments",
    "end_state_check",
    "friction_cone_violation",
    "local_defects",
    "maximal_dissipation_violation",
    "open_loop_sensitivity",
    "painleve_note",
    "planar_impulse_flow",
    "reference_deviation",
    "replay_controls",
    "simulate_impacts",
]
