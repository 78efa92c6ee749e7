"""FESD: piecewise smooth systems, collocation tableaus, discretisation and simulation.

Entry points: `discretize(system, grid=FesdGrid(...), scheme=RadauIIA(2), method=Fesd())`
builds the MPCC of a horizon; `simulate(system, x0, horizon=..., n_steps=...)` integrates
step by step. DESIGN.md section 4.6; Nurkanovic et al., Numer. Math. 2024.
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
from tfcontact.fesd.simulate import SimulationResult, SimulationStatus, simulate
from tfcontact.fesd.system import HeavisideSystem, PiecewiseSmoothSystem, StewartSystem
from tfcontact.fesd.tableau import (
    GaussLegendre,
    RadauIIA,
    Scheme,
    Tableau,
    collocation_tableau,
)

__all__ = [
    "Direct",
    "Discretization",
    "Fesd",
    "FesdGrid",
    "GaussLegendre",
    "HeavisideSystem",
    "HeuristicMean",
    "Layout",
    "NoEquilibration",
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
