"""TF-9's monoped planned in two stages: the time-freezing homotopy finds a hop, the exact
re-solve (`tfcontact.ocp.polish`) turns it into a verified plan.

The time-freezing homotopy of the full task from the start-everywhere guess ends
nlp_failed (benchmarks/monoped_settings.md); the reduced task's (one hole, T = 1 s)
converges and finds one hop: stick, flight, stick. The chain:

1. `reduced_exact_plan`: the reduced task's relaxed plan, then the exact re-solve along
   its sequence with a slip before the lift-off (its start guessed at 0.55 s): 8 RK4
   nodes per interval, then 16, then 16 nodes x 2 RK4 steps, each warm started from the
   last. A verified plan of the reduced task.
2. `tiled_guess`: that hop three times on a `Schedule`, lift-offs straight from stick at
   control jumps, one metre further per hop. `full_exact_plan` searches the schedule by
   default: `uniform_schedules` lists one hop per hole with the hop's flight time and
   lift-offs at evenly spaced control jumps, each candidate gets the first re-solve of
   step 3, and the solved candidate with the lowest objective continues (measured:
   lift-offs 0.5, 1.125, 1.75 s). The number of hops and the even spacing are a rule;
   the lift-off times are not set by hand. `HAND_SET_SCHEDULE` is the schedule of the
   earlier plans, set by hand from the reduced hop time scaled by 5/6: lift-offs 0.5,
   1.25 and 2.0 s, flights of 0.26 s.
3. `full_exact_plan`: the exact re-solve of `EXACT_TASK` (T = 2.5 s, N = 20, three holes
   of half width 0.25 as in the authors' robot_ocp.m) along that schedule with free
   touchdowns: with bump holes (8 nodes x 2 RK4 steps, then 16 x 2), then with TF-9's
   ellipses (16 x 2).
4. `radau_levels`: TF-9's scheme, Radau IIA order 5 collocation (FESD with the active
   set fixed), on `RADAU_ELEMENTS` elements per interval, then on that mesh refined where
   the plan's local defects exceed their share of the tolerance. TF-9's own 3 elements
   per interval are too coarse for this motion (`RADAU_ELEMENTS`).

The re-solves are fragile: one rerun of the chain found another local solution and
stopped at IPOPT's iteration cap in its second step, and the ellipse re-solve from that
capped iterate converged and passed. So a step that stops at the cap hands its iterate
to the next step (`ChainStep.status` says so), and the last step is solved once more
from its own iterate if it stops at the cap; any other failure ends the chain with a
failed status. Only the last step's verification decides.
"""

from __future__ import annotations

import ctypes
import dataclasses
import gc
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.ocp.polish import (
    FLIGHT,
    STICK,
    Phase,
    PolishedPlan,
    PolishOptions,
    contact_phases,
    polish_contact,
    refined_substeps,
    verify_polished,
)
from tfcontact.scenes.monoped import (
    FULL_TASK,
    MonopedProblem,
    hole_profile,
    monoped_options,
    monoped_problem,
)
from tfcontact.verify import Verification

EXACT_TASK = dataclasses.replace(FULL_TASK, hole_half_width=0.25, hole_form="ellipse")
"""The task of `full_exact_plan`: TF-9 (T = 2.5 s, N = 20, |u| <= 60, q(T) = (3, 0.4, 0, 0))
with TF-9's ellipses of half width 0.25 (the authors' robot_ocp.m; PROBLEMS.md lists 0.5,
under which the holes at 0.5, 1.5 and 2.5 leave 0.5 m of ground between them)."""



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


