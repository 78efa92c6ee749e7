"""PROTOTYPE driver (see polish.py): the reduced TF-9 monoped's relaxed plan, then the
exact re-solve along stick -> slip- -> flight -> stick, warm started step by step.

    PYTHONPATH=benchmarks/monoped_polish python benchmarks/monoped_polish/run.py 16:0 16:0:2

Each argument `substeps:painleve_margin[:steps_per_node]` is one more re-solve from the
previous one.
"""

import dataclasses
import sys
import time

import numpy as np
from polish import Phase, PolishOptions, contact_phases, polish_contact

from tfcontact.ocp.contact import solve_contact
from tfcontact.scenes.monoped import monoped_options, monoped_problem


def first_hop():
    """The reduced task's relaxed plan (homotopy from the start-everywhere guess: 778
    iterations, 9 s; stick, flight, stick) and its exact re-solve with a slip before the
    lift-off, its start guessed at 0.55 s (8 RK4 steps per interval)."""
    mp = monoped_problem("reduced")
    options = monoped_options("reduced")
    options = dataclasses.replace(
        options, homotopy=dataclasses.replace(options.homotopy, max_refinements=3),
        nlp=dataclasses.replace(options.nlp, options={"mu_strategy": "adaptive"},
                                element_derivatives=True, threads=1, intermediate_tol=0.1))
    relaxed = solve_contact(mp.problem, options, verbose=False)
    found = contact_phases(relaxed)
    lift_off = found[1].start
    phases = (Phase("stick", 0.0, 0.55), Phase("slip-", 0.55, lift_off),
              Phase("flight", lift_off, found[1].end), Phase("stick", found[2].start, 1.0))
    return relaxed, polish_contact(relaxed, phases,
                                   PolishOptions(substeps=8, painleve_margin=0.0))


def main() -> None:
    relaxed, plan = first_hop()
    for argument in sys.argv[1:]:
        fields = argument.split(":")
        substeps, margin = int(fields[0]), float(fields[1])
        per_node = int(fields[2]) if len(fields) > 2 else 1
        start = time.perf_counter()
        plan = polish_contact(relaxed, plan.phases,
                              PolishOptions(substeps=substeps, steps_per_node=per_node,
                                            painleve_margin=margin),
                              guess=(plan.t, plan.x, plan.u))
        print(f"substeps {substeps} x {per_node} RK4 steps, Painleve margin {margin}: "
              f"{time.perf_counter() - start:.1f} s")
        print("local defects", np.array2string(np.asarray(plan.verification.local_defects),
                                               precision=3), flush=True)


if __name__ == "__main__":
    main()
