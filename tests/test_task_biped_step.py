"""`tfcontact plan biped-step` end to end: its own file so that pytest-xdist runs it on
the other worker beside tests/test_task_legged_plans.py (whose plans take about 20
minutes in one process)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.mark.slow
def test_bolt_walks_up_the_step_with_no_contact_schedule_verified_and_clear(tmp_path):
    """`tfcontact plan biped-step` (measured about 5 minutes): biped-walk's discovery first,
    this task's homotopy continued from it moves the steps onto a 5 cm box from x = 0.35 m,
    and the stance re-solve along its stances makes the plan, which passes the
    multi-contact reference, does its task and is clear of the terrain. Checked here on
    Pinocchio's foot placements: both feet start on the ground, each rises at least twice
    more than 5 cm above what lies beneath it, and both end resting on the box's top
    (x past its edge, the sole at 5 cm); the base ends 0.5 m forwards."""
    import json

    import pinocchio as pin

    from tfcontact.cli import main
    from tfcontact.plan_format import load_trajectory
    from tfcontact.robot import RobotSpec, load_robot

    assert main(["plan", "biped-step", "--out", str(tmp_path), "--quiet"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["success"] and summary["status"] == "converged", summary["summary"]
    stages = {entry["stage"]: entry for entry in summary["stages"]}
    assert stages["stance re-solve"]["status"] == "converged"
    assert stages["collision check"]["status"] == "clear"
    trajectory = load_trajectory(tmp_path / "trajectory.npz")
    assert trajectory.verification["passed"] and trajectory.task["passed"]
    model = load_robot(RobotSpec.from_dict(trajectory.robot)).model
    data = model.createData()
    edge, top, radius = 0.35, 0.05, 0.016
    soles = []  # (x, height of the sole above the ground plane) per foot and sample
    for q in trajectory.q:
        pin.framesForwardKinematics(model, data, q)
        soles.append([[data.oMf[model.getFrameId(foot)].translation[0],
                       data.oMf[model.getFrameId(foot)].translation[2] - radius]
                      for foot in ("FL_FOOT", "FR_FOOT")])
    soles = np.array(soles)
    x, z = soles[..., 0], soles[..., 1]
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