HAND_SET_SCHEDULE = Schedule(lift_offs=(0.5, 1.25, 2.0), flight_time=0.26)
"""The schedule of the earlier verified plan (benchmarks/monoped_exact_plan.npz,
`tfcontact plan monoped --task hand-set`): set by hand from the reduced hop (time scaled
by 5/6), lift-offs at control jumps (T / N = 0.125 s)."""
HOP_LIFT_OFF, HOP_TOUCHDOWN = 0.6, 0.89
"""The reduced hop's lift-off and touchdown [s] as the tiling uses them (the measured hops:
0.600 and 0.881 s; the verified full plans were made with these numbers)."""
SLIP_START = 0.55
"""Guessed start [s] of the reduced hop's slip before its lift-off."""
CAPPED = "Maximum_Iterations_Exceeded"
RADAU_ELEMENTS = 12
"""Radau IIA elements per control interval of the last re-solves. TF-9's own N_FE = 3
re-solves the RK4 plan (32 iterations) into a plan whose exact replay parts from it by 14
in one interval: the leg swings at up to 100 rad/s before each touchdown."""
RADAU_CONE_MARGIN = 0.98
"""The Radau re-solves keep the stick forces within 0.98 mu lambda_n: with the full cone
(1.0) the 12-element plan stuck on the cone's edge in one interval, where the exact replay
slipped and parted from it by 3.2."""
HOLE_TOLERANCE = 1e-6
"""A plan enters a hole if its smallest hole value is below -HOLE_TOLERANCE."""


@dataclass(frozen=True)
class ChainStep:
    """One re-solve of the chain: its name, IPOPT status, iterations, seconds, objective
    and the plan's status."""

    name: str
    ipopt_status: str
    iterations: int
    seconds: float
    objective: float
    status: str


@dataclass(frozen=True, eq=False)
class ExactPlan:
    """The result of a chain: the last re-solve's plan, the problem it solves and the steps.

    Attributes:
        plan: the last step's `PolishedPlan` (its verification decides).
        problem: the `MonopedProblem` of the last step (`EXACT_TASK` or the reduced task).
        steps: every re-solve, in order (the relaxed homotopy first, as a step).
        smallest_hole_value: the smallest ellipse value ((p_x - x_c)/a)^2 + (p_z/b)^2 - 1
            at the plan's nodes (>= 0 outside the holes).
        wall_time: seconds for the whole chain.
        message: why the chain stopped, when it failed.
    """

    plan: PolishedPlan | None
    problem: MonopedProblem
    steps: tuple[ChainStep, ...]
    smallest_hole_value: float
    wall_time: float
    message: str = ""

    @property
    def status(self) -> str:
        if self.plan is None:
            return "chain_failed"
        if self.plan.success and not self.smallest_hole_value >= -HOLE_TOLERANCE:
            return "verification_failed"  # the foot enters a hole between constrained nodes
        return self.plan.status

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def summary(self) -> str:
        lines = [f"monoped exact chain: {self.status} in {self.wall_time:.0f} s"
                 + (f" ({self.message})" if self.message else "")]
        for step in self.steps:
            lines.append(f"  {step.name}: {step.status} (IPOPT {step.ipopt_status}, "
                         f"{step.iterations} iterations, {step.seconds:.0f} s, objective "
                         f"{step.objective:.6g})")
        if self.plan is not None:
            lines.append(self.plan.summary())
            lines.append(f"smallest hole value {self.smallest_hole_value:.3g} (>= 0 outside "
                         "the holes)")
        return "\n".join(lines)


def _step(name: str, plan: PolishedPlan, seconds: float) -> ChainStep:
    return ChainStep(name, plan.ipopt_status, plan.iterations, seconds, plan.cost, plan.status)


def _hole_value(problem: MonopedProblem, plan: PolishedPlan) -> float:
    return float(np.min(problem.hole_values(plan.x[:, :4])))


