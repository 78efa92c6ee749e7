"""PROTOTYPE driver (see polish.py): TF-9's three-hole task (T = 2.5 s, N = 20) re-solved
with the exact hybrid dynamics, seeded by the reduced task's hop.

    PYTHONPATH=benchmarks/monoped_polish python benchmarks/monoped_polish/full.py [OUT]

1. The reduced task (one hole, T = 1 s) from the start-everywhere guess: the relaxed
   time-freezing plan (its homotopy finds one hop), then the exact re-solve along its
   sequence with a slip before the lift-off (8, then 16 nodes per interval, then 16 x 2
   RK4 steps): `run.py`'s chain.
2. The full task's guess: that hop three times, lift-offs at the control jumps 0.5, 1.25
   and 2.0 s (straight from stick), flights of 0.26 s (a schedule set by hand from the
   reduced hop, time scaled by 5/6), velocities and torques scaled with it.
3. The exact re-solve of the full task along stick, flight, stick, ... with holes of half
   width 0.25 (the authors' robot_ocp.m): as bumps with 8 nodes x 2 RK4 steps per
   interval, then 16 x 2, then with TF-9's ellipses (16 x 2), each warm started from the
   last; the touchdowns are free. (16 x 4 steps took more than 16 GB to build.)

Writes OUT/plan.npz (node times, states, controls, boundary states, phases) and prints
each re-solve's summary. The IPOPT paths are fragile: the run that made
benchmarks/monoped_exact_plan.npz (the same chain through scratch drivers) took 320, 72
and 2450 iterations for the three full-task re-solves (about 35 minutes in all); a rerun
of this script took 1021 iterations for the first (another local solution, objective
232.862 against 232.976), and its second stopped at the 3000-iteration cap (41 minutes in
all, nlp_failed; benchmarks/monoped_settings.md).
"""

import dataclasses
import sys
import time
import types
from pathlib import Path

import numpy as np
from polish import Phase, PolishOptions, polish_contact
from run import first_hop

from tfcontact.scenes.monoped import FULL_TASK, monoped_problem

LIFT_OFFS = (0.5, 1.25, 2.0)
FLIGHT = 0.26
REDUCED_LIFT_OFF, REDUCED_TOUCHDOWN = 0.6, 0.89


def reduced_hop():
    """`run.py 16:0 16:0:2`: the reduced task's verified exact plan."""
    relaxed, plan = first_hop()
    for per_node in (1, 2):
        plan = polish_contact(relaxed, plan.phases,
                              PolishOptions(substeps=16, steps_per_node=per_node,
                                            painleve_margin=0.0),
                              guess=(plan.t, plan.x, plan.u))
    return plan


def tiled_guess(hop, horizon: float, n_intervals: int, control_bound: float):
    """The hop three times on the schedule LIFT_OFFS / FLIGHT: (t, x, u) and the phases."""
    segments = []  # (start, end, start in the hop, end in the hop, hop index)
    previous = 0.0
    for j, lift_off in enumerate(LIFT_OFFS):
        segments.append((previous, lift_off, 0.0, REDUCED_LIFT_OFF, j))
        segments.append((lift_off, lift_off + FLIGHT, REDUCED_LIFT_OFF, REDUCED_TOUCHDOWN, j))
        previous = lift_off + FLIGHT
    segments.append((previous, horizon, REDUCED_TOUCHDOWN, 1.0, len(LIFT_OFFS) - 1))
    t_guess, x_guess = [], []
    for a, b, ra, rb, j in segments:
        scale = (b - a) / (rb - ra)
        for s in np.linspace(0.0, 1.0, 25):
            x = np.array([np.interp(ra + s * (rb - ra), hop.t, hop.x[:, i])
                          for i in range(hop.x.shape[1])])
            x[0] += j  # one metre further per hop
            x[x.size // 2:] /= scale
            t_guess.append(a + s * (b - a))
            x_guess.append(x)
    dt = horizon / n_intervals
    u_guess = []
    for k in range(n_intervals):
        middle = (k + 0.5) * dt
        a, b, ra, rb, _ = next(s for s in segments if s[0] <= middle <= s[1])
        scale = (b - a) / (rb - ra)
        hop_time = ra + (middle - a) / scale
        index = min(int(hop_time * len(hop.u)), len(hop.u) - 1)
        u_guess.append(hop.u[index] / scale**2)
    phases = [Phase("stick", 0.0, LIFT_OFFS[0])]
    for lift_off in LIFT_OFFS:
        phases += [Phase("flight", lift_off, lift_off + FLIGHT),
                   Phase("stick", lift_off + FLIGHT, horizon)]
    u_guess = np.clip(np.array(u_guess), -control_bound, control_bound)
    return (np.array(t_guess), np.array(x_guess), u_guess), tuple(phases)


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/monoped_exact")
    start = time.perf_counter()
    hop = reduced_hop()
    print(f"reduced hop: {hop.status}, {time.perf_counter() - start:.0f} s", flush=True)
    task = dataclasses.replace(FULL_TASK, hole_half_width=0.25)
    mp = monoped_problem(task)
    guess, phases = tiled_guess(hop, task.horizon, task.n_intervals, task.control_bound)
    ellipses = monoped_problem(dataclasses.replace(task, hole_form="ellipse"))
    levels = [(mp, 8, 2), (mp, 16, 2), (ellipses, 16, 2)]
    plan = None
    for problem, nodes, per_node in levels:
        plan = polish_contact(types.SimpleNamespace(problem=problem.problem), phases,
                              PolishOptions(substeps=nodes, steps_per_node=per_node,
                                            painleve_margin=0.0), guess=guess)
        holes = float(np.min(mp.hole_values(plan.x[:, :4])))
        print(f"{problem.task.hole_form} holes, {nodes} x {per_node} RK4 steps: {plan.status}; "
              f"smallest ellipse value {holes:.3g} (>= 0 outside TF-9's holes); "
              f"{time.perf_counter() - start:.0f} s so far", flush=True)
        print("local defects", np.array2string(np.asarray(plan.verification.local_defects),
                                               precision=3), flush=True)
        if not plan.solved:
            break
        guess, phases = (plan.t, plan.x, plan.u), plan.phases
    out.mkdir(parents=True, exist_ok=True)
    np.savez(out / "plan.npz", t=plan.t, x=plan.x, u=plan.u, boundary=plan.boundary_states,
             phase_modes=np.array([p.mode for p in plan.phases]),
             phase_starts=np.array([p.start for p in plan.phases]),
             local_defects=np.asarray(plan.verification.local_defects))
    print(f"wrote {out / 'plan.npz'}; {plan.status} after {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
