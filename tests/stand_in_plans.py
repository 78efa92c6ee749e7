"""Exact re-solves without a solver, for the tests of chains and stages: a stand-in plan
of a given IPOPT status and cost, and the saved TF-9 plan as a `PolishedPlan`."""

from __future__ import annotations

import types
from pathlib import Path

import numpy as np

from tfcontact.ocp.polish import STICK, Phase, PolishedPlan
from tfcontact.plan_format.resolved import load_resolved_plan

SAVED_PLAN = Path(__file__).resolve().parents[1] / "benchmarks" / "monoped_exact_plan.npz"
"""The chain's verified TF-9 plan on the hand-set schedule (Radau IIA, refined mesh)."""


def stand_in_plan(status: str, cost: float, shift: float = 0.0,
                  verification=None) -> PolishedPlan:
    """Five nodes of the monoped standing (states `shift`), ten intervals; a verification
    that passes unless one is given."""
    t = np.linspace(0.0, 1.0, 5)
    return PolishedPlan(
        phases=(Phase(STICK, 0.0, 1.0),), t=t, x=np.zeros((5, 8)) + shift, u=np.zeros((10, 2)),
        boundary_states=np.zeros((11, 8)), contact_forces=np.zeros((0, 2)),
        impact_impulses=np.zeros((0, 2)), cost=cost, ipopt_status=status, iterations=7,
        solve_time=1.0, verification=verification or types.SimpleNamespace(passed=True,
                                                                           summary=str))


def saved_plan(verification, path: Path = SAVED_PLAN, cost: float = 0.0) -> PolishedPlan:
    """A node file (`plan.npz`) as the `PolishedPlan` that wrote it, with `verification`."""
    saved = load_resolved_plan(path)
    return PolishedPlan(
        phases=saved.phases, t=saved.t, x=saved.x, u=saved.u,
        boundary_states=saved.boundary_states, contact_forces=np.zeros((0, 2)),
        impact_impulses=np.zeros((0, 2)), cost=cost, ipopt_status="Solve_Succeeded",
        iterations=1, solve_time=1.0, verification=verification,
        integrator=saved.integrator, substeps=saved.substeps)