def reduced_exact_plan(verbose: bool = True) -> ExactPlan:
    """The reduced task (one bump hole, T = 1 s, N = 10): its relaxed plan from the
    start-everywhere guess (the homotopy finds stick, flight, stick), then the exact
    re-solve with a slip before the lift-off (8 nodes, 16 nodes, 16 nodes x 2 RK4 steps).
    About 6 minutes; the measured runs: 778 iterations for the homotopy, then 458, 122
    and 810 (objective 176.43)."""
    from tfcontact.ocp.contact import solve_contact

    start = time.perf_counter()
    mp = monoped_problem("reduced")
    options = monoped_options("reduced")
    options = dataclasses.replace(
        options, homotopy=dataclasses.replace(options.homotopy, max_refinements=3),
        nlp=dataclasses.replace(options.nlp, options={"mu_strategy": "adaptive"},
                                element_derivatives=True, threads=1, intermediate_tol=0.1))
    if verbose:
        print("monoped (reduced): the time-freezing homotopy from the start-everywhere guess",
              flush=True)
    relaxed = solve_contact(mp.problem, options, verbose=verbose)
    history = relaxed.ocp.mpcc_result.history
    steps = [ChainStep("time-freezing homotopy (reduced task)",
                       history[-1].ipopt_status if history else "none",
                       relaxed.ocp.total_iterations, time.perf_counter() - start,
                       float(relaxed.ocp.cost), relaxed.status)]
    found = contact_phases(relaxed)
    if [p.mode for p in found] != [STICK, FLIGHT, STICK] or found[1].start <= SLIP_START:
        return ExactPlan(None, mp, tuple(steps), float("nan"), time.perf_counter() - start,
                         message="the relaxed plan's contact sequence is "
                                 f"{[(p.mode, round(p.start, 3)) for p in found]}, not one "
                                 f"hop lifting off after {SLIP_START} s")
    lift_off = found[1].start
    phases = (Phase(STICK, 0.0, SLIP_START), Phase("slip-", SLIP_START, lift_off),
              Phase(FLIGHT, lift_off, found[1].end), Phase(STICK, found[2].start, 1.0))
    levels = [("exact re-solve, 8 nodes", mp, PolishOptions(substeps=8, painleve_margin=0.0)),
              ("exact re-solve, 16 nodes", mp, PolishOptions(substeps=16, painleve_margin=0.0)),
              ("exact re-solve, 16 nodes x 2 RK4 steps", mp,
               PolishOptions(substeps=16, steps_per_node=2, painleve_margin=0.0))]
    return run_chain(levels, phases, relaxed, steps, start, verbose)


