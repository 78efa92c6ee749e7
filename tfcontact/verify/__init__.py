"""tfcontact.verify: independent checks of a plan against the ORIGINAL rigid-body system.

A plan is computed on a time-freezing reformulation; these checks use only the original
complementarity Lagrangian system (M(q), smooth forces, gaps, contact directions, exact
impacts), never the time-freezing modes, so that an error in those modes shows up here.

* `simulate_impacts`, `replay_controls`: an event-detecting simulator of the original
  system with exact impacts (`tfcontact.verify.reference`).

Layering: `tfcontact.verify` reads the time-freezing layer (the CLS) and nothing above it;
`tfcontact.ocp` calls it, and it never imports `tfcontact.ocp`.
"""

from tfcontact.verify.reference import (
    END_GAP_TOLERANCE,
    ReferenceImpact,
    ReferenceSimulation,
    StackedFunction,
    planar_impulse_flow,
    replay_controls,
    simulate_impacts,
)

__all__ = [
    "END_GAP_TOLERANCE",
    "ReferenceImpact",
    "ReferenceSimulation",
    "StackedFunction",
    "planar_impulse_flow",
    "replay_controls",
    "simulate_impacts",
]
