"""Figures of a trajectory (matplotlib, Agg, no pyplot state): PNG and SVG.

Each figure shows numerical time tau on the left and, where it makes sense, physical
time t on the right (frozen pieces dropped, DESIGN.md 4.1); frozen pieces are shaded
in numerical time. Curves carry the plan's own names with units ("x [m]", "v_x [m/s]",
"u_knee [N m]"; `tfcontact.viz.labels`), contacts their frame names.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tfcontact.errors import InvalidInput, TfcontactError
from tfcontact.plan_format.trajectory import (
    STANCE_GAP,
    PhysicalSamples,
    Trajectory,
    physical_time,
    stance_intervals,
)
from tfcontact.robot import BASE_COORDINATES, Terrain
from tfcontact.viz.labels import Labels, trajectory_labels
from tfcontact.viz.terrain_view import (
    scene_terrain,
    section_grid,
    surface_normals,
    surface_tangents,
    terrain_section,
)

_FORMATS = ("png", "svg")
_FROZEN_STYLE = {"color": "tab:blue", "alpha": 0.15, "lw": 0}
_LEGEND_WIDTH = 1.8  # [in] room right of the axes for a legend of names with units


def plot_trajectory(
    traj: Trajectory,
    out_dir: str | os.PathLike,
    *,
    formats: tuple[str, ...] = _FORMATS,
    rate_tol: float | None = None,
    dpi: int = 120,
    robot: Any = None,
) -> list[Path]:
    """Write the standard figures of `traj` to `out_dir`.

    Figures (each in every format of `formats`):

    * `states`: q, v and u against numerical time tau (left) and physical time t (right),
      each curve named with its unit.
    * `clock`: the clock t(tau) with frozen pieces shaded, and the speed of time s(tau).
    * `contacts`: gaps [m] and normal velocities [m/s] against tau and against t.
    * `contact_diagram`: which contact touches when (gap <= 1 mm, `stance_intervals`),
      one row per contact against physical time: the gait.
    * `path`: the contact spheres' centres (and a planar or floating base's x, z) in the
      x-z plane over a section of the scene's terrain (flat ground, slopes, steps,
      holes); the contacts need the robot (`robot`, or rebuilt from `traj.robot`).
    * `force_<contact>` (one per contact, named by its frame): the contact force [N]
      against physical time, split into its normal and tangential parts along the
      terrain's normal where the contact is, the friction cone's bounds +-mu f_n when the
      terrain gives mu > 0, and the impulses [N s] of the impacts.
    * `homotopy`: complementarity residual per homotopy step, from
      `traj.solver["history"]` (entries with `residual` (or `complementarity`), optionally
      `sigma`: e.g. `dataclasses.asdict` of each `tfcontact.mpcc` `HomotopyStep`);
      written only when that history is present.

    Args:
        traj: the trajectory.
        out_dir: output folder (created if missing).
        formats: file formats, any of "png", "svg".
        rate_tol: clock-rate tolerance for frozen pieces (see `physical_time`); default
            the trajectory's own `frozen_rate_tol`.
        dpi: resolution of the PNG files [dots per inch].
        robot: a Pinocchio model of the trajectory's robot, a (model, visual_model) pair
            or an object with `.model`; None rebuilds it from `traj.robot` (without it,
            the path figure has no contact paths and forces are split along the normal of
            a terrain of one plane, world z otherwise).

    Returns:
        The paths written.
    """
    if not isinstance(traj, Trajectory):
        raise InvalidInput(f"`traj` must be a Trajectory, got {type(traj).__name__}")
    bad = [f for f in formats if f not in _FORMATS]
    if bad or not formats:
        raise InvalidInput(f"`formats` must be a non-empty subset of {_FORMATS}, got {formats!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = trajectory_figures(traj, rate_tol=rate_tol, robot=robot)
    written = []
    for name, fig in figures.items():
        for fmt in formats:
            path = out / f"{name}.{fmt}"
            fig.savefig(path, format=fmt, dpi=dpi, metadata={"Date": None} if fmt == "svg"
                        else None)
            written.append(path)
    return written


def trajectory_figures(traj: Trajectory, *, rate_tol: float | None = None,
                       robot: Any = None) -> dict[str, Figure]:
    """The figures of `plot_trajectory` as matplotlib `Figure`s (Agg canvas), by file stem,
    to embed or restyle them; arguments as `plot_trajectory`'s."""
    if not isinstance(traj, Trajectory):
        raise InvalidInput(f"`traj` must be a Trajectory, got {type(traj).__name__}")
    phys = physical_time(traj, rate_tol=rate_tol)
    model = robot_model(traj, robot)
    labels = trajectory_labels(traj, model)
    positions = None if model is None else contact_positions(traj, model)
    terrain = scene_terrain(traj.scene)
    figures = {
        "states": _states(traj, phys, labels),
        "clock": _clock(traj, phys),
        "contacts": _contacts(traj, phys, labels),
        "contact_diagram": _contact_diagram(phys, labels),
        "path": _path(traj, phys, labels, terrain, positions),
    }
    normals, mu = _surface(traj, terrain, positions)
    for k, name in enumerate(force_figure_names(labels.contacts)):
        figures[name] = _force(traj, phys, k, labels.contacts[k], normals[:, k], mu[:, k],
                               located=positions is not None)
    history = _history(traj.solver)
    if history is not None:
        figures["homotopy"] = _homotopy(*history)
    return figures


