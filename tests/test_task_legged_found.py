"""`tfcontact plan biped-step` and `quadruped-gait` end to end (about 5 and 2.5 minutes):
their own file so that pytest-xdist runs them on the other worker beside
tests/test_task_legged_plans.py (whose plans take about 20 minutes in one process)."""

from __future__ import annotations

import numpy as np
import pytest
from legged_plans import frame_positions, planned


@pytest.mark.slow
def test_bolt_walks_up_the_step_with_no_contact_schedule_verified_and_clear(tmp_path):
    """`tfcontact plan biped-step` (measured about 5 minutes): biped-walk's discovery first,
    this task's homotopy continued from it moves the steps onto a 5 cm box from x = 0.35 m,
    and the stance re-solve along its stances makes the plan, which passes the
    multi-contact reference, does its task and is clear of the terrain. Checked here on
    Pinocchio's foot placements: both feet start on the ground, each rises at least twice
    more than 5 cm above what lies beneath it, and both end resting on the box's top
    (x past its edge, the sole at 5 cm); the base ends 0.5 m forwards."""
    _, trajectory, model = planned("biped-step", tmp_path)
    assert trajectory.task["passed"]
    edge, top, radius = 0.35, 0.05, 0.016
    feet = frame_positions(model, trajectory.q, ["FL_FOOT", "FR_FOOT"])
    x, z = feet[..., 0], feet[..., 2] - radius  # the soles' x and height above the ground
    # the sole's clearance above the box's top past its edge, above the ground before it
    # (within the 1 cm rounding only an upper bound; no clearance is measured there)
    beneath = np.where(x > edge + 0.01, top, 0.0)
    clearance = z - beneath
    assert np.all(np.abs(z[0]) < 1e-3)
    for foot in range(2):
        up = clearance[:, foot] > 0.05
        rises = int(np.sum(up[1:] & ~up[:-1]))
        assert rises >= 2, (foot, rises)
    assert np.all(x[-1] > edge + 0.01)
    np.testing.assert_allclose(z[-1], top, atol=1e-3)
    assert abs(trajectory.q[-1, 0] - 0.5) <= 0.05


@pytest.mark.slow
def test_solo12_in_the_plane_moves_forwards_in_a_gait_it_finds_verified_and_clear(tmp_path):
    """`tfcontact plan quadruped-gait` (measured about 2.5 minutes): from a base reference
    that bobs twice and no contact schedule, the discovery finds a gait, the stance
    re-solve makes the plan, which passes the multi-contact reference, does its task and
    is clear of the ground and of itself; the gait reported is a two-hop pronk. Checked
    here on Pinocchio's foot placements: two separate flights with all four feet off the
    ground for at least 0.1 s each, the feet down at the start and at the end, the base
    0.3 m forwards."""
    summary, trajectory, model = planned("quadruped-gait", tmp_path)
    feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
    assert summary["gait"] == {"name": "pronk", "groups": [feet, feet]}
    assert trajectory.task["passed"]
    heights = frame_positions(model, trajectory.q, feet)[..., 2] - 0.016
    t = trajectory.clock
    flying = np.all(heights > 0.01, axis=1)
    starts = np.flatnonzero(flying[1:] & ~flying[:-1]) + 1
    ends = np.flatnonzero(flying[:-1] & ~flying[1:])
    assert len(starts) == len(ends) == 2, (starts, ends)
    assert np.all(t[ends] - t[starts] >= 0.1)
    assert np.all(np.abs(heights[0]) < 1e-4)
    assert np.all(np.abs(heights[t > trajectory.clock[-1] - 0.1]) < 1e-4)
    assert abs(trajectory.q[-1, 0] - 0.3) <= 0.05
