# /// script
# requires-python = ">=3.11,<3.12"
# dependencies = ["tfcontact"]
# ///
"""Measure the size of standalone replay pages: the test hopper and solo12.

Usage: python scripts/replay_sizes.py [OUT_DIR]   (default: out/replay_sizes)

solo12's meshes are binary STL files from example-robot-data (2.5 MB for its 17
visuals); `mesh_detail` re-meshes them by vertex clustering. The trajectories are
synthetic (no solver): a hop for the hopper, a bobbing trot-like motion for solo12.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import example_robot_data
import numpy as np
import pinocchio as pin

from tfcontact.plan_format import Trajectory
from tfcontact.viz import replay

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from viz_hop import hop_trajectory, hopper_models  # noqa: E402


def solo12_trajectory(duration: float, n: int = 201) -> tuple[Trajectory, tuple]:
    robot = example_robot_data.load("solo12")
    model = robot.model
    tau = np.linspace(0.0, duration, n)
    q0 = robot.q0 if robot.q0 is not None else pin.neutral(model)
    q = np.repeat(q0[None], n, axis=0)
    q[:, 0] = 0.3 * tau
    q[:, 2] = 0.3 + 0.05 * np.sin(2 * np.pi * tau)
    q[:, 8::3] += 0.3 * np.sin(2 * np.pi * tau)[:, None]
    feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
    traj = Trajectory(
        tau=tau, clock=tau, s=np.ones(n), q=q, v=np.zeros((n, model.nv)),
        u=np.zeros((n, 12)), gap=np.zeros((n, 4)), normal_velocity=np.zeros((n, 4)),
        robot={"source": "solo12", "contacts": [{"frame": f, "radius": 0.016} for f in feet]},
    )
    return traj, (robot.model, robot.visual_model)


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/replay_sizes")
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    cases = [("hopper", hop_trajectory(), hopper_models(), 0.03, 1.0)]
    for duration in (1.0, 5.0):
        traj, models = solo12_trajectory(duration)
        for detail in (None, 0.05, 0.03, 0.02):
            cases.append((f"solo12 {duration:g} s", traj, models, detail, duration))
    for name, traj, models, detail, _ in cases:
        sizes = []
        for compress in (False, True):
            start = time.perf_counter()
            page = out / f"{name.replace(' ', '_')}_{detail}_{compress}.html"
            result = replay(traj, html=page, robot=models, mesh_detail=detail,
                            compress=compress)
            sizes.append(result.html_bytes)
        rows.append((name, detail, result.n_frames, *sizes, time.perf_counter() - start))
    print("| case | mesh_detail | frames (30 fps) | HTML [MB] plain | HTML [MB] compressed "
          "(default) | build time [s] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name, detail, frames, plain, packed, seconds in rows:
        print(f"| {name} | {detail} | {frames} | {plain / 1e6:.2f} | {packed / 1e6:.2f} "
              f"| {seconds:.2f} |")


if __name__ == "__main__":
    main()