def force_figure_names(contacts: tuple[str, ...] | list[str]) -> list[str]:
    """The file stems of the contact-force figures: `force_<frame>` (characters other
    than letters, digits, `.`, `_` and `-` replaced by `_`; a repeated name gets `_<k>`)."""
    stems: list[str] = []
    for k, name in enumerate(contacts):
        stem = "force_" + (re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or str(k))
        stems.append(stem if stem not in stems else f"{stem}_{k}")
    return stems


def robot_model(traj: Trajectory, robot: Any = None) -> Any:
    """The Pinocchio model of `robot` (a model, a (model, visual_model) pair or an object
    with `.model`) or, for None, of the robot rebuilt from `traj.robot`; None when it
    cannot be rebuilt or does not fit the trajectory's q."""
    if robot is None:
        if not traj.robot:
            return None
        from tfcontact.robot import RobotSpec, load_robot

        try:
            model = load_robot(RobotSpec.from_dict(traj.robot)).model
        except TfcontactError:
            return None
    elif isinstance(robot, tuple):
        model = robot[0]
    else:
        model = getattr(robot, "model", robot)
    if not hasattr(model, "nq"):
        raise InvalidInput(
            "`robot` must be None, a Pinocchio model, a (model, visual_model) pair or an "
            f"object with `.model`, got {type(robot).__name__}")
    return model if model.nq == traj.q.shape[1] else None


def contact_positions(traj: Trajectory, model: Any) -> np.ndarray | None:
    """World positions [m] of the contact spheres' centres (the frames of
    `traj.robot["contacts"]`) at every sample, shape (N, nc, 3); None when a frame is
    missing from `model`."""
    import pinocchio as pin

    specs = traj.robot.get("contacts", []) or []
    frames = [spec.get("frame") if isinstance(spec, dict) else None for spec in specs]
    if len(frames) != traj.n_contacts or not all(
            isinstance(f, str) and model.existFrame(f) for f in frames):
        return None
    ids = [model.getFrameId(f) for f in frames]
    data = model.createData()
    out = np.empty((traj.n_samples, len(ids), 3))
    for i, q in enumerate(traj.q):
        pin.framesForwardKinematics(model, data, q)
        for k, frame in enumerate(ids):
            out[i, k] = data.oMf[frame].translation
    return out


def _legend_columns(entries: int) -> int:
    return max(1, math.ceil(entries / 12))


