"""Solver presets a task names (`Task.solver`): tested settings, not per-task tuning."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


def default_preset() -> Any:
    """Discovery from the start-everywhere guess, as the hopper plan measured it
    (benchmarks/hopper_bench.md): FESD on Radau IIA 2 with 3 elements per interval and
    gamma_h = 0.9, Scholtes from sigma_0 = 1 down to 1e-4 (kappa 0.1, failed steps cut
    up to 3 times), each NLP to 1e-8 with IPOPT's monotone barrier, the element derivatives
    on 2 threads, up to 3 attempts (a failed plan solved again from a perturbed guess)."""
    from tfcontact.fesd import Fesd, RadauIIA
    from tfcontact.mpcc import Homotopy, Ipopt, Scholtes
    from tfcontact.ocp.contact import ContactSolverOptions

    return ContactSolverOptions(
        scheme=RadauIIA(2), n_finite_elements=3, method=Fesd(gamma_h=0.9),
        relaxation=Scholtes(),
        homotopy=Homotopy(sigma_0=1.0, kappa=0.1, tolerance=1e-4, max_nlps=6,
                          max_refinements=3),
        nlp=Ipopt(tol=1e-8, max_iter=1000, options={"mu_strategy": "monotone"},
                  element_derivatives=True, threads=2),
        attempts=3)


def fast_preset() -> Any:
    """Fewer, looser NLPs, as the hopper's bench task measured them: Scholtes from
    sigma_0 = 0.1 to 1e-3, the stepping-stone NLPs to IPOPT tolerance 0.1 and the last to
    1e-8 with the adaptive barrier; one attempt."""
    from tfcontact.fesd import Fesd, RadauIIA
    from tfcontact.mpcc import Homotopy, Ipopt, Scholtes
    from tfcontact.ocp.contact import ContactSolverOptions

    return ContactSolverOptions(
        scheme=RadauIIA(2), n_finite_elements=3, method=Fesd(gamma_h=0.9),
        relaxation=Scholtes(),
        homotopy=Homotopy(sigma_0=0.1, kappa=0.1, tolerance=1e-3, max_nlps=6,
                          max_refinements=0),
        nlp=Ipopt(tol=1e-8, max_iter=1000, intermediate_tol=1e-1,
                  element_derivatives=True, threads=2),
        attempts=1)


SOLVER_PRESETS: dict[str, Callable[[], Any]] = {"default": default_preset,
                                                "fast": fast_preset}
"""Preset name -> a function returning its `tfcontact.ocp.ContactSolverOptions`."""
