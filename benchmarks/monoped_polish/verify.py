"""Check a saved plan of full.py again: the exact reference replays it interval by interval
(`polish._verify`, the checks of `tfcontact.ocp.contact.verify_plan`) and TF-9's holes
are measured at its nodes.

    PYTHONPATH=benchmarks/monoped_polish python benchmarks/monoped_polish/verify.py \
        benchmarks/monoped_exact_plan.npz
"""

import dataclasses
import sys

import numpy as np
from polish import PolishOptions, _Dynamics, _verify

from tfcontact.scenes.monoped import FULL_TASK, monoped_problem


def verify_saved(path):
    """(Verification, smallest ellipse value) of a plan.npz written by full.py: the replay,
    local defects, amplification and gaps (the friction cone of the solve's stick forces
    and impulses was checked when it was solved, and is not repeated here)."""
    plan = np.load(path)
    task = dataclasses.replace(FULL_TASK, hole_half_width=0.25, hole_form="ellipse")
    mp = monoped_problem(task)
    cls = mp.system.cls
    dyn = _Dynamics(cls)
    n = task.n_intervals
    clocks = np.array([k * task.horizon / n for k in range(n + 1)])
    verification = _verify(cls, mp.problem, clocks, plan["boundary"], plan["u"], plan["x"],
                           dyn, np.zeros((0, 2)), np.zeros((0, 2)), PolishOptions())
    return verification, float(np.min(mp.hole_values(plan["x"][:, :4])))


if __name__ == "__main__":
    verification, holes = verify_saved(sys.argv[1])
    print(verification.summary())
    print(f"smallest ellipse value {holes:.3g} (>= 0 outside TF-9's holes)")