def _new(rows: int, cols: int, height: float = 2.2, legend: bool | int = False):
    # fixed margins: constrained layout would double the drawing time; `legend`: room for
    # that many legend columns right of the axes (True: one)
    extra = _LEGEND_WIDTH * int(legend)
    width = 5.0 * cols + extra
    fig = Figure(figsize=(width, height * rows + 0.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False, sharex="col")
    fig.subplots_adjust(left=0.85 / width, right=1 - (0.1 + extra) / width,
                        bottom=0.5 / (height * rows + 0.6),
                        top=1 - 0.35 / (height * rows + 0.6), hspace=0.12, wspace=0.15)
    return fig, axes


def _shade(ax, phys) -> None:
    for a, b in phys.frozen:
        ax.axvspan(a, b, **_FROZEN_STYLE)


def _lines(ax, x, y, names: tuple[str, ...] | list[str], what: str, legend: bool) -> None:
    if y.shape[1] == 0:
        ax.text(0.5, 0.5, f"no {what}", ha="center", va="center", transform=ax.transAxes)
        return
    for j in range(y.shape[1]):
        # beyond the 10 colours of the cycle, dashes tell the curves apart
        ax.plot(x, y[:, j], lw=1.2, label=names[j], ls="-" if j % 20 < 10 else "--")
    if legend:
        ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  ncols=_legend_columns(y.shape[1]), borderaxespad=0.0, frameon=False)


def _units(units: tuple[str, ...]) -> str:
    return f" [{', '.join(units)}]" if units else ""


def _states(traj: Trajectory, phys: PhysicalSamples, labels: Labels):
    widest = max(traj.q.shape[1], traj.v.shape[1], traj.u.shape[1])
    fig, axes = _new(3, 2, legend=_legend_columns(widest))
    rows = (("configuration q" + _units(labels.q_units), traj.q, phys.q, labels.q, "q"),
            ("velocity v" + _units(labels.v_units), traj.v, phys.v, labels.v, "v"),
            ("control u" + _units(labels.u_units), traj.u, phys.u, labels.u, "controls"))
    for r, (name, y_tau, y_t, names, what) in enumerate(rows):
        _lines(axes[r, 0], traj.tau, y_tau, names, what, legend=False)
        _shade(axes[r, 0], phys)
        _lines(axes[r, 1], phys.t, y_t, names, what, legend=True)
        axes[r, 0].set_ylabel(name, fontsize="small")
    axes[0, 0].set_title("numerical time (frozen pieces shaded)")
    axes[0, 1].set_title("physical time (frozen pieces dropped)")
    axes[-1, 0].set_xlabel(r"$\tau$ [s]")
    axes[-1, 1].set_xlabel("t [s]")
    return fig


def _clock(traj: Trajectory, phys):
    fig, axes = _new(2, 1)
    ax = axes[0, 0]
    ax.plot(traj.tau, traj.clock, lw=1.5, color="k")
    _shade(ax, phys)
    ax.set_ylabel(r"clock t($\tau$) [s]")
    ax.set_title(f"clock: {len(phys.frozen)} frozen piece(s) shaded")
    ax = axes[1, 0]
    ax.step(traj.tau, traj.s, where="post", lw=1.5, color="tab:orange")
    _shade(ax, phys)
    ax.set_ylabel("speed of time s [-]")
    ax.set_xlabel(r"$\tau$ [s]")
    return fig


def _contacts(traj: Trajectory, phys: PhysicalSamples, labels: Labels):
    fig, axes = _new(2, 2, legend=_legend_columns(traj.n_contacts))
    rows = (("gap [m]", traj.gap, phys.gap, "gap"),
            ("normal velocity [m/s]", traj.normal_velocity, phys.normal_velocity, "vn"))
    for r, (name, y_tau, y_t, what) in enumerate(rows):
        names = [f"{what} {c}" for c in labels.contacts]
        _lines(axes[r, 0], traj.tau, y_tau, names, "contacts", legend=False)
        _shade(axes[r, 0], phys)
        _lines(axes[r, 1], phys.t, y_t, names, "contacts", legend=True)
        axes[r, 0].set_ylabel(name)
        for ax in axes[r]:
            ax.axhline(0.0, color="0.5", lw=0.8)
    axes[0, 0].set_title("numerical time (frozen pieces shaded)")
    axes[0, 1].set_title("physical time (frozen pieces dropped)")
    axes[-1, 0].set_xlabel(r"$\tau$ [s]")
    axes[-1, 1].set_xlabel("t [s]")
    return fig


