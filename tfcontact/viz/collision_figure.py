"""The collision check of a saved plan and its figure (matplotlib, Agg, no pyplot state).

`trajectory_collisions(traj)` runs `tfcontact.verify.collision.check_collisions` on the
physical samples of a `Trajectory` (frozen pieces dropped) with the robot rebuilt from its
sidecar and the terrain of its scene; `collision_figure(report)` draws every collision
body's distance to the terrain, and every self-collision pair's distance, against
physical time.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tfcontact.errors import InvalidInput
from tfcontact.plan_format.trajectory import Trajectory, physical_time
from tfcontact.robot import Robot, RobotSpec, Terrain, load_robot
from tfcontact.verify.collision import (
    CollisionOptions,
    CollisionReport,
    Obstacle,
    box_obstacle,
    check_robot_collisions,
    halfspace_obstacle,
    terrain_obstacles,
)


def scene_obstacles(traj: Trajectory) -> tuple[Obstacle, ...]:
    """The terrain of a trajectory's scene as obstacles.

    Reads `scene['terrain']`: {"type": "flat", "height": h, "normal": n} (default flat at
    0, z up), the solid half-space below the plane, named "ground"; or a terrain of
    primitives, `tfcontact.robot.Terrain.to_dict()` ({"kind": "terrain", ...}), as
    `tfcontact.verify.collision.terrain_obstacles` (planes, boxes, the ground beside
    holes, hole floors, named by the primitive's index); and the optional
    `scene['boxes']` ([{"center": [x, y, z], "size": [lx, ly, lz]}, ...]), named "box 1",
    "box 2", ... (or their "name"). The monoped's `holes` are regions the foot's centre
    avoids, not solids: they are not obstacles.

    Raises:
        InvalidInput: a terrain type other than "flat" or a terrain description, a bad
            terrain description, or a box without centre and size.
    """
    if not isinstance(traj, Trajectory):
        raise InvalidInput(f"`traj` must be a Trajectory, got {type(traj).__name__}")
    terrain = traj.scene.get("terrain", {})
    if terrain.get("kind") == "terrain":
        out = list(terrain_obstacles(Terrain.from_dict(terrain)))
    else:
        kind = terrain.get("type", "flat")
        if kind != "flat":
            raise InvalidInput(f"scene terrain of type {kind!r} has no obstacle form here; "
                               "pass `obstacles` explicitly")
        out = [halfspace_obstacle("ground", normal=terrain.get("normal", (0.0, 0.0, 1.0)),
                                  height=float(terrain.get("height", 0.0)))]
    for k, box in enumerate(traj.scene.get("boxes", ()), start=1):
        if not isinstance(box, dict) or "center" not in box or "size" not in box:
            raise InvalidInput(f"scene box {k} must have a 'center' and a 'size', got {box!r}")
        out.append(box_obstacle(str(box.get("name", f"box {k}")), box["size"],
                                center=box["center"]))
    return tuple(out)


def trajectory_collisions(
    traj: Trajectory,
    obstacles: Sequence[Obstacle] | None = None,
    *,
    robot: Robot | None = None,
    options: CollisionOptions | None = None,
    rate_tol: float | None = None,
) -> CollisionReport:
    """Check a plan's full collision model along its physical samples.

    Main arguments:
        traj: the plan.
        obstacles: the terrain; default `scene_obstacles(traj)`.

    Other arguments:
        robot: the plan's robot; default rebuilt from `traj.robot` (`load_robot`), whose
            contacts are the declared ones.
        options: a `CollisionOptions`; default `CollisionOptions()`.
        rate_tol: the clock rate below which an interval is frozen (`physical_time`).

    Returns:
        A `CollisionReport` (see `tfcontact.verify.collision.check_collisions`).

    Raises:
        InvalidInput: a robot whose nq differs from the trajectory's q.
    """
    if not isinstance(traj, Trajectory):
        raise InvalidInput(f"`traj` must be a Trajectory, got {type(traj).__name__}")
    if robot is None:
        robot = load_robot(RobotSpec.from_dict(traj.robot))
    if robot.nq != traj.q.shape[1]:
        raise InvalidInput(f"`robot` has nq = {robot.nq} but the trajectory's q has "
                           f"{traj.q.shape[1]} columns; pass the plan's robot")
    phys = physical_time(traj, rate_tol=rate_tol)
    obstacles = scene_obstacles(traj) if obstacles is None else obstacles
    return check_robot_collisions(robot, phys.t, phys.q, obstacles, options=options)


def collision_figure(report: CollisionReport) -> Figure:
    """Distances [mm] against physical time: each body to the terrain, each self pair.

    Declared contacts' bodies are dashed; the penetration tolerance is the dotted line
    below zero, and each curve's minimum is marked.
    """
    if not isinstance(report, CollisionReport):
        raise InvalidInput(f"`report` must be a CollisionReport, got {type(report).__name__}")
    panels = [("distance to the terrain [mm]", report.terrain_distance,
               [(b.body + (" (contact)" if b.contact else ""), b.contact)
                for b in report.bodies])]
    if report.pairs:
        panels.append(("distance between bodies [mm]", report.pair_distance,
                       [(f"{p.body_a} / {p.body_b}", False) for p in report.pairs]))
    height = 2.6
    fig = Figure(figsize=(7.0, height * len(panels) + 1.0))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, squeeze=False, sharex="col")[:, 0]
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.5 / fig.get_figheight(),
                        top=1 - 0.75 / fig.get_figheight(), hspace=0.15)
    for ax, (label, values, curves) in zip(axes, panels, strict=True):
        _curves(ax, report.times, values, curves, report.tolerance)
        ax.set_ylabel(label)
    if not report.bodies:
        axes[0].text(0.5, 0.5, "no bodies checked", ha="center", va="center",
                     transform=axes[0].transAxes)
    axes[-1].set_xlabel("t [s]")
    flag = "passed" if report.passed else "FAILED"
    fig.suptitle("\n".join(textwrap.wrap(f"collisions {flag}: {report.worst}", 110)),
                 fontsize="small")
    return fig


def save_collision_figure(report: CollisionReport, path: str | os.PathLike, *,
                          dpi: int = 120) -> Path:
    """Write `collision_figure(report)` to `path` (its suffix: .png or .svg)."""
    out = Path(path)
    fmt = out.suffix.lstrip(".").lower()
    if fmt not in ("png", "svg"):
        raise InvalidInput(f"`path` must end in .png or .svg, got {str(path)!r}")
    out.parent.mkdir(parents=True, exist_ok=True)
    collision_figure(report).savefig(out, format=fmt, dpi=dpi,
                                     metadata={"Date": None} if fmt == "svg" else None)
    return out


def _curves(ax: Any, t: np.ndarray, values: np.ndarray, curves: list[tuple[str, bool]],
            tolerance: float) -> None:
    finite = values[np.isfinite(values)]
    for j, (name, dashed) in enumerate(curves):
        y = 1e3 * values[:, j]
        if not np.any(np.isfinite(y)):
            continue
        line, = ax.plot(t, y, lw=1.3, ls="--" if dashed else "-", label=name)
        k = int(np.argmin(y))
        ax.plot(t[k], y[k], "o", ms=4, color=line.get_color())
    ax.axhline(0.0, color="0.4", lw=0.8)
    ax.axhline(-1e3 * tolerance, color="tab:red", lw=0.8, ls=":", label="-tolerance")
    if finite.size and float(finite.min()) < -tolerance:
        ax.axhspan(1e3 * float(finite.min()), -1e3 * tolerance, color="tab:red", alpha=0.08,
                   lw=0)
    if len(curves) <= 10:
        ax.legend(fontsize="x-small", loc="best", ncols=2)