def _return_memory() -> None:
    """Collect garbage and hand freed heap pages back to the system (glibc's malloc_trim).
    Without it the process kept much of each re-solve's freed NLP graph: the reduced chain
    held 3.0 GB after its last step (0.17 GB with it), the full chain peaked at 21 GB."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to trim
        pass


def run_chain(levels, phases, guess, steps: list[ChainStep], start: float,
           verbose: bool) -> ExactPlan:
    """Run the re-solves `levels` [(name, MonopedProblem, PolishOptions or a function
    (last plan, problem) -> PolishOptions)] in order, each from the last (the first from
    `guess`: a relaxed plan or (t, x, u)); a
    step at the iteration cap hands its iterate on, the last one is solved once more from
    its own iterate; other failures stop the chain (module docstring)."""
    plan = None
    for i, (name, problem, options) in enumerate(levels):
        last = i == len(levels) - 1
        if callable(options):  # settings that depend on the last plan (a refined mesh)
            options = options(plan, problem)
        for attempt in range(2 if last else 1):
            label = name if attempt == 0 else f"{name}, again from its capped iterate"
            if verbose:
                print(f"monoped: {label}", flush=True)
            begin = time.perf_counter()
            plan = polish_contact(problem.problem, phases, options, guess=guess,
                                  verbose=verbose)
            _return_memory()
            steps.append(_step(label, plan, time.perf_counter() - begin))
            guess, phases = (plan.t, plan.x, plan.u), plan.phases
            if plan.ipopt_status != CAPPED:
                break
        if not plan.solved and plan.ipopt_status != CAPPED:
            return ExactPlan(plan, problem, tuple(steps), _hole_value(problem, plan),
                             time.perf_counter() - start,
                             message=f"{name}: IPOPT {plan.ipopt_status}")
        if not plan.solved and verbose and not last:
            print(f"monoped: {name} stopped at the iteration cap; its iterate starts the next "
                  "step", flush=True)
    return ExactPlan(plan, problem, tuple(steps), _hole_value(problem, plan),
                     time.perf_counter() - start,
                     message="" if plan.solved else f"{levels[-1][0]}: IPOPT {plan.ipopt_status}")


def tiled_guess(hop: PolishedPlan, task=EXACT_TASK, schedule: Schedule = HAND_SET_SCHEDULE):
    """The reduced hop once per lift-off of `schedule`: ((t, x, u), phases) as a guess of
    the full task. Each segment of the hop (stance before the lift-off, flight, last
    stance) is time scaled onto its slot, velocities divided and torques by the square of
    the scale, q_x moved one metre per hop."""
    if schedule.lift_offs[-1] + schedule.flight_time >= task.horizon:
        raise InvalidInput(f"the schedule's last hop lands after the horizon {task.horizon} s")
    lift_offs, flight_time = schedule.lift_offs, schedule.flight_time
    lift_off, touchdown = HOP_LIFT_OFF, HOP_TOUCHDOWN
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


def uniform_schedules(hop: PolishedPlan, task=EXACT_TASK, first=(3, 4, 5),
                      spacing=(5, 6)) -> tuple[Schedule, ...]:
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


def search_schedule(hop: PolishedPlan, schedules: tuple[Schedule, ...], problem: MonopedProblem,
                    options: PolishOptions, verbose: bool = True
                    ) -> tuple[ScheduleTrial | None, tuple[ScheduleTrial, ...]]:
    """Re-solve the full task from the hop tiled on each schedule; (the trial IPOPT solved
    with the lowest objective or None, every trial). A schedule the re-solve cannot follow
    ends infeasible (benchmarks/monoped_settings.md, sixth session: 4 of 8 did)."""
    trials = []
    for i, schedule in enumerate(schedules):
        if verbose:  # a candidate takes 1-5 minutes
            print(f"monoped: schedule {i + 1} of {len(schedules)}, {schedule}", flush=True)
        guess, phases = tiled_guess(hop, problem.task, schedule)
        begin = time.perf_counter()
        plan = polish_contact(problem.problem, phases, options, guess=guess, verbose=False)
        _return_memory()
        trials.append(ScheduleTrial(schedule, plan, time.perf_counter() - begin))
        if verbose:
            print(f"  IPOPT {plan.ipopt_status}, {plan.iterations} iterations, "
                  f"{trials[-1].seconds:.0f} s, objective {plan.cost:.6g}", flush=True)
    solved = [t for t in trials if t.plan.solved]
    best = min(solved, key=lambda t: t.plan.cost) if solved else None
    return best, tuple(trials)


def full_exact_plan(verbose: bool = True, schedule: Schedule | str = "search"
                    ) -> ExactPlan:
    """TF-9's task (`EXACT_TASK`) by the chain of the module docstring, its guess the
    reduced hop tiled on the `uniform_schedules` candidate whose first re-solve IPOPT
    solves with the lowest objective (schedule="search": `search_schedule`; that re-solve
    is the chain's first step), or on a given `Schedule` (`HAND_SET_SCHEDULE`: the
    earlier verified plan). About an hour on a 2-core machine either way
    (benchmarks/monoped_exact.md).

    Raises:
        InvalidInput: `schedule` is neither a `Schedule` nor "search".
    """
    if not (isinstance(schedule, Schedule) or schedule == "search"):
        raise InvalidInput(f"`schedule` must be a Schedule or 'search', got {schedule!r}")
    start = time.perf_counter()
    reduced = reduced_exact_plan(verbose)
    steps = list(reduced.steps)
    if not reduced.success:
        return ExactPlan(reduced.plan, reduced.problem, tuple(steps),
                         reduced.smallest_hole_value, time.perf_counter() - start,
                         message=f"the reduced hop is not verified ({reduced.status}"
                                 f"{': ' + reduced.message if reduced.message else ''})")
    bumps = monoped_problem(dataclasses.replace(EXACT_TASK, hole_form="bump"))
    ellipses = monoped_problem(EXACT_TASK)
    options = {n: PolishOptions(substeps=n, steps_per_node=2, painleve_margin=0.0)
               for n in (8, 16)}
    levels = [("full task, bump holes, 8 nodes x 2 RK4 steps", bumps, options[8]),
              ("full task, bump holes, 16 nodes x 2 RK4 steps", bumps, options[16]),
              ("full task, TF-9's ellipses, 16 nodes x 2 RK4 steps", ellipses, options[16]),
              *radau_levels(ellipses)]
    if schedule != "search":
        guess, phases = tiled_guess(reduced.plan, EXACT_TASK, schedule)
        return run_chain(levels, phases, guess, steps, start, verbose)
    # the candidates' re-solve is the chain's first level, which the chosen one replaces
    first_name, first_problem, first_options = levels[0]
    best, trials = search_schedule(reduced.plan, uniform_schedules(reduced.plan),
                                   first_problem, first_options, verbose)
    steps += [_step(f"{first_name}, {trial.schedule}", trial.plan, trial.seconds)
              for trial in trials]
    if best is None:
        return ExactPlan(None, first_problem, tuple(steps), float("nan"),
                         time.perf_counter() - start,
                         message=f"no schedule of {len(trials)} gave a solved re-solve")
    if verbose:
        print(f"monoped: schedule found, {best.schedule}, flights of "
              f"{best.schedule.flight_time:.4g} s", flush=True)
    plan = best.plan
    return run_chain(levels[1:], plan.phases, (plan.t, plan.x, plan.u), steps, start, verbose)


def radau_options(substeps: int | tuple[int, ...] = RADAU_ELEMENTS) -> PolishOptions:
    """TF-9's scheme (Radau IIA, order 5) on `substeps` elements per control interval,
    the stick forces kept 2 % inside the friction cone (`RADAU_CONE_MARGIN`)."""
    return PolishOptions(substeps=substeps, integrator="radau", painleve_margin=0.0,
                         cone_margins=(RADAU_CONE_MARGIN,))


def refine_by_defects(plan: PolishedPlan, problem: MonopedProblem) -> PolishOptions:
    """`radau_options` on the last plan's mesh, its elements doubled in each interval whose
    local defect exceeds its share of the verification's tolerance (`refined_substeps`)."""
    n = problem.task.n_intervals
    mesh = plan.substeps if plan.substeps else (RADAU_ELEMENTS,) * n
    return radau_options(refined_substeps(mesh, plan.verification.local_defects,
                                          PolishOptions().end_state_tolerance))