def _contact_diagram(phys: PhysicalSamples, labels: Labels):
    schedule = stance_intervals(phys.t, phys.gap)
    n = len(schedule)
    fig, axes = _new(1, 1, height=max(1.2, 0.45 * n + 0.6))
    ax = axes[0, 0]
    span = float(phys.t[-1] - phys.t[0]) if phys.t.size else 1.0
    for row, intervals in enumerate(schedule):
        # a touch at one instant (an impact and lift-off together) still shows as a sliver
        bars = [(a, max(b - a, 2e-3 * span)) for a, b in intervals]
        ax.broken_barh(bars, (n - 1 - row - 0.35, 0.7), color=f"C{row % 10}")
    ax.set_yticks(range(n), list(reversed(labels.contacts)), fontsize="small")
    ax.set_ylim(-0.6, n - 0.4)
    if phys.t.size:
        ax.set_xlim(float(phys.t[0]), float(phys.t[-1]))
    ax.set_xlabel("t [s]")
    ax.set_title(f"contacts down (gap <= {1e3 * STANCE_GAP:g} mm)")
    return fig


def _base_xz(traj: Trajectory) -> tuple[int, int] | None:
    """Columns of q holding a planar or floating base's x and z (the root joint comes
    first in q), or None."""
    base = traj.robot.get("base")
    names = [name for name, _ in BASE_COORDINATES.get(base, ())] if isinstance(base, str) else []
    if "x" in names and "z" in names:
        return names.index("x"), names.index("z")
    return None


def _path(traj: Trajectory, phys: PhysicalSamples, labels: Labels, terrain: Terrain | None,
          positions: np.ndarray | None):
    fig = Figure(figsize=(8.0 + _LEGEND_WIDTH, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.09, 0.12, 0.9 - (_LEGEND_WIDTH + 0.1) / fig.get_figwidth(), 0.78))
    xs, zs = [], []
    if positions is not None:
        at = positions[phys.index]
        radii = [float(c.get("radius", 0.0)) for c in traj.robot["contacts"]]
        for k, name in enumerate(labels.contacts):
            (line,) = ax.plot(at[:, k, 0], at[:, k, 2], lw=1.3, label=f"{name} (centre)",
                              marker="o", markevery=[0], ms=3)  # a foot at rest shows
            for i in (0, -1):  # the sphere at the start and at the end
                ax.add_patch(_circle(at[i, k, [0, 2]], radii[k], line.get_color(), 0.25))
            for a, _ in phys.frozen_index:  # and at each impact
                ax.add_patch(_circle(positions[a, k, [0, 2]], radii[k], line.get_color(), 0.6))
            xs += [at[:, k, 0]]
            zs += [at[:, k, 2]]
        y_cut = float(np.mean(at[:, :, 1])) if at.size else 0.0
    else:
        y_cut = 0.0
    base = _base_xz(traj)
    if base is not None:
        ax.plot(phys.q[:, base[0]], phys.q[:, base[1]], "--", color="0.25", lw=1.0,
                label="base (x, z)", marker="o", markevery=[0], ms=3)
        xs.append(phys.q[:, base[0]])
        zs.append(phys.q[:, base[1]])
    if xs:
        lo, hi = float(min(x.min() for x in xs)), float(max(x.max() for x in xs))
    else:
        lo, hi = -0.5, 0.5
    pad = max(0.15 * (hi - lo), 0.1)
    # equal scales on both axes: widen whichever span the axes' shape asks for
    box = ax.get_position()
    ratio = box.width * fig.get_figwidth() / (box.height * fig.get_figheight())
    z_lo = min(z.min() for z in zs) if zs else 0.0
    z_hi = max(z.max() for z in zs) if zs else 0.0
    walls = [(np.asarray(b["center"], dtype=float), np.asarray(b["size"], dtype=float))
             for b in traj.scene.get("boxes", []) or []]
    for c, size in walls:
        z_lo, z_hi = min(z_lo, c[2] - size[2] / 2), max(z_hi, c[2] + size[2] / 2)
    span = max(hi - lo + 2 * pad, (z_hi - z_lo + 2 * pad) * ratio)
    mid = (lo + hi) / 2
    grid, ground = _section(terrain, mid - span / 2, mid + span / 2, y_cut)
    finite = np.isfinite(ground)
    if finite.any():
        z_lo, z_hi = min(z_lo, float(ground[finite].min())), max(z_hi, float(ground[finite].max()))
    if (z_hi - z_lo + 2 * pad) * ratio > span:
        span = (z_hi - z_lo + 2 * pad) * ratio
        grid, ground = _section(terrain, mid - span / 2, mid + span / 2, y_cut)
        finite = np.isfinite(ground)
    bottom = (z_lo + z_hi) / 2 - span / ratio / 2
    if finite.any():
        ax.fill_between(grid, bottom, np.where(finite, ground, bottom), where=finite,
                        color="0.82", lw=0, label="terrain")
        ax.plot(grid, ground, color="0.35", lw=1.0)
    for k, (c, size) in enumerate(walls):
        from matplotlib.patches import Rectangle

        ax.add_patch(Rectangle((c[0] - size[0] / 2, c[2] - size[2] / 2), size[0], size[2],
                               color="0.65", lw=0, label="scene box" if k == 0 else None))
    for k, hole in enumerate(traj.scene.get("holes", []) or []):
        if isinstance(hole, dict) and "profile" in hole:
            profile = np.asarray(hole["profile"], dtype=float)
            ax.fill(profile[:, 0], profile[:, 1], color="tab:red", alpha=0.3, lw=0,
                    label="keep-out region" if k == 0 else None)
    ax.set_xlim(mid - span / 2, mid + span / 2)
    ax.set_ylim(bottom, bottom + span / ratio)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(f"path in the x-z plane (physical time); terrain section at y = {y_cut:.3g} m"
                 + ("" if positions is not None else "; contacts unknown (robot not found)"),
                 fontsize="small")
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False, borderaxespad=0.0)
    return fig


