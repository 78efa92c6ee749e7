"""The monoped chain's last two levels (Radau IIA, then the mesh refined where the local
defects are large) from the saved RK4 plan. Slow (about 12 minutes until the warm starts
at impacts and the terminal rows were mended, 31 s since), a file of its own: the test
runner distributes files over its workers (`--dist loadfile`)."""

from __future__ import annotations

import numpy as np
import pytest
from stand_in_plans import SAVED_PLAN

import tfcontact.scenes.monoped_exact as monoped_exact
from tfcontact.ocp.chain import resolve_chain
from tfcontact.plan_format.resolved import load_resolved_plan
from tfcontact.scenes.monoped import monoped_problem
from tfcontact.scenes.monoped_exact import EXACT_TASK


@pytest.mark.slow
def test_radau_levels_turn_the_rk4_plan_into_a_verified_radau_plan():
    """The chain's last two levels from the saved RK4 plan (what its RK4 levels end
    with): 12 Radau IIA elements per interval fail the exact replay, the mesh refined where
    the local defects are large passes it, 4x closer than the RK4 plan (measured with
    element derivatives: 39 and 38 iterations, 31 s, peak 0.63 GB; defects summing to
    8.2e-3 against the RK4 plan's 3.7e-2. Before the mends: 262 and 783 iterations, 8
    minutes)."""
    rk4 = load_resolved_plan(SAVED_PLAN.with_name("monoped_exact_rk4_plan.npz"))
    mp = monoped_problem(EXACT_TASK)
    result = resolve_chain(monoped_exact.radau_levels(mp.problem), rk4.phases,
                           (rk4.t, rk4.x, rk4.u), verbose=False)
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
