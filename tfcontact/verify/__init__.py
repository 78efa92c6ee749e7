"""tfcontact.verify: independent checks of a plan against the ORIGINAL rigid-body system.

A plan is computed on a time-freezing reformulation; these checks use only the original
complementarity Lagrangian system (M(q), smooth forces, gaps, contact directions, exact
impacts), never the time-freezing modes, so that an error in those modes shows up here.

Entry point: `check_time_freezing_plan(plan, options=VerifyOptions(...))` ->
`Verification`, for a time-freezing plan given as arrays (`TimeFreezingPlan`). The replay
method is a strategy object of `VerifyOptions.replay`: `ExactReplay()`,
`MultiContactReplay()`, `FesdReplay(refinement=4, scheme=RadauIIA(3),
relaxation=Scholtes())` or `AutoReplay(fallback=FesdReplay())` (the exact replay, else the
multi-contact one for several frictional inelastic contacts, else the fallback).

Parts, usable on their own (e.g. by the exact re-solve `tfcontact.ocp.polish`):

* `simulate_impacts`, `replay_controls` (`tfcontact.verify.reference`): an event-detecting
  simulator of the original system with exact impacts.
* `simulate_multicontact`, `replay_multicontact`, `multicontact_local_defects`
  (`tfcontact.verify.multicontact`): an event-driven simulator of the original system with
  several frictional contacts (modes and simultaneous inelastic impacts from contact LCPs,
  `solve_lcp` in `tfcontact.verify.lcp`), and the local defects of a plan with it.
* the physical checks (`tfcontact.verify.checks`): contact impulses recovered from the
  momentum balance (`contact_impulses`, `collocation_impulses`), the friction cone,
  Coulomb's maximal dissipation, the clock, Painleve's ill-posed contacts.
* the replays of a plan's controls (`tfcontact.verify.replay`, on a `ReplayedPlan`): the
  open-loop end-state deviation, the local defects per control interval, the open-loop
  amplification and the end-state check built on them.
* `Verification` (`tfcontact.verify.result`): the outcome of the checks of one plan.
* the full collision model along a plan (`tfcontact.verify.collision`): every URDF
  collision body against the terrain (`Obstacle`s) and against the robot's other bodies,
  `check_collisions` / `check_robot_collisions` -> `CollisionReport`; optional, not part
  of `Verification`.

Layering: data flow robot -> timefreezing -> fesd -> mpcc -> ocp. `tfcontact.verify` sits
beside `tfcontact.ocp`: it imports the time-freezing layer (the CLS, physical time), the
FESD simulator and the MPCC settings (for `FesdReplay`), and never `tfcontact.ocp`, which
calls it (`solve_contact` verifies every plan through `check_time_freezing_plan`). A plan
reaches it as arrays, whatever computed it.
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
from tfcontact.verify.collision import (
    CollisionOptions,
    CollisionReport,
    CollisionStatus,
    Obstacle,
    box_obstacle,
    check_collisions,
    check_robot_collisions,
    ground_obstacle,
    halfspace_obstacle,
    terrain_obstacles,
)
from tfcontact.verify.lcp import LcpSolution, solve_lcp
from tfcontact.verify.methods import (
    AutoReplay,
    ExactReplay,
    FesdReplay,
    MultiContactReplay,
    Replay,
    ReplayOutcome,
)
from tfcontact.verify.multicontact import (
    ContactEvent,
    ContactImpact,
    ContactMode,
    EvaluationBudget,
    EventKind,
    MultiContactOptions,
    MultiContactSimulation,
    SimulationStatus,
    multicontact_local_defects,
    replay_multicontact,
    simulate_multicontact,
    stopped_replay,
)
from tfcontact.verify.options import VerifyOptions
from tfcontact.verify.plan import TimeFreezingPlan, check_time_freezing_plan, state_indices
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
    ReplayTo,
    StoppedReplay,
    defect_segments,
    departure_check,
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
    "AutoReplay",
    "CollisionOptions",
    "CollisionReport",
    "CollisionStatus",
    "ContactEvent",
    "ContactImpact",
    "ContactMode",
    "EvaluationBudget",
    "EventKind",
    "ExactReplay",
    "FesdReplay",
    "LcpSolution",
    "MultiContactOptions",
    "MultiContactReplay",
    "MultiContactSimulation",
    "Obstacle",
    "ReferenceImpact",
    "ReferenceSimulation",
    "Replay",
    "ReplayOutcome",
    "ReplayTo",
    "ReplayedPlan",
    "SimulationStatus",
    "StackedFunction",
    "StoppedReplay",
    "TimeFreezingPlan",
    "Verification",
    "VerifyOptions",
    "box_obstacle",
    "check_collisions",
    "check_robot_collisions",
    "terrain_obstacles",
    "check_time_freezing_plan",
    "clock_checks",
    "collocation_impulses",
    "contact_impulses",
    "defect_segments",
    "departure_check",
    "end_state_check",
    "friction_cone_violation",
    "ground_obstacle",
    "halfspace_obstacle",
    "local_defects",
    "maximal_dissipation_violation",
    "multicontact_local_defects",
    "open_loop_sensitivity",
    "painleve_note",
    "planar_impulse_flow",
    "reference_deviation",
    "replay_controls",
    "replay_multicontact",
    "simulate_impacts",
    "simulate_multicontact",
    "solve_lcp",
    "stopped_replay",
    "state_indices",
]
