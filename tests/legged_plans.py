"""The shipped legged plans run end to end for the slow tests: plan a task through the
CLI, check the stages every legged plan must pass, and give back what the test checks on
Pinocchio's own placements."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np


def planned(task: str, out: Path, solve_stage: str = "stance re-solve"
            ) -> tuple[dict[str, Any], Any, Any]:
    """`tfcontact plan <task>` into `out`: asserts the plan converged, its `solve_stage`
    converged, the collision check is clear and the trajectory passed its verification;
    returns (summary.json's content, the loaded trajectory, the robot's pinocchio model)."""
    from tfcontact.cli import main

    assert main(["plan", task, "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] and summary["status"] == "converged", summary["summary"]
    stages = summary_stages(summary)
    assert stages[solve_stage]["status"] == "converged"
    assert stages["collision check"]["status"] == "clear"
    return summary, *trajectory_and_model(out)


def summary_stages(summary: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """summary.json's stages by name."""
    return {entry["stage"]: entry for entry in summary["stages"]}


def trajectory_and_model(out: Path) -> tuple[Any, Any]:
    """The plan's trajectory.npz (its verification passed) and its robot's model."""
    from tfcontact.plan_format import load_trajectory
    from tfcontact.robot import RobotSpec, load_robot

    trajectory = load_trajectory(out / "trajectory.npz")
    assert trajectory.verification["passed"]
    return trajectory, load_robot(RobotSpec.from_dict(trajectory.robot)).model


def frame_positions(model: Any, qs: np.ndarray, frames: list[str]) -> np.ndarray:
    """The world positions of `frames` at each configuration: (samples, frame, xyz)."""
    import pinocchio as pin

    data = model.createData()
    ids = [model.getFrameId(name) for name in frames]
    positions = []
    for q in qs:
        pin.framesForwardKinematics(model, data, q)
        positions.append([data.oMf[i].translation.copy() for i in ids])
    return np.array(positions)
