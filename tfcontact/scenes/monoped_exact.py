"""TF-9's monoped planned in stages (`STAGES`, run by `tfcontact plan monoped`): the
time-freezing homotopy finds a hop, exact re-solves (`tfcontact.ocp.chain`) turn it into
a verified plan, and that hop tiled over the holes starts the full task's re-solves.

The time-freezing homotopy of the full task from the start-everywhere guess ends
nlp_failed (benchmarks/monoped_settings.md); the reduced task's (one hole, T = 1 s)
converges and finds one hop: stick, flight, stick. The stages:

1. `Discover(reduced_discovery)`: the reduced task's relaxed plan from the
   start-everywhere guess.
2. `ExactResolve(levels=reduced_levels, start=OneHopWithSlip())`: the exact re-solve
   along its sequence with a slip before the lift-off (its start guessed at 0.55 s): 8 RK4
   nodes per interval, then 16, then 16 nodes x 2 RK4 steps, each warm started from the
   last. A verified plan of the reduced task (`--task reduced` ends here).
3. `ExactResolve(levels=full_levels, start=TiledHops(...), setup=full_setup)`:
   `tiled_guess` puts that hop three times on a `Schedule`, lift-offs straight from stick
   at control jumps, one metre further per hop. The full task searches the schedule:
   `uniform_schedules` lists one hop per hole with the hop's flight time and lift-offs at
   evenly spaced control jumps, each candidate gets the chain's first level, and the
   solved candidate with the lowest objective continues (measured: lift-offs 0.5, 1.125,
   1.75 s). The number of hops and the even spacing are a rule; the lift-off times are
   not set by hand. `--task hand-set` follows `HAND_SET_SCHEDULE`, the schedule of the
   earlier plans, set by hand from the reduced hop time scaled by 5/6: lift-offs 0.5,
   1.25 and 2.0 s, flights of 0.26 s. The levels re-solve `EXACT_TASK` (T = 2.5 s, N =
   20, three holes of half width 0.25 as in the authors' robot_ocp.m) with free
   touchdowns: with bump holes (8 nodes x 2 RK4 steps, then 16 x 2), then with TF-9's
   ellipses (16 x 2), then `radau_levels`: TF-9's scheme, Radau IIA order 5 collocation
   (FESD with the active set fixed), on `RADAU_ELEMENTS` elements per interval, then on
   that mesh refined where the plan's local defects exceed their share of the tolerance
   (not solved again when none does: measured on the full task, whose 12-element plan
   passes).
   TF-9's own 3 elements per interval are too coarse for this motion (`RADAU_ELEMENTS`).
4. `--task terrain` runs stage 3's search and levels, then `radau_levels` once more on
   `TERRAIN_TASK`, whose holes are the terrain's: the bump and ellipse levels lead the
   re-solves over the holes (the terrain's holes alone remove support but point nowhere:
   the discovery over them finds no hop, benchmarks/monoped_settings.md), the last
   levels let the foot pass inside the ellipses.

How a chain goes on past a level stopped at IPOPT's iteration cap, and what decides at its
end, is `tfcontact.ocp.chain`'s (the same for every robot).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.native import peak_memory, reset_peak_memory, return_memory
from tfcontact.ocp.chain import PATH_TOLERANCE, ChainStep, ResolveLevel, refine_by_defects
from tfcontact.ocp.contact import ContactProblem
from tfcontact.ocp.polish import (
    FLIGHT,
    STICK,
    Phase,
    PolishedPlan,
    PolishOptions,
    contact_phases,
    polish_contact,
    verify_polished,
)
from tfcontact.plan_format.resolved import load_resolved_plan
from tfcontact.scenes.monoped import (
    FULL_TASK,
    MonopedTask,
    monoped_options,
    monoped_problem,
)
from tfcontact.scenes.pipeline import (
    Discover,
    ExactResolve,
    NoStart,
    PlanSetup,
    ResolveStart,
    StageInput,
    Start,
    discovered,
    discovery_step,
)
from tfcontact.verify import Verification

EXACT_TASK = dataclasses.replace(FULL_TASK, hole_half_width=0.25, hole_form="ellipse")
"""The task of the full plan's re-solves: TF-9 (T = 2.5 s, N = 20, |u| <= 60, q(T) =
(3, 0.4, 0, 0)) with TF-9's ellipses of half width 0.25 (the authors' robot_ocp.m;
PROBLEMS.md lists 0.5, under which the holes at 0.5, 1.5 and 2.5 leave 0.5 m of ground
between them)."""


@dataclass(frozen=True)
class Schedule:
    """When the full task's guess hops: lift-offs [s] at control jumps, each flight
    `flight_time` [s] long. The re-solve keeps each touchdown in the control interval its
    guess lies in, so the schedule fixes the interval of every lift-off and touchdown."""

    lift_offs: tuple[float, ...]
    flight_time: float

    def __post_init__(self) -> None:
        if not self.lift_offs or not self.flight_time > 0:
            raise InvalidInput(f"a schedule needs lift-offs and a positive flight time, got "
                               f"{self.lift_offs!r}, {self.flight_time!r}")
        landed = [t + self.flight_time for t in self.lift_offs[:-1]]
        if self.lift_offs[0] <= 0 or any(
                b <= a for a, b in zip(landed, self.lift_offs[1:], strict=True)):
            raise InvalidInput(f"lift-offs {self.lift_offs} with flights of "
                               f"{self.flight_time} s: each hop must start after the last "
                               "one landed, the first after t = 0")

    def __str__(self) -> str:
        return f"lift-offs {', '.join(f'{t:g}' for t in self.lift_offs)} s"


TERRAIN_TASK = dataclasses.replace(EXACT_TASK, hole_form="terrain")
"""`EXACT_TASK` with its holes as the terrain's (`tfcontact.robot.Hole`, bottomless, rims
rounded 1 cm): no support over them, no constraint on the foot's path (it may dip into a
hole), the replay and the sidecar draw them (`tfcontact plan monoped --task terrain`)."""
TERRAIN_TOUCHDOWN_RATE = 0.025
"""`PolishOptions.touchdown_rate` of the terrain task's Radau levels (r_n >= 0.025 W_nn,
about 0.047 1/kg here): without it the re-solve landed grazing (v_n = -0.012 m/s at
v_t = 4.4 m/s, r_n at 1e-3) and the exact replay missed the ground; TF-9's plan lands
with r_n / W_nn = 0.04-0.05."""


HAND_SET_SCHEDULE = Schedule(lift_offs=(0.5, 1.25, 2.0), flight_time=0.26)
"""The schedule of the earlier verified plan (benchmarks/monoped_exact_plan.npz,
`tfcontact plan monoped --task hand-set`): set by hand from the reduced hop (time scaled
by 5/6), lift-offs at control jumps (T / N = 0.125 s)."""
SLIP_START = 0.55
"""Guessed start [s] of the reduced hop's slip before its lift-off."""
RADAU_ELEMENTS = 12
"""Radau IIA elements per control interval of the last re-solves. TF-9's own N_FE = 3
re-solves the RK4 plan (32 iterations) into a plan whose exact replay parts from it by 14
in one interval: the leg swings at up to 100 rad/s before each touchdown."""
RADAU_CONE_MARGIN = 0.98
"""The Radau re-solves keep the stick forces within 0.98 mu lambda_n: with the full cone
(1.0) the 12-element plan stuck on the cone's edge in one interval, where the exact replay
slipped and parted from it by 3.2."""

