"""Figures of a trajectory (matplotlib, Agg, no pyplot state): PNG and SVG.

Each figure shows numerical time tau on the left and, where it makes sense, physical
time t on the right (frozen pieces dropped, DESIGN.md 4.1); frozen pieces are shaded
in numerical time.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tfcontact.errors import InvalidInput
from tfcontact.viz.trajectory import Trajectory, physical_time

_FORMATS = ("png", "svg")
_FROZEN_STYLE = {"color": "tab:blue", "alpha": 0.15, "lw": 0}


def plot_trajectory(
    traj: Trajectory,
    out_dir: str | os.PathLike,
    *,
    formats: tuple[str, ...] = _FORMATS,
    rate_tol: float | None = None,
    dpi: int = 120,
) -> list[Path]:
    """Write the standard figures of `traj` to `out_dir`.

    Figures (each in every format of `formats`):

    * `states`: q, v and u against numerical time tau (left) and physical time t (right).
    * `clock`: the clock t(tau) with frozen pieces shaded, and the speed of time s(tau).
    * `contacts`: gaps [m] and normal velocities [m/s] against tau and against t.
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
    phys = physical_time(traj, rate_tol=rate_tol)
    figures = {
        "states": _states(traj, phys),
        "clock": _clock(traj, phys),
        "contacts": _contacts(traj, phys),
    }
    history = _history(traj.solver)
    if history is not None:
        figures["homotopy"] = _homotopy(*history)
    written = []
    for name, fig in figures.items():
        for fmt in formats:
            path = out / f"{name}.{fmt}"
            fig.savefig(path, format=fmt, dpi=dpi, metadata={"Date": None} if fmt == "svg"
                        else None)
            written.append(path)
    return written


def _new(rows: int, cols: int, height: float = 2.2):
    # fixed margins: constrained layout would double the drawing time
    fig = Figure(figsize=(5.0 * cols, height * rows + 0.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False, sharex="col")
    fig.subplots_adjust(left=0.85 / (5.0 * cols), right=0.98, bottom=0.5 / (height * rows + 0.6),
                        top=1 - 0.35 / (height * rows + 0.6), hspace=0.12, wspace=0.15)
    return fig, axes


def _shade(ax, phys) -> None:
    for a, b in phys.frozen:
        ax.axvspan(a, b, **_FROZEN_STYLE)


def _lines(ax, x, y, label: str) -> None:
    if y.shape[1] == 0:
        ax.text(0.5, 0.5, f"no {label}", ha="center", va="center", transform=ax.transAxes)
        return
    for j in range(y.shape[1]):
        ax.plot(x, y[:, j], lw=1.2, label=f"{label}[{j}]")
    if y.shape[1] <= 8:
        ax.legend(fontsize="x-small", loc="best", ncols=2)


def _states(traj: Trajectory, phys):
    fig, axes = _new(3, 2)
    rows = (("q", traj.q, phys.q, "q"), ("v", traj.v, phys.v, "v"), ("u", traj.u, phys.u, "u"))
    for r, (name, y_tau, y_t, label) in enumerate(rows):
        _lines(axes[r, 0], traj.tau, y_tau, label)
        _shade(axes[r, 0], phys)
        _lines(axes[r, 1], phys.t, y_t, label)
        axes[r, 0].set_ylabel(name)
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


def _contacts(traj: Trajectory, phys):
    fig, axes = _new(2, 2)
    rows = (("gap [m]", traj.gap, phys.gap, "gap"),
            ("normal velocity [m/s]", traj.normal_velocity, phys.normal_velocity, "vn"))
    for r, (name, y_tau, y_t, label) in enumerate(rows):
        _lines(axes[r, 0], traj.tau, y_tau, label)
        _shade(axes[r, 0], phys)
        _lines(axes[r, 1], phys.t, y_t, label)
        axes[r, 0].set_ylabel(name)
        for ax in axes[r]:
            ax.axhline(0.0, color="0.5", lw=0.8)
    axes[0, 0].set_title("numerical time (frozen pieces shaded)")
    axes[0, 1].set_title("physical time (frozen pieces dropped)")
    axes[-1, 0].set_xlabel(r"$\tau$ [s]")
    axes[-1, 1].set_xlabel("t [s]")
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
