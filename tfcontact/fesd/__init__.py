"""FESD: piecewise smooth systems, collocation tableaus, discretisation and simulation.

Entry points: `discretize(system, grid=FesdGrid(...), scheme=RadauIIA(2), method=Fesd())`
builds the MPCC of a horizon; `simulate(system, x0, horizon=..., n_steps=...)` integrates
step by step (`horizon=Physical(T)` for a time-freezing system's physical time; failed steps
are cut and the auxiliary gain a_n adapted, see `Adaptivity`; `result.state_at(t)` reads
the state at any physical time). DESIGN.md section 4.6; Nurkanovic et al., Numer. Math. 2024.
"""

from tfcontact.fesd.discretization import (
    Direct,
    Discretization,
    Fesd,
    FesdGrid,
    HeuristicMean,
    Layout,
    NoEquilibration,
    Standard,
    StepEquilibration,
    discretize,
)
from tfcontact.fesd.simulate import (
    FROZEN_RATE_TOL,
    NO_ADAPTATION,
    Adaptation,
    Adaptivity,
    ClockedSystem,
    Physical,
    SimulationResult,
    SimulationStatus,
    simulate,
)
from tfcontact.fesd.system import HeavisideSystem, PiecewiseSmoothSystem, StewartSystem
from tfcontact.fesd.tableau import (
    GaussLegendre,
    RadauIIA,
    Scheme,
    Tableau,
    collocation_tableau,
)

__all__ = [
    "FROZEN_RATE_TOL",
    "NO_ADAPTATION",
    "Adaptation",
    "Adaptivity",
    "ClockedSystem",
    "Direct",
    "Discretization",
    "Fesd",
    "FesdGrid",
    "GaussLegendre",
    "HeavisideSystem",
    "HeuristicMean",
    "Layout",
    "NoEquilibration",
    "Physical",
    "PiecewiseSmoothSystem",
    "RadauIIA",
    "Scheme",
    "SimulationResult",
    "SimulationStatus",
    "Standard",
    "StepEquilibration",
    "StewartSystem",
    "Tableau",
    "collocation_tableau",
    "discretize",
    "simulate",
]