def _section(terrain: Terrain | None, lo: float, hi: float, y: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """x samples in [lo, hi] and the terrain's height there (NaN: none) [m]."""
    if terrain is None:
        return np.array([lo, hi]), np.full(2, np.nan)
    grid = section_grid(terrain, lo, hi)
    return grid, terrain_section(terrain, grid, y)


def _circle(center: np.ndarray, radius: float, color: str, alpha: float):
    from matplotlib.patches import Circle

    return Circle((float(center[0]), float(center[1])), max(radius, 1e-3), fill=False,
                  color=color, alpha=alpha, lw=0.8)


def _surface(traj: Trajectory, terrain: Terrain | None, positions: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Per sample and contact: the terrain's unit normal (N, nc, 3) where the contact is
    (without positions: a single plane's normal, else z; no terrain: z) and its friction
    coefficient mu (N, nc), NaN where unknown (no positions, no support)."""
    n, nc = traj.n_samples, traj.n_contacts
    mu = np.full((n, nc), np.nan)
    if terrain is None:
        return np.broadcast_to(np.array([0.0, 0.0, 1.0]), (n, nc, 3)), mu
    if positions is None:
        planes = terrain.planes
        normal = planes[0].normal if len(planes) == 1 and not terrain.boxes else (0, 0, 1)
        return np.broadcast_to(np.asarray(normal, dtype=float), (n, nc, 3)), mu
    normals = surface_normals(terrain, positions.reshape(-1, 3)).reshape(n, nc, 3)
    for i, k in zip(*np.nonzero(np.any(traj.force != 0, axis=2)
                                | np.any(traj.impulse != 0, axis=2)), strict=True):
        x, y = positions[i, k, :2]
        if math.isfinite(terrain.height_at(x, y)):
            mu[i, k] = terrain.friction_at(x, y)
    return normals, mu


def _split(vectors: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(normal, tangent 1, tangent 2) components of world vectors (k, 3) [same unit]."""
    t1, t2 = surface_tangents(normals)
    return np.stack([np.sum(vectors * normals, axis=1), np.sum(vectors * t1, axis=1),
                     np.sum(vectors * t2, axis=1)], axis=1)


def _force(traj: Trajectory, phys: PhysicalSamples, k: int, name: str, normals: np.ndarray,
           mu: np.ndarray, *, located: bool):
    fig, axes = _new(2, 1, height=2.4, legend=True)
    parts = _split(traj.force[phys.index, k], normals[phys.index])
    spread = float(np.max(np.abs(parts))) if parts.size else 0.0
    ax = axes[0, 0]
    styles = (("normal $f_n$ [N]", "tab:blue"), ("tangential $f_{t1}$ [N]", "tab:orange"),
              ("tangential $f_{t2}$ [N]", "tab:green"))
    for j, (text, color) in enumerate(styles):
        if j < 2 or np.max(np.abs(parts[:, j])) > 1e-12 * max(spread, 1.0):
            # a force acts on the interval that starts at its sample
            ax.step(phys.t, parts[:, j], where="post", lw=1.3, color=color, label=text)
    cone = mu[phys.index] * parts[:, 0]
    if np.any(np.nan_to_num(mu) > 0):
        ax.step(phys.t, cone, where="post", ls="--", lw=0.9, color="0.4",
                label=r"cone $\pm\mu f_n$")
        ax.step(phys.t, -cone, where="post", ls="--", lw=0.9, color="0.4")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("force [N]")
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False, borderaxespad=0.0)
    where = ("the terrain's normal n at the contact" if located
             else "the ground's normal n (contact position unknown)")
    ax.set_title(f"contact {name}: force on the robot along {where}", fontsize="small")
    ax = axes[1, 0]
    hits = np.flatnonzero(np.any(traj.impulse[:, k] != 0, axis=1))
    if hits.size:
        impulses = _split(traj.impulse[hits, k], normals[hits])
        times = traj.clock[hits]
        for j, (text, color) in enumerate(styles):
            if j == 2 and not np.any(np.abs(impulses[:, 2]) > 0):
                continue
            ax.vlines(times, 0.0, impulses[:, j], color=color, lw=1.5)
            ax.plot(times, impulses[:, j], "o", color=color, ms=4,
                    label=text.replace("f_", r"\Lambda_").replace("[N]", "[N s]"))
        ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  frameon=False, borderaxespad=0.0)
    else:
        ax.text(0.5, 0.5, "no impulses", ha="center", va="center", transform=ax.transAxes)
    for t in phys.impacts:
        for a in axes[:, 0]:
            a.axvline(t, color="0.6", lw=0.8, ls=":")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_ylabel("impulse [N s]")
    ax.set_xlabel("t [s]")
    return fig


def _history(solver: dict):
    """(residuals, sigmas or None) from `solver['history']`, or None when absent."""
    history = solver.get("history")
    if not isinstance(history, list) or not history:
        return None
    residuals, sigmas = [], []
    for step in history:
        if not isinstance(step, dict):
            return None
        value = next((step[k] for k in ("complementarity", "complementarity_residual",
                                         "residual") if k in step), None)
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return None
        residuals.append(float(value))
        sigma = step.get("sigma")
        sigmas.append(float(sigma) if isinstance(sigma, (int, float)) else math.nan)
    sigmas_arr = np.array(sigmas)
    return np.array(residuals), (None if np.all(np.isnan(sigmas_arr)) else sigmas_arr)


def _homotopy(residuals: np.ndarray, sigmas: np.ndarray | None):
    fig, axes = _new(1, 1, height=3.0)
    ax = axes[0, 0]
    steps = np.arange(1, residuals.size + 1)
    floor = np.finfo(float).tiny
    ax.semilogy(steps, np.maximum(residuals, floor), "o-", label="complementarity residual")
    if sigmas is not None:
        ax.semilogy(steps, np.maximum(sigmas, floor), "s--", label=r"relaxation $\sigma$")
    ax.set_xlabel("homotopy step (NLP)")
    ax.set_xticks(steps)
    ax.legend(fontsize="small")
    ax.set_title("MPCC homotopy")
    return fig
