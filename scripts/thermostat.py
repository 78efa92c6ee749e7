"""TF-14: the thermostat with hysteresis, simulated by time-freezing + FESD.

The relay (heater off at y = 20, on at y = 18, y(0) = 15 heating) becomes the
time-freezing hysteresis system of DESIGN.md 4.5 (`tfcontact.scenes.thermostat`,
push gain a = 5), integrated by `tfcontact.fesd.simulate` over the numerical horizon
T_sim = 4 with N_sim = 40 steps, N_FE = 2, Radau IIA (s = 2) (PROBLEMS.md TF-14) and
the Scholtes relaxation (the paper's l_inf steering, here `LinfPenalty`, stalls at the
first switch: (psi, w) = (1, 0) is a triple point of the Voronoi cells where the push-down
field vanishes, so x' = 0 is in the Filippov set and the homotopy may stay there).
It prints the switches found (in numerical time tau and in physical time t, the clock)
against the closed form, and writes a figure: y and w
against tau, the clock t(tau) with its frozen pieces, and y against physical time.

Usage:
    python scripts/thermostat.py [--out benchmarks] [--scheme radau|gauss] [--relaxation ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from tfcontact.fesd import GaussLegendre, RadauIIA, simulate
from tfcontact.mpcc import Homotopy, Ipopt, LinfPenalty, Scholtes
from tfcontact.scenes.thermostat import (
    TF14,
    numerical_switch_intervals,
    physical_time,
    switching_times,
    temperature,
    time_freezing_system,
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent.parent / "benchmarks")
    parser.add_argument("--scheme", choices=("radau", "gauss"), default="radau")
    parser.add_argument(
        "--relaxation", choices=("scholtes", "linf"), default="scholtes",
        help="linf (the paper's steering) sticks at the first switch, see the report",
    )
    args = parser.parse_args(argv)
    problem = TF14
    system = time_freezing_system(problem)
    y0 = system.initial_state([problem.y0], 0.0)
    scheme = RadauIIA(2) if args.scheme == "radau" else GaussLegendre(2)
    started = time.process_time()
    sim = simulate(
        system.pss,
        y0,
        horizon=problem.horizon,
        n_steps=problem.n_steps,
        scheme=scheme,
        n_finite_elements=2,
        relaxation=Scholtes() if args.relaxation == "scholtes" else LinfPenalty(),
        homotopy=Homotopy(sigma_0=1.0, kappa=0.1, tolerance=1e-9),
        nlp=Ipopt(tol=1e-10),
    )
    cpu = time.process_time() - started
    tau, y = sim.t, sim.x
    w, clock = y[:, system.memory_index], y[:, system.clock_index]

    starts, ends = numerical_switch_intervals(problem)
    t_exact, _ = switching_times(problem, t_end=float(clock[-1]))
    # The frozen pieces found: runs of finite elements on which the clock stands still.
    frozen = np.diff(clock) <= 1e-6 * np.diff(tau)
    padded = np.concatenate([[False], frozen, [False]]).astype(int)
    first = np.flatnonzero(np.diff(padded) == 1)
    last = np.flatnonzero(np.diff(padded) == -1)
    found_starts, found_ends = tau[first], tau[last]
    found_t = clock[first]
    print(
        f"thermostat (TF-14): {sim.n_steps} steps, {sim.n_nlps} NLPs, {sim.total_iterations} "
        f"IPOPT iterations, CPU {cpu:.2f} s, max complementarity residual {sim.residual:.1e}"
    )
    print(f"{'switch':>6} {'tau start':>10} {'exact':>10} {'tau end':>10} {'exact':>10} "
          f"{'t (clock)':>10} {'exact':>10} {'y':>8}")
    for k in range(max(len(found_starts), len(starts))):
        row = [
            found_starts[k] if k < len(found_starts) else np.nan,
            starts[k] if k < len(starts) else np.nan,
            found_ends[k] if k < len(found_ends) else np.nan,
            ends[k] if k < len(ends) else np.nan,
            found_t[k] if k < len(found_t) else np.nan,
            t_exact[k] if k < len(t_exact) else np.nan,
            np.interp(found_starts[k], tau, y[:, 0]) if k < len(found_starts) else np.nan,
        ]
        print(f"{k + 1:>6} " + " ".join(f"{v:10.6f}" for v in row[:-1]) + f" {row[-1]:8.4f}")
    running = np.concatenate([[True], ~frozen])
    err = np.max(np.abs(y[running, 0] - temperature(problem, clock[running])))
    print(f"physical trajectory: max |y(t) - y_exact(t)| = {err:.2e} deg C over the unfrozen "
          f"element boundaries (exact: the closed-form relay)")
    t_end_exact = physical_time(problem, problem.horizon)[0]
    print(
        f"physical time at tau = {problem.horizon:g}: {clock[-1]:.9f} s; the exact "
        f"time-freezing clock: {t_end_exact:.9f} s ({len(starts)} frozen pieces of "
        f"{problem.push_duration:g}); the lag is numerical time spent creeping into the "
        "triple point (psi, w) = (1, 0) or (0, 1) before each push"
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    axes[0].plot(tau, y[:, 0], label="y (temperature)")
    axes[0].axhline(problem.y_on, color="k", ls=":", lw=0.8)
    axes[0].axhline(problem.y_off, color="k", ls=":", lw=0.8)
    ax_w = axes[0].twinx()
    ax_w.plot(tau, w, color="C1", label="w (memory)")
    ax_w.set_ylabel("w")
    axes[0].set(xlabel="numerical time tau [s]", ylabel="y [deg C]", title="states")
    axes[1].plot(tau, clock, label="clock t(tau)")
    axes[1].plot(tau, physical_time(problem, tau), "k--", lw=0.8, label="exact")
    for a, b in zip(starts, ends, strict=True):
        axes[1].axvspan(a, b, color="C1", alpha=0.15)
    axes[1].set(xlabel="numerical time tau [s]", ylabel="physical time t [s]",
                title="clock (shaded: frozen, exact)")
    axes[1].legend()
    axes[2].plot(clock[running], y[running, 0], ".-", ms=3, label="FESD")
    t_fine = np.linspace(0.0, clock[-1], 400)
    axes[2].plot(t_fine, temperature(problem, t_fine), "k--", lw=0.8, label="exact")
    axes[2].legend()
    for t_s in t_exact:
        axes[2].axvline(t_s, color="k", ls=":", lw=0.8)
    axes[2].set(xlabel="physical time t [s]", ylabel="y [deg C]",
                title="physical time (dotted: exact switches)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "thermostat.png"
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
