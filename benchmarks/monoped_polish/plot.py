"""The figure of full.py's plan: the foot's path over TF-9's holes, the joint angles and
the torques.

    PYTHONPATH=benchmarks/monoped_polish python benchmarks/monoped_polish/plot.py PLAN.npz OUT.png
"""

import dataclasses
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from tfcontact.scenes.monoped import FULL_TASK, monoped_problem  # noqa: E402


def main() -> None:
    plan = np.load(sys.argv[1])
    task = dataclasses.replace(FULL_TASK, hole_half_width=0.25, hole_form="ellipse")
    mp = monoped_problem(task)
    t, x, u = plan["t"], plan["x"], plan["u"]
    foot = np.asarray(mp.foot(x[:, :4].T)).T
    knee = np.asarray(mp.knee(x[:, :4].T)).T
    fig, (path, angles, torques) = plt.subplots(3, 1, figsize=(8, 8.5))
    angle = np.linspace(0, np.pi, 60)
    for centre in task.holes:
        path.fill_between(centre + task.hole_half_width * np.cos(angle),
                          task.hole_depth * np.sin(angle), color="tab:red", alpha=0.3, lw=0)
    path.plot(foot[:, 0], foot[:, 1], label="foot")
    path.plot(x[:, 0], x[:, 1], label="hip")
    path.plot(knee[:, 0], knee[:, 1], lw=0.8, label="knee")
    path.axhline(0, color="k", lw=0.8)
    path.set(xlabel="x [m]", ylabel="z [m]", aspect="equal",
             title="TF-9 monoped, exact re-solve (holes: half width 0.25, TF-9's ellipses)")
    path.legend(loc="upper right", fontsize=8)
    angles.plot(t, x[:, 2], label="hip angle")
    angles.plot(t, x[:, 3], label="knee angle")
    angles.set(xlabel="t [s]", ylabel="[rad]")
    angles.legend(fontsize=8)
    grid = np.linspace(0, task.horizon, len(u) + 1)
    for i, name in enumerate(("hip", "knee")):
        torques.stairs(u[:, i], grid, label=f"{name} torque")
    for mode, start in zip(plan["phase_modes"], plan["phase_starts"], strict=True):
        if mode == "flight":
            torques.axvline(start, color="gray", lw=0.6, ls=":")
    torques.set(xlabel="t [s] (dotted: lift-offs)", ylabel="[N m]")
    torques.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)
    print(f"wrote {sys.argv[2]}")


if __name__ == "__main__":
    main()