def radau_levels(problem: MonopedProblem) -> list:
    """The chain's last two re-solves: TF-9's Radau IIA order 5 on `RADAU_ELEMENTS`
    elements per interval, then on that mesh refined where its local defects are large."""
    return [(f"full task, TF-9's ellipses, Radau IIA order 5, {RADAU_ELEMENTS} elements per "
             "interval", problem, radau_options()),
            ("full task, TF-9's ellipses, Radau IIA order 5, mesh refined by the local "
             "defects", problem, refine_by_defects)]


# ---- saved plans -------------------------------------------------------------------------

def save_exact_plan(plan: PolishedPlan, path: str | Path) -> Path:
    """Write a polished plan's arrays (node times, states, controls, boundary states, phases,
    local defects) to an .npz that `verify_saved` checks again."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, t=plan.t, x=plan.x, u=plan.u, boundary=plan.boundary_states,
             phase_modes=np.array([p.mode for p in plan.phases]),
             phase_starts=np.array([p.start for p in plan.phases]),
             local_defects=np.asarray(plan.verification.local_defects),
             integrator=plan.integrator, substeps=np.asarray(plan.substeps, dtype=int))
    return path


def saved_phases(plan: Any) -> tuple[Phase, ...]:
    """The contact sequence of a plan saved by `save_exact_plan`."""
    starts = [float(s) for s in plan["phase_starts"]]
    ends = starts[1:] + [float(plan["t"][-1])]
    return tuple(Phase(str(m), a, b)
                 for m, a, b in zip(plan["phase_modes"], starts, ends, strict=True))


def verify_saved(path: str | Path, task=EXACT_TASK) -> tuple[Verification, float]:
    """(Verification, smallest hole value) of a plan saved by `save_exact_plan`: the exact
    reference replays it interval by interval (the checks of `verify_plan`), the friction
    cone is checked on the forces and impulses recomputed from its states and controls,
    and the holes are measured at its nodes."""
    plan = np.load(path)
    mp = monoped_problem(task)
    verification = verify_polished(mp.problem, saved_phases(plan), plan["t"], plan["x"],
                                   plan["u"], plan["boundary"])
    return verification, float(np.min(mp.hole_values(plan["x"][:, :4])))


_SCHEME = {"rk4": "RK4", "radau": "Radau IIA"}


def plot_exact_plan(plan: PolishedPlan, problem: MonopedProblem, path: str | Path) -> Path:
    """The figure of a monoped plan: the foot's, knee's and hip's paths over the holes, the
    joint angles and the torques (dotted: lift-offs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    task = problem.task
    t, x, u = plan.t, plan.x, plan.u
    foot = np.asarray(problem.foot(x[:, :4].T)).T
    knee = np.asarray(problem.knee(x[:, :4].T)).T
    fig, (where, angles, torques) = plt.subplots(3, 1, figsize=(8, 8.5))
    for centre in task.holes:
        outline = hole_profile(task, centre, 64)
        where.fill(outline[:, 0], np.maximum(outline[:, 1], 0.0), color="tab:red", alpha=0.3,
                   lw=0)
    where.plot(foot[:, 0], foot[:, 1], label="foot")
    where.plot(x[:, 0], x[:, 1], label="hip")
    where.plot(knee[:, 0], knee[:, 1], lw=0.8, label="knee")
    where.axhline(0, color="k", lw=0.8)
    where.set(xlabel="x [m]", ylabel="z [m]", aspect="equal",
              title=f"TF-9 monoped, exact re-solve ({_SCHEME[plan.integrator]}; "
                    f"{task.hole_form} holes of half width {task.hole_half_width:g} m): "
                    f"{plan.status}")
    where.legend(loc="upper right", fontsize=8)
    angles.plot(t, x[:, 2], label="hip angle")
    angles.plot(t, x[:, 3], label="knee angle")
    angles.set(xlabel="t [s]", ylabel="[rad]")
    angles.legend(fontsize=8)
    grid = np.linspace(0, task.horizon, len(u) + 1)
    for i, name in enumerate(("hip", "knee")):
        torques.stairs(u[:, i], grid, label=f"{name} torque")
    for phase in plan.phases:
        if phase.mode == FLIGHT:
            torques.axvline(phase.start, color="gray", lw=0.6, ls=":")
    torques.set(xlabel="t [s] (dotted: lift-offs)", ylabel="[N m]")
    torques.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":  # python -m tfcontact.scenes.monoped_exact PLAN.npz
    import sys

    checked, hole_value = verify_saved(sys.argv[1])
    print(checked.summary())
    print(f"smallest ellipse value {hole_value:.3g} (>= 0 outside TF-9's holes)")
    sys.exit(0 if checked.passed and hole_value >= -HOLE_TOLERANCE else 1)
