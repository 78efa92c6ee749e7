"""tfcontact.timefreezing: complementarity Lagrangian systems -> piecewise smooth systems.

The time-freezing reformulation (DESIGN.md 4.1-4.5) removes the state jumps of impacts
(and of hysteresis) by auxiliary dynamics on the prohibited region and a clock state that
stops while they act. Entry points:

* `from_robot(robot, ground, mu=...)`: the CLS of a `tfcontact.robot.Robot`.
* `time_freeze(cls, method=...)`: a `ComplementarityLagrangianSystem` -> `TimeFreezingSystem`
  (`Inelastic()` Heaviside form with friction, `Elastic(stiffness)` Stewart form).
  `Inelastic(dynamics=...)` chooses how the velocity rows are written: `PerModeSolves()`
  (default, one M(q) solve per mode), `OneSolve()` (one solve) or `InverseDynamics()`
  (accelerations as stage variables, no M(q)^-1; benchmarks/dynamics_forms.md);
  `Inelastic(friction=...)` how 3-D contacts rub: `SmoothedCone()` (default, [AUTO23])
  or `InscribedPyramid()` (planar friction per tangent: bounded derivatives, exact stick).
* `hysteresis_system(...)`: a two-mode hysteresis -> `TimeFreezingSystem` (Stewart, Voronoi).
* `with_speed_of_time`, `with_lagrange_cost`: the OCP layer's transformations.
* `to_physical_time`: numerical-time solutions -> physical time with impacts as jumps.

The event-detecting simulator of the original system with exact impacts, used to check
plans, is in `tfcontact.verify` (`simulate_impacts`, `replay_controls`).
"""

from tfcontact.timefreezing.builder import time_freeze
from tfcontact.timefreezing.cls import Cls, ComplementarityLagrangianSystem, Contact
from tfcontact.timefreezing.elastic import (
    Elastic,
    elastic_damping,
    frozen_duration,
    normal_spring,
)
from tfcontact.timefreezing.from_robot import from_robot
from tfcontact.timefreezing.hysteresis import VORONOI_POINTS, hysteresis_system, push_speed
from tfcontact.timefreezing.inelastic import (
    Inelastic,
    InscribedPyramid,
    InverseDynamics,
    OneSolve,
    PerModeSolves,
    SmoothedCone,
    SpatialFriction,
)
from tfcontact.timefreezing.physical import (
    FROZEN_RATE_TOL,
    Impact,
    PhysicalTrajectory,
    to_physical_time,
)
from tfcontact.timefreezing.system import (
    TimeFreezingSystem,
    with_lagrange_cost,
    with_speed_of_time,
)

__all__ = [
    "FROZEN_RATE_TOL",
    "VORONOI_POINTS",
    "Cls",
    "ComplementarityLagrangianSystem",
    "Contact",
    "Elastic",
    "Impact",
    "Inelastic",
    "InscribedPyramid",
    "InverseDynamics",
    "OneSolve",
    "PerModeSolves",
    "SmoothedCone",
    "SpatialFriction",
    "PhysicalTrajectory",
    "TimeFreezingSystem",
    "elastic_damping",
    "from_robot",
    "frozen_duration",
    "hysteresis_system",
    "normal_spring",
    "push_speed",
    "time_freeze",
    "to_physical_time",
    "with_lagrange_cost",
    "with_speed_of_time",
]