RESOLVE_DERIVATIVES: dict[str, object] = {"element_derivatives": True, "threads": 2}
"""How the chain's re-solves are differentiated (`PolishOptions.element_derivatives`
and `threads`): each shooting step or collocation element, contact and path row once,
evaluated on two threads. {}: CasADi differentiates each whole NLP, the route before
2026-11-28 (`scripts/bench_monoped.py` runs both; benchmarks/monoped_bench.md)."""


def resolve_options(**settings) -> PolishOptions:
    """The chain's `PolishOptions`: `settings` with `RESOLVE_DERIVATIVES`."""
    return PolishOptions(**{**RESOLVE_DERIVATIVES, **settings})


def tiled_guess(hop: PolishedPlan, task: MonopedTask = EXACT_TASK,
                schedule: Schedule = HAND_SET_SCHEDULE
                ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], tuple[Phase, ...]]:
    """The reduced hop once per lift-off of `schedule`: ((t, x, u), phases) as a guess of
    the full task. Each segment of the hop (stance before the lift-off, flight, last
    stance: the hop's own phases) is time scaled onto its slot, velocities divided and
    torques by the square of the scale, q_x moved one metre per hop."""
    if schedule.lift_offs[-1] + schedule.flight_time >= task.horizon:
        raise InvalidInput(f"the schedule's last hop lands after the horizon {task.horizon} s")
    lift_offs, flight_time = schedule.lift_offs, schedule.flight_time
    flight = next(p for p in hop.phases if p.mode == FLIGHT)
    lift_off, touchdown = flight.start, flight.end
    hop_end = hop.phases[-1].end
    segments = []  # (start, end, start in the hop, end in the hop, hop index)
    previous = 0.0
    for j, jump in enumerate(lift_offs):
        segments.append((previous, jump, 0.0, lift_off, j))
        segments.append((jump, jump + flight_time, lift_off, touchdown, j))
        previous = jump + flight_time
    segments.append((previous, task.horizon, touchdown, hop_end, len(lift_offs) - 1))
    t_guess, x_guess = [], []
    for a, b, ra, rb, j in segments:
        scale = (b - a) / (rb - ra)
        for s in np.linspace(0.0, 1.0, 25):
            x = np.array([np.interp(ra + s * (rb - ra), hop.t, hop.x[:, i])
                          for i in range(hop.x.shape[1])])
            x[0] += j
            x[x.size // 2:] /= scale
            t_guess.append(a + s * (b - a))
            x_guess.append(x)
    dt = task.horizon / task.n_intervals
    u_guess = []
    for k in range(task.n_intervals):
        middle = (k + 0.5) * dt
        a, b, ra, rb, _ = next(s for s in segments if s[0] <= middle <= s[1])
        scale = (b - a) / (rb - ra)
        hop_time = ra + (middle - a) / scale
        index = min(int(hop_time / hop_end * len(hop.u)), len(hop.u) - 1)
        u_guess.append(hop.u[index] / scale**2)
    phases = [Phase(STICK, 0.0, lift_offs[0])]
    for jump in lift_offs:
        phases += [Phase(FLIGHT, jump, jump + flight_time),
                   Phase(STICK, jump + flight_time, task.horizon)]
    u_guess = np.clip(np.array(u_guess), -task.control_bound, task.control_bound)
    return (np.array(t_guess), np.array(x_guess), u_guess), tuple(phases)


def uniform_schedules(hop: PolishedPlan, task: MonopedTask = EXACT_TASK,
                      first: tuple[int, ...] = (3, 4, 5), spacing: tuple[int, ...] = (5, 6)
                      ) -> tuple[Schedule, ...]:
    """One hop per hole, each as long in flight as the reduced hop's, the lift-offs at the
    control jumps k_1 T / N, (k_1 + s) T / N, ... for each first jump k_1 in `first` and
    spacing s in `spacing` whose last touchdown leaves at least one control interval of
    stance before the horizon (the hops' count is the scene's: the foot has no ground
    inside a hole)."""
    dt = task.horizon / task.n_intervals
    flight = next(p for p in hop.phases if p.mode == FLIGHT)
    flight_time = flight.end - flight.start
    schedules = []
    for k_1 in first:
        for s in spacing:
            lift_offs = tuple((k_1 + j * s) * dt for j in range(len(task.holes)))
            if lift_offs[-1] + flight_time <= task.horizon - dt:
                schedules.append(Schedule(lift_offs, flight_time))
    return tuple(schedules)


@dataclass(frozen=True)
class ScheduleTrial:
    """A candidate schedule and its first re-solve (bump holes, 8 nodes x 2 RK4 steps)."""

    schedule: Schedule
    plan: PolishedPlan
    seconds: float
    peak_memory: float | None = None


def search_schedule(hop: PolishedPlan, schedules: tuple[Schedule, ...], problem: ContactProblem,
                    options: PolishOptions, task: MonopedTask = EXACT_TASK,
                    verbose: bool = True
                    ) -> tuple[ScheduleTrial | None, tuple[ScheduleTrial, ...]]:
    """Re-solve `problem` (a form of `task`) from the hop tiled on each schedule; (the trial
    IPOPT solved with the lowest objective or None, every trial). A schedule the re-solve
    cannot follow ends infeasible (benchmarks/monoped_settings.md, sixth session: 4 of 8
    did)."""
    trials = []
    for i, schedule in enumerate(schedules):
        if verbose:  # a candidate takes 15-45 s
            print(f"monoped: schedule {i + 1} of {len(schedules)}, {schedule}", flush=True)
        guess, phases = tiled_guess(hop, task, schedule)
        begin = time.perf_counter()
        reset_peak_memory()
        plan = polish_contact(problem, phases, options, guess=guess, verbose=False)
        trials.append(ScheduleTrial(schedule, plan, time.perf_counter() - begin, peak_memory()))
        return_memory()
        if verbose:
            print(f"  IPOPT {plan.ipopt_status}, {plan.iterations} iterations, "
                  f"{trials[-1].seconds:.0f} s, objective {plan.cost:.6g}", flush=True)
    solved = [t for t in trials if t.plan.solved]
    best = min(solved, key=lambda t: t.plan.cost) if solved else None
    return best, tuple(trials)


def radau_options(substeps: int | tuple[int, ...] = RADAU_ELEMENTS,
                  **settings) -> PolishOptions:
    """TF-9's scheme (Radau IIA, order 5) on `substeps` elements per control interval,
    the stick forces kept 2 % inside the friction cone (`RADAU_CONE_MARGIN`); `settings`:
    other `PolishOptions` fields."""
    # element derivatives as in the RK4 levels (until the warm starts at impacts and the
    # terminal rows were mended, the refined level from the saved RK4 plan ended
    # nlp_failed with them: monoped_bench.md)
    return resolve_options(**{"substeps": substeps, "integrator": "radau",
                              "painleve_margin": 0.0, "cone_margins": (RADAU_CONE_MARGIN,),
                              **settings})


# ---- saved plans -------------------------------------------------------------------------

def radau_levels(problem: ContactProblem, holes: str = "TF-9's ellipses",
                 **settings) -> list[ResolveLevel]:
    """The chain's last two re-solves: TF-9's Radau IIA order 5 on `RADAU_ELEMENTS`
    elements per interval, then on that mesh refined where its local defects are large.
    `holes` names the problem's holes; `settings`: other `PolishOptions` fields."""
    options = radau_options(**settings)
    return [ResolveLevel(f"full task, {holes}, Radau IIA order 5, {RADAU_ELEMENTS} "
                         "elements per interval", problem, options),
            ResolveLevel(f"full task, {holes}, Radau IIA order 5, mesh refined by the "
                         "local defects", problem,
                         refine_by_defects(options, RADAU_ELEMENTS))]


# ---- the plan's stages --------------------------------------------------------------------

def _setup(task: MonopedTask | str, options=None) -> PlanSetup:
    mp = monoped_problem(task)
    return PlanSetup(mp.robot, mp.problem, options, mp.scene())


def reduced_discovery(_: str | None = None) -> PlanSetup:
    """The reduced task (one bump hole, T = 1 s, N = 10) with the homotopy settings of the
    chain: up to 3 refinements, IPOPT's adaptive barrier, element derivatives, one thread,
    intermediate NLPs to 0.1."""
    options = monoped_options("reduced")
    options = dataclasses.replace(
        options, homotopy=dataclasses.replace(options.homotopy, max_refinements=3),
        nlp=dataclasses.replace(options.nlp, options={"mu_strategy": "adaptive"},
                                element_derivatives=True, threads=1, intermediate_tol=0.1))
    return _setup("reduced", options)


def reduced_levels(setup: PlanSetup) -> list[ResolveLevel]:
    """The reduced hop's re-solves: 8 RK4 nodes per interval, then 16, then 16 x 2 steps."""
    return [ResolveLevel("exact re-solve, 8 nodes", setup.problem,
                         resolve_options(substeps=8, painleve_margin=0.0)),
            ResolveLevel("exact re-solve, 16 nodes", setup.problem,
                         resolve_options(substeps=16, painleve_margin=0.0)),
            ResolveLevel("exact re-solve, 16 nodes x 2 RK4 steps", setup.problem,
                         resolve_options(substeps=16, steps_per_node=2, painleve_margin=0.0))]


def full_setup(_: str | None = None) -> PlanSetup:
    """TF-9's task with the authors' ellipses (`EXACT_TASK`), re-solved exactly only."""
    return _setup(EXACT_TASK)


def full_levels(setup: PlanSetup) -> list[ResolveLevel]:
    """The full task's re-solves: with bump holes (8 nodes x 2 RK4 steps, then 16 x 2),
    then TF-9's ellipses (16 x 2), then `radau_levels`."""
    bumps = monoped_problem(dataclasses.replace(EXACT_TASK, hole_form="bump")).problem
    rk4 = {n: resolve_options(substeps=n, steps_per_node=2, painleve_margin=0.0)
           for n in (8, 16)}
    return [ResolveLevel("full task, bump holes, 8 nodes x 2 RK4 steps", bumps, rk4[8]),
            ResolveLevel("full task, bump holes, 16 nodes x 2 RK4 steps", bumps, rk4[16]),
            ResolveLevel("full task, TF-9's ellipses, 16 nodes x 2 RK4 steps", setup.problem,
                         rk4[16]),
            *radau_levels(setup.problem)]


def terrain_setup(_: str | None = None) -> PlanSetup:
    """TF-9's task with its holes as the terrain's (`TERRAIN_TASK`), re-solved exactly."""
    return _setup(TERRAIN_TASK)


def terrain_levels(setup: PlanSetup) -> list[ResolveLevel]:
    """The terrain task's re-solves: `full_levels` (the bump holes and TF-9's ellipses
    lead the re-solves to hops over the holes), then `radau_levels` on the terrain's
    holes with `TERRAIN_TOUCHDOWN_RATE`."""
    return [*full_levels(full_setup()),
            *radau_levels(setup.problem, "terrain holes", touchdown_rate=TERRAIN_TOUCHDOWN_RATE)]


@dataclass(frozen=True)
class OneHopWithSlip(ResolveStart):
    """Follow the discovered hop (stick, flight, stick) with a slip from `slip_start` to
    the lift-off, the relaxed plan the guess."""

    slip_start: float = SLIP_START

    def begin(self, given: StageInput, levels: Sequence[ResolveLevel]) -> Start:
        result = discovered(given)
        found = contact_phases(result)
        if [p.mode for p in found] != [STICK, FLIGHT, STICK] or found[1].start <= self.slip_start:
            raise NoStart("the relaxed plan's contact sequence is "
                          f"{[(p.mode, round(p.start, 3)) for p in found]}, not one hop "
                          f"lifting off after {self.slip_start} s")
        lift_off = found[1].start
        phases = (Phase(STICK, 0.0, self.slip_start), Phase("slip-", self.slip_start, lift_off),
                  Phase(FLIGHT, lift_off, found[1].end), Phase(STICK, found[2].start, 1.0))
        return Start(result, phases, (discovery_step(result),))


@dataclass(frozen=True)
class TiledHops(ResolveStart):
    """The verified reduced hop tiled on a schedule per task: "search" tries
    `uniform_schedules` with the chain's first level (`search_schedule`), whose cheapest
    solved re-solve replaces that level; a `Schedule` is followed as given."""

    schedules: Mapping[str, Schedule | str]

    def __post_init__(self) -> None:
        for task, schedule in self.schedules.items():
            if not (isinstance(schedule, Schedule) or schedule == "search"):
                raise InvalidInput(f"task `{task}`: a schedule must be a Schedule or "
                                   f"'search', got {schedule!r}")

    def begin(self, given: StageInput, levels: Sequence[ResolveLevel]) -> Start:
        chain = None if given.previous is None else given.previous.chain
        if chain is None:
            raise InvalidInput("the hops are tiled from the reduced hop's exact re-solve")
        if not chain.success:
            raise NoStart(f"the reduced hop is not verified ({chain.status}"
                          f"{': ' + chain.message if chain.message else ''})")
        schedule = self.schedules[given.task]
        if isinstance(schedule, Schedule):
            guess, phases = tiled_guess(chain.plan, EXACT_TASK, schedule)
            return Start(guess, phases, chain.steps)
        first = levels[0]
        best, trials = search_schedule(chain.plan, uniform_schedules(chain.plan), first.problem,
                                       first.options, EXACT_TASK, given.verbose)
        if best is None:
            raise NoStart(f"no schedule of {len(trials)} gave a solved re-solve (IPOPT: "
                          f"{', '.join(t.plan.ipopt_status for t in trials)})")
        if given.verbose:
            print(f"monoped: schedule found, {best.schedule}, flights of "
                  f"{best.schedule.flight_time:.4g} s", flush=True)
        steps = chain.steps + tuple(ChainStep.of(f"{first.name}, {trial.schedule}", trial.plan,
                                                 trial.seconds, trial.peak_memory)
                                    for trial in trials)
        plan = best.plan
        return Start((plan.t, plan.x, plan.u), plan.phases, steps, skip_levels=1)


STAGES = (
    Discover(reduced_discovery, name="discover the reduced task's hop"),
    ExactResolve(levels=reduced_levels, start=OneHopWithSlip(),
                 name="exact re-solve of the reduced hop"),
    ExactResolve(levels=full_levels, start=TiledHops({"full": "search",
                                                      "hand-set": HAND_SET_SCHEDULE}),
                 setup=full_setup, name="exact re-solve of TF-9's task",
                 tasks=("full", "hand-set")),
    ExactResolve(levels=terrain_levels, start=TiledHops({"terrain": "search"}),
                 setup=terrain_setup, name="exact re-solve of TF-9's task, holes as terrain",
                 tasks=("terrain",)),
)
"""The monoped's plan (`tfcontact plan monoped`): the module docstring's chain as stages."""


def verify_saved(path: str | Path, task: MonopedTask = EXACT_TASK
                 ) -> tuple[Verification, float]:
    """(Verification, smallest hole value) of a plan's node file (`plan.npz`,
    `tfcontact.plan_format.resolved`): the exact reference replays it interval by interval
    (the checks of `verify_plan`), the friction cone is checked on the forces and impulses
    recomputed from its states and controls, and the holes are measured at its nodes."""
    plan = load_resolved_plan(path)
    mp = monoped_problem(task)
    verification = verify_polished(mp.problem, plan.phases, plan.t, plan.x, plan.u,
                                   plan.boundary_states)
    return verification, float(np.min(mp.hole_values(plan.x[:, :4])))


if __name__ == "__main__":  # python -m tfcontact.scenes.monoped_exact PLAN.npz
    import sys

    checked, hole_value = verify_saved(sys.argv[1])
    print(checked.summary())
    print(f"smallest ellipse value {hole_value:.3g} (>= 0 outside TF-9's holes)")
    sys.exit(0 if checked.passed and hole_value >= -PATH_TOLERANCE else 1)
