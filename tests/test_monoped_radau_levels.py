"""The monoped chain's last two levels (Radau IIA, then the mesh refined where the local
defects are large) from the saved RK4 plan, with TF-9's ellipses and with the holes as
the terrain's. Slow (about 12 minutes until the warm starts at impacts and the terminal
rows were mended, 31 s since; the terrain's 110 s), a file of its own: the test runner
distributes files over its workers (`--dist loadfile`)."""

from __future__ import annotations

import numpy as np
import pytest
from stand_in_plans import SAVED_PLAN

import tfcontact.scenes.monoped_exact as monoped_exact
from tfcontact.ocp.chain import resolve_chain
from tfcontact.ocp.polish import HybridDynamics
from tfcontact.plan_format.resolved import load_resolved_plan
from tfcontact.scenes.monoped import monoped_problem
from tfcontact.scenes.monoped_exact import EXACT_TASK

RK4_PLAN = SAVED_PLAN.with_name("monoped_exact_rk4_plan.npz")


@pytest.fixture(scope="module")
def ellipse_chain():
    rk4 = load_resolved_plan(RK4_PLAN)
    mp = monoped_problem(EXACT_TASK)
    return mp, resolve_chain(monoped_exact.radau_levels(mp.problem), rk4.phases,
                             (rk4.t, rk4.x, rk4.u), verbose=False)


@pytest.mark.slow
def test_radau_levels_turn_the_rk4_plan_into_a_verified_radau_plan(ellipse_chain):
    """The chain's last two levels from the saved RK4 plan (what its RK4 levels end
    with): 12 Radau IIA elements per interval fail the exact replay, the mesh refined where
    the local defects are large passes it, 4x closer than the RK4 plan (measured with
    element derivatives: 39 and 38 iterations, 31 s, peak 0.63 GB; defects summing to
    8.2e-3 against the RK4 plan's 3.7e-2. Before the mends: 262 and 783 iterations, 8
    minutes)."""
    mp, result = ellipse_chain
    first, refined = result.steps
    assert first.status == "verification_failed" and refined.status == "converged"
    assert result.success and result.plan.integrator == "radau"
    assert max(result.plan.substeps) == 24 and min(result.plan.substeps) == 12
    v = result.plan.verification
    assert v.defect_sum < 2e-2 and v.min_gap >= -1e-3
    assert result.path_violation <= 1e-6
    assert np.min(mp.hole_values(result.plan.x[:, :4])) >= -1e-6
    np.testing.assert_allclose(result.plan.boundary_states[-1][:4], EXACT_TASK.q_goal,
                               atol=1e-6)


@pytest.mark.slow
def test_the_holes_as_terrain_give_a_verified_plan_no_dearer_than_tf9s_ellipses(
        ellipse_chain):
    """`--task terrain`'s last levels from the same RK4 plan: the holes are the terrain's
    (no support over them, the foot free to pass inside TF-9's ellipses), the landings keep
    r_n >= 0.025 W_nn (`TERRAIN_TOUCHDOWN_RATE`). The plan is verified, meets q(T) = goal,
    keeps the foot out of the terrain, and costs no more than the ellipses' plan (measured:
    224.06 against 240.0; 47 and 72 iterations, 110 s)."""
    _, ellipse = ellipse_chain
    rk4 = load_resolved_plan(RK4_PLAN)
    setup = monoped_exact.terrain_setup()
    levels = monoped_exact.terrain_levels(setup)[-2:]
    result = resolve_chain(levels, rk4.phases, (rk4.t, rk4.x, rk4.u), verbose=False)
    assert result.success, result.summary()
    plan = result.plan
    assert plan.verification.min_gap >= -1e-3 and result.path_violation <= 1e-6
    np.testing.assert_allclose(plan.boundary_states[-1][:4], EXACT_TASK.q_goal, atol=1e-6)
    assert plan.cost <= ellipse.plan.cost
    mp = monoped_problem(EXACT_TASK)
    assert np.min(mp.hole_values(plan.x[:, :4])) < -0.1  # inside an ellipse, above the hole
    dyn = HybridDynamics(setup.problem.system.cls)
    landings = [i for i in range(1, len(plan.t)) if plan.t[i] == plan.t[i - 1]]
    assert len(landings) == 3
    for i in landings:
        w = np.asarray(dyn.delassus(plan.x[i - 1]))
        v_t = float(np.asarray(dyn.velocity(plan.x[i - 1]))[1, 0])
        rate_n = w[0, 0] - np.sign(v_t) * dyn.mu * w[0, 1]
        assert rate_n >= monoped_exact.TERRAIN_TOUCHDOWN_RATE * w[0, 0] - 1e-6
