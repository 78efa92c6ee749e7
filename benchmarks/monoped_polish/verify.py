"""Check a saved plan of full.py again: the exact reference replays it interval by interval
(`polish._verify`, the checks of `tfcontact.ocp.contact.verify_plan`), the friction cone
is checked on the contact forces and impulses recomputed from its states and controls,
and TF-9's holes are measured at its nodes.

    PYTHONPATH=benchmarks/monoped_polish python benchmarks/monoped_polish/verify.py \\
        benchmarks/monoped_exact_plan.npz
"""

import dataclasses
import sys

import numpy as np
from polish import STICK, PolishOptions, _Dynamics, _verify

from tfcontact.scenes.monoped import FULL_TASK, monoped_problem


def contact_values(plan, dyn: _Dynamics, horizon: float):
    """(stick forces (n, 2) [N], touchdown impulses (m, 2) [N s]) of a saved plan: the
    stick force at both ends of every RK4 segment inside a stick phase, with that
    segment's control (so at a control jump with both controls, as the re-solve's rows
    hold them), and the impulse of each touchdown (two nodes at one time)."""
    t, x, u = plan["t"], plan["x"], plan["u"]
    starts, modes = plan["phase_starts"], plan["phase_modes"]
    dt = horizon / len(u)
    forces, impulses = [], []
    for i in range(len(t) - 1):
        if t[i + 1] == t[i]:
            impulses.append(np.asarray(dyn.impact(x[i])[1]).ravel())
            continue
        middle = 0.5 * (t[i] + t[i + 1])
        if modes[np.searchsorted(starts, middle) - 1] != STICK:
            continue
        u_k = u[min(int(middle / dt), len(u) - 1)]
        forces += [np.asarray(dyn.force(x[j], u_k)).ravel() for j in (i, i + 1)]
    return np.array(forces).reshape(-1, 2), np.array(impulses).reshape(-1, 2)


def verify_saved(path):
    """(Verification, smallest ellipse value) of a plan.npz written by full.py."""
    plan = np.load(path)
    task = dataclasses.replace(FULL_TASK, hole_half_width=0.25, hole_form="ellipse")
    mp = monoped_problem(task)
    cls = mp.system.cls
    dyn = _Dynamics(cls)
    n = task.n_intervals
    clocks = np.array([k * task.horizon / n for k in range(n + 1)])
    forces, impulses = contact_values(plan, dyn, task.horizon)
    verification = _verify(cls, mp.problem, clocks, plan["boundary"], plan["u"], plan["x"],
                           dyn, forces, impulses, PolishOptions())
    return verification, float(np.min(mp.hole_values(plan["x"][:, :4])))


if __name__ == "__main__":
    verification, holes = verify_saved(sys.argv[1])
    print(verification.summary())
    print(f"smallest ellipse value {holes:.3g} (>= 0 outside TF-9's holes)")
