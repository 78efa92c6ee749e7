"""The shipped legged task files planned end to end (`tfcontact plan`): bolt's short walk
and solo12's planar jump from no contact schedule, solo12's jump and trot along the
contact sequences their files give; each checked on Pinocchio's own foot placements.
Kept apart from tests/test_task.py (the task layer's validation and small solves) so that
pytest-xdist runs these long plans beside it on another worker."""

from __future__ import annotations

import numpy as np
import pytest
from legged_plans import frame_positions, planned, summary_stages, trajectory_and_model


@pytest.mark.slow
def test_biped_walk_short_steps_once_per_foot_verified_and_clear(tmp_path):
    """`tfcontact plan biped-walk-short` (biped-walk reduced to 0.6 s and one step per
    foot, no period; measured about 45 s): from the start-everywhere guess the discovery
    finds a step per foot, the stance re-solve along its stances makes the plan, which
    passes the multi-contact reference, does its task and is clear of the ground. The
    feet's lift-offs, their reach and the base's end are checked here on Pinocchio's foot
    placements."""
    import pinocchio as pin

    summary, trajectory, model = planned("biped-walk-short", tmp_path)
    assert summary_stages(summary)["discover"]["ran"]
    # the gait report: one foot at a time, both feet stepping (a planar biped: no name)
    assert summary["gait"]["name"] == ""
    assert all(len(group) == 1 for group in summary["gait"]["groups"])
    assert {g[0] for g in summary["gait"]["groups"]} == {"FL_FOOT", "FR_FOOT"}
    data = model.createData()
    heights, offsets = [], []  # the feet's lowest points above the ground; their x in
    for q in trajectory.q:     # the base's frame, per sample
        pin.framesForwardKinematics(model, data, q)
        base = data.oMf[model.getFrameId("root_joint")]
        feet = [data.oMf[model.getFrameId(foot)].translation for foot in ("FL_FOOT",
                                                                          "FR_FOOT")]
        heights.append([foot[2] - 0.016 for foot in feet])
        offsets.append([base.actInv(foot)[0] for foot in feet])
    heights = np.array(heights)
    # the re-solve keeps each foot's reach (12 cm about the base): without those rows a
    # re-solved foot went 27 cm from the base (a start 3.8 cm ahead)
    assert np.abs(offsets).max() <= 0.12 + 2e-3
    assert heights.min() >= -1e-3
    # each foot starts down and lifts above 5 cm (the task does not ask the feet down at
    # T: measured, the right foot lifts off again at 0.5 s and is in the air at T)
    assert np.all(heights[0] < 1e-3)
    assert np.all(heights.max(axis=0) > 0.05)
    assert abs(trajectory.q[-1, 0] - 0.2) <= 0.05


@pytest.mark.slow
def test_solo12_jumps_along_its_given_contact_sequence_verified_and_clear(tmp_path):
    """`tfcontact plan quadruped-jump-schedule` (measured 3-5 minutes): solo12, floating
    base, four 3-D frictional feet, along all down / flight / all landing: verified by the
    multi-contact reference, its task done, clear of the ground and itself. Checked here
    on Pinocchio's foot placements and centre of mass: all four feet off the ground
    together for 0.1 s, down at both ends, and the push-off's forces carrying the
    robot's weight and its change of momentum."""
    import pinocchio as pin

    summary, trajectory, model = planned("quadruped-jump-schedule", tmp_path,
                                         solve_stage="stance solve")
    assert "discover" not in summary_stages(summary)
    assert summary["gait"] == {"name": "pronk", "groups": [
        ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]]}
    data = model.createData()
    feet = [model.getFrameId(f"{leg}_FOOT") for leg in ("FL", "FR", "HL", "HR")]
    heights, momentum = [], []
    for q, v in zip(trajectory.q, trajectory.v, strict=True):
        pin.framesForwardKinematics(model, data, q)
        heights.append([data.oMf[f].translation[2] - 0.016 for f in feet])
        pin.centerOfMass(model, data, q, v)
        momentum.append(pin.computeTotalMass(model) * data.vcom[0][2])
    heights, momentum, t = np.array(heights), np.array(momentum), trajectory.clock
    assert np.all(np.abs(heights[0]) < 1e-4) and np.all(np.abs(heights[-1]) < 1e-4)
    flying = np.all(heights > 0.01, axis=1)
    assert t[flying].max() - t[flying].min() >= 0.1
    assert np.all(np.diff(t[flying]) < 0.03)  # one flight, not two short ones
    assert abs(trajectory.q[-1, 0] - 0.2) <= 0.05
    push = t <= 0.2 + 1e-9
    impulse = np.trapezoid(trajectory.force[push].sum(axis=1)[:, 2], t[push])
    weight = pin.computeTotalMass(model) * 9.81
    last = int(np.flatnonzero(push)[-1])
    assert impulse == pytest.approx(weight * t[last] + momentum[last] - momentum[0], rel=2e-2)


