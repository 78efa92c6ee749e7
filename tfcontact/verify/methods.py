"""How a time-freezing plan's controls are re-simulated for its end-state check.

Each method is a strategy object of `VerifyOptions.replay`:

* `ExactReplay()`: the event-detecting reference of the original system with exact
  impacts (`replay_controls`): one contact, or several frictionless elastic ones. It
  also gives the plan's local defects and, for an open-loop unstable plan, its
  amplification (`end_state_check`). Where it does not apply, verification raises.
* `FesdReplay(refinement, scheme, relaxation)`: the FESD simulator of the time-freezing
  system on a grid `refinement` times finer with (by default) a higher-order scheme: any
  system, but the same reformulation the plan was computed with.
* `AutoReplay(fallback=FesdReplay())`: the exact replay where it applies, else the fallback.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from tfcontact.errors import InvalidInput, TfcontactError, positive_int
from tfcontact.fesd import RadauIIA, Scheme, simulate
from tfcontact.mpcc import Relaxation, Scholtes
from tfcontact.verify.replay import reference_deviation

if TYPE_CHECKING:
    from tfcontact.verify.plan import TimeFreezingPlan


@dataclass(frozen=True)
class ReplayOutcome:
    """What a replay measured.

    Attributes:
        deviation: ||x_plan(T) - x_replay(T)|| (inf norm) [state units]; inf: the replay
            failed.
        method: how the plan was replayed, for `Verification.method`.
        reference_end: the exact replay's state at T (None: no exact replay).
        local_defects: per control interval (`local_defects`); empty: not computed.
    """

    deviation: float
    method: str
    reference_end: np.ndarray | None = None
    local_defects: tuple[float, ...] = ()


class Replay(ABC):
    """A way of re-simulating a plan's controls (a strategy of `VerifyOptions.replay`)."""

    @abstractmethod
    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        """Replay `plan`; what could not be checked is appended to `notes`.

        Args:
            plan: the `TimeFreezingPlan`.
            gap_tolerance: a restart may lie this far inside an obstacle [m].
            notes: the verification's notes.
        """


@dataclass(frozen=True)
class ExactReplay(Replay):
    """The event-detecting reference of the original system with exact impacts: the
    open-loop replay from the plan's start, and the local defects (the reference restarted
    from the plan's state at each control-interval boundary that holds a physical state).

    Raises (from `run`): `TfcontactError` where the reference does not apply (several
    contacts with friction, a jam, a budget stop: `simulate_impacts`).
    """

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        deviation, method, reference_end = reference_deviation(plan.replayed(),
                                                               plan.end_state)
        return ReplayOutcome(deviation, method, reference_end,
                             plan.local_defects(gap_tolerance))


@dataclass(frozen=True)
class FesdReplay(Replay):
    """The FESD simulator of the time-freezing system (`tfcontact.fesd.simulate`) with the
    plan's controls, its MPCC settings and N_FE, compared on (q, v, clock) at the end.

    Args:
        refinement: integration steps per control interval.
        scheme: the IRK scheme (a higher order than the plan's shows its
            discretisation error).
        relaxation: the simulator's relaxation (`L1Penalty()` needs one or two NLPs per
            step where `Scholtes()` needs one per decade of sigma).
    """

    refinement: int = 4
    scheme: Scheme = field(default_factory=lambda: RadauIIA(3))
    relaxation: Relaxation = field(default_factory=Scholtes)

    def __post_init__(self) -> None:
        positive_int(self.refinement, "refinement")
        if not isinstance(self.scheme, Scheme):
            raise InvalidInput(f"`scheme` must be a Scheme (RadauIIA(s), GaussLegendre(s)), "
                               f"got {self.scheme!r}")
        if not isinstance(self.relaxation, Relaxation):
            raise InvalidInput(f"`relaxation` must be a Relaxation (Scholtes(), L1Penalty(), "
                               f"LinfPenalty()), got {self.relaxation!r}")

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        n_int = len(plan.u)
        system = plan.system
        sim = simulate(
            system.pss, plan.x[0], horizon=plan.tau_horizon, n_steps=n_int * self.refinement,
            u=np.repeat(plan.u, self.refinement, axis=0), scheme=self.scheme,
            n_finite_elements=plan.n_finite_elements, homotopy=plan.homotopy,
            relaxation=self.relaxation, nlp=plan.nlp, throw=False,
        )
        idx = plan.state_indices + [system.clock_index]
        method = (f"FESD re-simulation, {n_int * self.refinement} steps x "
                  f"{plan.n_finite_elements} elements, {self.scheme!r}")
        if not sim.success:
            notes.append(f"re-simulation did not converge: {sim.message}")
            return ReplayOutcome(float("inf"), method)
        return ReplayOutcome(float(np.max(np.abs(sim.x[-1, idx] - plan.x[-1, idx]))), method)


@dataclass(frozen=True)
class AutoReplay(Replay):
    """`ExactReplay()` where the reference applies, else `fallback`; the local defects are
    computed either way (where the exact replay stopped, the intervals before still tell).

    Args:
        fallback: the `FesdReplay` used where the exact reference does not apply.
    """

    fallback: FesdReplay = field(default_factory=FesdReplay)

    def __post_init__(self) -> None:
        if not isinstance(self.fallback, FesdReplay):
            raise InvalidInput(f"`fallback` must be a FesdReplay, got {self.fallback!r}")

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        try:
            return ExactReplay().run(plan, gap_tolerance, notes)
        except TfcontactError as error:
            notes.append(f"event-detecting reference not applicable ({error}); FESD used")
        defects = plan.local_defects(gap_tolerance)
        return replace(self.fallback.run(plan, gap_tolerance, notes), local_defects=defects)
