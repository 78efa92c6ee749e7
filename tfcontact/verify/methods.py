"""How a time-freezing plan's controls are re-simulated for its end-state check.

Each method is a strategy object of `VerifyOptions.replay`:

* `ExactReplay()`: the event-detecting reference of the original system with exact
  impacts (`replay_controls`): one contact, or several frictionless elastic ones. It
  also gives the plan's local defects and, for an open-loop unstable plan, its
  amplification (`end_state_check`). Where it does not apply, verification raises.
* `MultiContactReplay(simulation=MultiContactOptions())`: the
  event-driven simulator of the original system with several frictional inelastic
  contacts (`replay_multicontact`), and the local defects and the amplification with it.
  Where it does not apply, verification raises.
* `FesdReplay(refinement, scheme, relaxation)`: the FESD simulator of the time-freezing
  system on a grid `refinement` times finer with (by default) a higher-order scheme: any
  system, but the same reformulation the plan was computed with.
* `AutoReplay(fallback=FesdReplay(), multicontact=MultiContactReplay())`: the exact replay
  where it applies, else the multi-contact replay where that applies and succeeds, else
  the fallback.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from tfcontact.errors import (
    IncompatibleOptions,
    InvalidInput,
    SolveFailed,
    TfcontactError,
    positive_int,
)
from tfcontact.fesd import RadauIIA, Scheme, simulate
from tfcontact.mpcc import Relaxation, Scholtes
from tfcontact.timefreezing import ComplementarityLagrangianSystem
from tfcontact.verify.multicontact import (
    EvaluationBudget,
    MultiContactOptions,
    MultiContactSimulation,
    multicontact_local_defects,
    replay_multicontact,
    stopped_replay,
)
from tfcontact.verify.replay import (
    ReplayEnd,
    ReplayTo,
    StoppedReplay,
    defect_segments,
    reference_deviation,
)

if TYPE_CHECKING:
    from tfcontact.verify.plan import TimeFreezingPlan


@dataclass(frozen=True)
class ReplayOutcome:
    """What a replay measured.

    Attributes:
        deviation: ||x_plan(T) - x_replay(T)|| (inf norm) [state units]; inf: the replay
            failed.
        method: how the plan was replayed, for `Verification.method`.
        reference_end: the independent replay's state at T (None: no independent
            replay).
        local_defects: per control interval (`local_defects`); empty: not computed.
        replay_end: that replay from another start, for the open-loop amplification
            (`end_state_check`); None: the exact-impact reference's.
        stopped: the independent replay as far as it got, where it stopped before T
            (`end_state_check` judges it where it left the plan).
        parted: a replay that ran to T at the boundaries before T, where
            `end_state_check` judges it should its kicked replays to T stop (None: such a
            replay fails).
    """

    deviation: float
    method: str
    reference_end: np.ndarray | None = None
    local_defects: tuple[float, ...] = ()
    replay_end: ReplayEnd | None = None
    stopped: StoppedReplay | None = None
    parted: StoppedReplay | None = None


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

    @staticmethod
    def applies_to(cls: ComplementarityLagrangianSystem) -> bool:
        """Whether `simulate_impacts` takes this system: one contact, or several that are
        all frictionless and elastic (the limits it raises IncompatibleOptions for)."""
        return cls.n_contacts == 1 or all(
            not c.has_friction and c.restitution > 0 for c in cls.contacts)

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        deviation, method, reference_end = reference_deviation(plan.replayed(),
                                                               plan.end_state)
        return ReplayOutcome(deviation, method, reference_end,
                             plan.local_defects(gap_tolerance))


@dataclass(frozen=True)
class MultiContactReplay(Replay):
    """The event-driven simulator of the original system with several frictional
    inelastic contacts (`simulate_multicontact`: contact modes and simultaneous impacts
    from contact LCPs): the open-loop replay of the plan's physical controls from its
    start, compared on (q, v) at T, and the local defects (restarts from the plan's state
    at each control-interval boundary that holds a physical state,
    `multicontact_local_defects`).

    An open-loop unstable plan (a biped balancing on its feet) may pass on its local
    defects as with the exact reference (`end_state_check`): this simulator is the replay
    kicked for the amplification. A kicked replay to T that stops (Painleve, event cap,
    budget) measures nothing: the plan is then judged where the open-loop replay left it
    (`departure_check`, kicks up to that boundary), as is an open-loop replay that stops
    before T; where those kicks stop too, the check fails.

    Args:
        simulation: the simulator's `MultiContactOptions` (default: its defaults); its
            `start_gap_tolerance` is raised to the verification's gap tolerance (a plan's
            state may lie that far inside an obstacle).
        budget: model evaluations of the whole check, the open-loop replay and every
            local-defect restart together (`EvaluationBudget`): restarts after it is used
            up are not run, their defects inf, and the notes say how many. A genuine plan
            needs far fewer (the pushed two-contact box: about 100 per interval); a plan
            that chatters would spend the simulator's cap in every restart (a failed
            solo12 jump: 1e6 evaluations, 83 s, per restart). About 40 s of solo12.

    A simulation that stops with a status (Painleve, event cap, budget) is a failed
    replay, not an error: the deviation is inf, the notes give the status and where it
    stopped, and the end-state check is made where it left the plan, if it did (a failed
    NLP's plan may chatter at its start; `solve_contact` reports such a plan as
    unverified instead of raising).

    Raises (from `run`): `IncompatibleOptions` for a contact with restitution > 0;
    `InvalidInput` for a start inside an obstacle.
    """

    # The simulator's defaults: a restart of a pushed box's plan 2e-8 m inside the ground
    # with v_n = 3e-7 m/s (the plan's own error) now flies and lands back at its depth
    # (`simulate_multicontact`); it used to chatter at t = 0 and needed 1e-6 m/s here.
    simulation: MultiContactOptions = field(default_factory=MultiContactOptions)
    budget: int = 500_000

    def __post_init__(self) -> None:
        if not isinstance(self.simulation, MultiContactOptions):
            raise InvalidInput(f"`simulation` must be a MultiContactOptions, got "
                               f"{self.simulation!r}")
        positive_int(self.budget, "budget")

    @staticmethod
    def applies_to(cls: ComplementarityLagrangianSystem) -> bool:
        """Whether `simulate_multicontact` takes this system: every contact inelastic."""
        return all(c.restitution == 0 for c in cls.contacts)

    def options(self, gap_tolerance: float) -> MultiContactOptions:
        """The simulator's options with a start allowed `gap_tolerance` [m] inside."""
        return replace(self.simulation, start_gap_tolerance=max(
            self.simulation.start_gap_tolerance, gap_tolerance))

    def local_defects(self, plan: TimeFreezingPlan, gap_tolerance: float,
                      budget: EvaluationBudget | None = None) -> tuple[float, ...]:
        """The plan's local defects with this simulator (`multicontact_local_defects`,
        cut like `TimeFreezingPlan.local_defects`), within `budget` if given."""
        replayed = plan.replayed()
        return multicontact_local_defects(
            replayed, defect_segments(replayed.clocks, ~plan.running), gap_tolerance,
            self.options(gap_tolerance), budget)

    def simulate(self, plan: TimeFreezingPlan, gap_tolerance: float,
                 budget: EvaluationBudget | None = None,
                 x0: np.ndarray | None = None,
                 until: int | None = None) -> MultiContactSimulation:
        """The open-loop replay of the plan's physical controls from its start (or `x0`)
        to T (or control-interval boundary `until`), within `budget` if given; a failure
        is the result's status.

        Raises:
            IncompatibleOptions: a contact with restitution > 0.
        """
        cls = plan.system.cls
        if not self.applies_to(cls):
            elastic = [c.name for c in cls.contacts if c.restitution > 0]
            raise IncompatibleOptions(f"the multi-contact replay models inelastic contacts "
                                      f"only; {elastic} have restitution > 0")
        replayed = plan.replayed()
        options = self.options(gap_tolerance)
        last = len(replayed.controls) if until is None else until
        sim = replay_multicontact(cls, replayed.x0 if x0 is None else x0,
                                  replayed.clocks[:last + 1], replayed.controls[:last],
                                  replayed.horizon if until is None
                                  else float(replayed.clocks[until]),
                                  options=options if budget is None
                                  else budget.options(options))
        if budget is not None:
            budget.spend(sim.n_rhs)
        return sim

    def replay_end(self, plan: TimeFreezingPlan, gap_tolerance: float) -> ReplayEnd:
        """The open-loop replay from another start to T (`replay_to` to no boundary)."""
        to = self.replay_to(plan, gap_tolerance)
        return lambda x0: to(x0, None)

    def replay_to(self, plan: TimeFreezingPlan, gap_tolerance: float) -> ReplayTo:
        """The open-loop replay from another start up to a control-interval boundary
        (None: to T), each within its own `budget`; one that stops raises `SolveFailed`
        (its sensitivity is not measured)."""
        def to(x0: np.ndarray, boundary: int | None) -> np.ndarray:
            sim = self.simulate(plan, gap_tolerance, EvaluationBudget(self.budget), x0,
                                until=boundary)
            if not sim.success:
                raise SolveFailed(f"kicked multi-contact replay stopped: {sim.message}", sim)
            return sim.final_state()
        return to

    def stopped(self, plan: TimeFreezingPlan, sim: MultiContactSimulation,
                gap_tolerance: float) -> StoppedReplay:
        """`sim`, an open-loop replay that stopped (or ran to T: its boundaries before T),
        as `end_state_check` reads it."""
        return stopped_replay(sim, plan.replayed(), self.replay_to(plan, gap_tolerance))

    def outcome(self, plan: TimeFreezingPlan, sim: MultiContactSimulation,
                defects: tuple[float, ...], gap_tolerance: float) -> ReplayOutcome:
        """The end-state deviation of a successful simulation, named for the report."""
        times = np.round([imp.time for imp in sim.impacts], 4).tolist()
        method = (f"event-driven multi-contact reference (DOP853, contact LCPs, inelastic "
                  f"frictional impacts), {len(times)} impacts at t = {times} s, "
                  f"{len(sim.events)} contact-mode changes")
        return ReplayOutcome(sim.deviation_at(plan.horizon, plan.end_state), method,
                             reference_end=sim.final_state(), local_defects=defects,
                             replay_end=self.replay_end(plan, gap_tolerance),
                             parted=self.stopped(plan, sim, gap_tolerance))

    @staticmethod
    def stop_note(sim: MultiContactSimulation) -> str:
        """The verification's note on a simulation that stopped with a status."""
        stop = sim.t[-1] if sim.t.size else 0.0
        return (f"multi-contact reference stopped at t = {stop:.6g} s with status "
                f"{sim.status.value}: {sim.message}")

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        budget = EvaluationBudget(self.budget)
        sim = self.simulate(plan, gap_tolerance, budget)
        defects = self.local_defects(plan, gap_tolerance, budget)
        if not sim.success:
            notes.append(self.stop_note(sim))
        if budget.skipped:
            notes.append(f"the multi-contact reference used up its budget of {self.budget} "
                         f"model evaluations: {budget.skipped} local-defect restarts not run "
                         "(their defects inf); raise MultiContactReplay(budget=...) if the "
                         "plan's motion needs more")
        if not sim.success:
            return ReplayOutcome(math.inf, "event-driven multi-contact reference (stopped)",
                                 local_defects=defects,
                                 stopped=self.stopped(plan, sim, gap_tolerance))
        return self.outcome(plan, sim, defects, gap_tolerance)


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
    """An independent replay of the original system where one applies, else `fallback`:

    * `ExactReplay()` where the exact-impact reference takes the system (one contact, or
      several frictionless elastic ones); if it raises (a jam, a budget stop), `fallback`.
    * else `multicontact` where every contact is inelastic (several frictional contacts);
      if its simulation stops with a status (Painleve, event cap, budget) or rejects the
      start, `fallback`, and the notes say which status and why.
    * else (several contacts, some elastic and some with friction or inelastic) `fallback`.

    The local defects of the independent replay are computed either way (where its
    open-loop replay stopped, the intervals before still tell).

    Args:
        fallback: the `FesdReplay` used where no independent replay applies.
        multicontact: the `MultiContactReplay` of several frictional inelastic contacts.
    """

    fallback: FesdReplay = field(default_factory=FesdReplay)
    multicontact: MultiContactReplay = field(default_factory=MultiContactReplay)

    def __post_init__(self) -> None:
        if not isinstance(self.fallback, FesdReplay):
            raise InvalidInput(f"`fallback` must be a FesdReplay, got {self.fallback!r}")
        if not isinstance(self.multicontact, MultiContactReplay):
            raise InvalidInput(f"`multicontact` must be a MultiContactReplay, got "
                               f"{self.multicontact!r}")

    def run(self, plan: TimeFreezingPlan, gap_tolerance: float,
            notes: list[str]) -> ReplayOutcome:
        cls = plan.system.cls
        if not ExactReplay.applies_to(cls) and self.multicontact.applies_to(cls):
            return self.run_multicontact(plan, gap_tolerance, notes)
        try:
            return ExactReplay().run(plan, gap_tolerance, notes)
        except TfcontactError as error:
            notes.append(f"event-detecting reference not applicable ({error}); FESD used")
        defects = plan.local_defects(gap_tolerance)
        return replace(self.fallback.run(plan, gap_tolerance, notes), local_defects=defects)

    def run_multicontact(self, plan: TimeFreezingPlan, gap_tolerance: float,
                         notes: list[str]) -> ReplayOutcome:
        """The multi-contact replay, else (it stopped or rejected the start) `fallback`
        with the multi-contact local defects."""
        defects = self.multicontact.local_defects(plan, gap_tolerance)
        try:
            sim = self.multicontact.simulate(plan, gap_tolerance)
        except TfcontactError as error:
            notes.append(f"multi-contact reference rejected the plan ({error}); FESD used")
        else:
            if sim.success:
                return self.multicontact.outcome(plan, sim, defects, gap_tolerance)
            notes.append(MultiContactReplay.stop_note(sim) + "; FESD used")
            return replace(self.fallback.run(plan, gap_tolerance, notes), local_defects=defects,
                           stopped=self.multicontact.stopped(plan, sim, gap_tolerance))
        return replace(self.fallback.run(plan, gap_tolerance, notes), local_defects=defects)