@pytest.mark.slow
def test_solo12_in_the_plane_jumps_with_no_contact_schedule_verified_and_clear(tmp_path):
    """`tfcontact plan quadruped-jump-planar` (quadruped-jump in the sagittal plane;
    measured about 2 minutes): from the base reference the discovery finds a four-foot
    jump, the stance re-solve along its stances makes the plan, which passes the
    multi-contact reference, does its task and is clear. Checked here on Pinocchio's
    foot and knee placements: all four feet off the ground together for 0.1 s in one
    flight, down at the start and from the landing to T (`end_standing`), the knees at
    least 25 mm up, the base ending 0.2 m forwards; the gait reported is a pronk."""
    summary, trajectory, model = planned("quadruped-jump-planar", tmp_path)
    assert summary_stages(summary)["discover"]["ran"]
    assert summary["gait"] == {"name": "pronk", "groups": [
        ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]]}
    assert trajectory.task["passed"]
    legs = ("FL", "FR", "HL", "HR")
    heights = frame_positions(model, trajectory.q, [f"{leg}_FOOT" for leg in legs])[..., 2]
    heights = heights - 0.016
    knee_heights = frame_positions(model, trajectory.q, [f"{leg}_KFE" for leg in legs])[..., 2]
    t = trajectory.clock
    flying = np.all(heights > 0.01, axis=1)
    assert t[flying].max() - t[flying].min() >= 0.1
    assert np.all(np.diff(t[flying]) < 0.03)  # one flight, not two short ones
    assert np.all(np.abs(heights[0]) < 1e-4)
    landed = t > t[flying].max() + 0.06  # after both pairs' touchdowns
    assert landed.sum() > 5 and np.abs(heights[landed]).max() < 1e-4
    assert np.min(knee_heights) >= 0.025 - 1e-4
    assert abs(trajectory.q[-1, 0] - 0.2) <= 0.05


@pytest.mark.slow
def test_solo12_trots_along_its_given_contact_sequence_verified_and_clear(tmp_path):
    """`quadruped-trot-schedule` cut to its first two diagonal steps (T = 0.5 s, N = 10,
    0.15 m forwards; measured 100 s): verified by the multi-contact reference, task done,
    clear. Checked on Pinocchio's foot placements: in each swing the swinging diagonal
    pair rises above 3 cm while the other pair stays on the ground without sliding, all
    four feet are down at both ends, and the base ends 0.15 m forwards."""
    import dataclasses

    from tfcontact.scenes.plans import run_plan
    from tfcontact.task import Waypoint, load_task, shipped_tasks

    full = load_task(shipped_tasks()["quadruped-trot-schedule"])
    horizon, end = 0.5, {"x": 0.15}
    task = dataclasses.replace(
        full, horizon=horizon, n_intervals=10,
        stances=tuple(s for s in full.stances if s.start < horizon),
        waypoints=(Waypoint(horizon, {**full.waypoints[-1].values, **end}),),
        goals=dataclasses.replace(full.goals, end=end,
                                  lift_offs=dict.fromkeys(full.goals.lift_offs, 1)))
    assert [s.closed for s in task.stances][1:4:2] == [("FR_FOOT", "HL_FOOT"),
                                                       ("FL_FOOT", "HR_FOOT")]
    import json

    report = run_plan(task, tmp_path, verbose=False)
    assert report.success and report.status == "converged", report.summary
    gait = json.loads((tmp_path / "summary.json").read_text())["gait"]
    assert gait == {"name": "trot", "groups": [["FL_FOOT", "HR_FOOT"], ["FR_FOOT", "HL_FOOT"]]}
    trajectory, model = trajectory_and_model(tmp_path)
    assert trajectory.task["passed"]
    feet = frame_positions(model, trajectory.q, [f"{leg}_FOOT" for leg in ("FL", "FR", "HL",
                                                                         "HR")])
    t = trajectory.clock  # feet: (samples, foot, xyz)
    heights = feet[:, :, 2] - 0.016
    assert np.all(np.abs(heights[0]) < 1e-4) and np.all(np.abs(heights[-1]) < 1e-4)
    solved = trajectory.solver["stances"]  # the touchdowns at their solved times
    assert [s["closed"] for s in solved] == [[0, 1, 2, 3], [1, 2], [0, 1, 2, 3], [0, 3],
                                             [0, 1, 2, 3]]
    for swing, landing in ((solved[1], solved[2]), (solved[3], solved[4])):
        inside = (t > swing["start"] + 1e-9) & (t < landing["start"] - 1e-9)
        down = swing["closed"]
        up = [i for i in range(4) if i not in down]
        assert np.all(heights[inside][:, up] > 0)
        assert np.all(heights[inside][:, up].max(axis=0) > 0.03)
        assert np.all(np.abs(heights[inside][:, down]) < 1e-4)
        slide = feet[inside][:, down, :2] - feet[inside][:1, down, :2]
        assert np.abs(slide).max() < 1e-3
    assert abs(trajectory.q[-1, 0] - 0.15) <= 0.05
