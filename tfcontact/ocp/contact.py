"""Optimal control with time-freezing: contact-rich plans in physical time.

A `ContactProblem` states an OCP for a complementarity Lagrangian system (impacts,
friction) in *physical* time; `solve_contact` turns it into a time-freezing OCP of the
generic layer and solves it (DESIGN.md 4.1, [AUTO23] section 5):

* the speed of time s_k, one per control interval, 1 <= s_k <= s_max, scales every mode;
* the clock constraints t(tau_k) = k T / N at every control-interval boundary (or only
  t(T_numerical) = T), which tie numerical and physical time;
* the running cost is integrated in physical time: L s in free flight, 0 while frozen
  (the modes' clock row; `with_lagrange_cost`), references are evaluated at the clock t;
* the initial guess is the start state everywhere with zero controls (no contact
  schedule), or a given (q, v) guess at the interval boundaries with the clock k T / N.

After the solve the plan is mapped to physical time (frozen pieces dropped, impacts as
jumps) and checked independently by `tfcontact.verify` (`verify_plan` hands the plan's
arrays to `check_time_freezing_plan` with `ContactSolverOptions.verify`): a replay of its
controls (the event-detecting reference of the original system with impacts, else FESD on
a finer grid), the gaps, the friction cone of the recovered contact impulses and the clock.
Only a plan that converged and passed these checks has status success.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, SolveFailed, positive_int
from tfcontact.fesd import Fesd, RadauIIA, Scheme
from tfcontact.fesd.tableau import as_tableau
from tfcontact.mpcc import Homotopy, HomotopyStep, Ipopt, MpccStatus, Relaxation, Scholtes
from tfcontact.ocp.goals import Goal, Motion, TaskReport, check_goals
from tfcontact.ocp.problem import Constraint, OptimalControlProblem
from tfcontact.ocp.solve import OcpResult, Transcription, solve
from tfcontact.timefreezing import (
    PhysicalTrajectory,
    TimeFreezingSystem,
    to_physical_time,
    with_lagrange_cost,
    with_speed_of_time,
)
from tfcontact.verify import (
    TimeFreezingPlan,
    Verification,
    VerifyOptions,
    check_time_freezing_plan,
    state_indices,
)


def _vector(value: object, n: int, default: float, name: str) -> np.ndarray:
    if value is None:
        return np.full(n, default)
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.size == 1 and n != 1:
        return np.full(n, float(arr[0]))
    if arr.size != n:
        raise InvalidInput(f"`{name}` has {arr.size} entries, expected {n}")
    return arr


@dataclass(frozen=True)
class Periodicity:
    """A gait's period at the control-interval boundaries: x_i(t_k + P) = x_i(t_k) for the
    states i named, at every boundary k >= `first` with k + `period` <= N.

    Args:
        states: indices into x = (q, v) of the states that repeat; leave out what
            progresses (a walking base's forward position).
        period: P in control intervals.
        first: the first boundary k that repeats (a start-up before it; 0: the gait
            repeats the start state).
    """

    states: tuple[int, ...]
    period: int
    first: int = 0

    def __post_init__(self) -> None:
        states = tuple(self.states)
        if not states or len(set(states)) != len(states) or not all(
                isinstance(i, int | np.integer) and i >= 0 for i in states):
            raise InvalidInput(f"`Periodicity.states` must be distinct state indices, got "
                               f"{self.states!r}")
        object.__setattr__(self, "states", tuple(int(i) for i in states))
        positive_int(self.period, "Periodicity.period")
        if not isinstance(self.first, int | np.integer) or self.first < 0:
            raise InvalidInput(f"`Periodicity.first` must be a boundary k >= 0, got "
                               f"{self.first!r}")


@dataclass(frozen=True, eq=False)
class ContactProblem:
    """An OCP of a time-freezing system, stated in physical time.

    Main args:
        system: the `TimeFreezingSystem` from `time_freeze(cls)` (no speed of time, no cost
            state yet: this layer adds both).
        q0, v0: the initial configuration and velocity, shape (n_q,).
        horizon: the physical horizon T [s].
        n_intervals: N control intervals.

    Other args:
        running_cost: L(y, u) [cost]/[s], an SX scalar in `system.y` and `system.u`
            (the clock y[clock_index] may appear, for references x_ref(t)).
        terminal_cost: an SX scalar in `system.y` [cost].
        u_lower, u_upper: bounds of the physical controls, (n_u,) or scalar.
        q_lower, q_upper, v_lower, v_upper: state bounds at every grid point.
        speed_of_time: (s_min, s_max) bounds of the speed of time; PROBLEMS.md 0.1
            defaults (1, 25).
        numerical_horizon: the numerical horizon [s] (default: `horizon`).
        stagewise_clock: impose t = k T / N at every control-interval boundary
            (else only at the end).
        path: `Constraint` in (y, u) at every stage point.
        terminal: `Constraint` in y at the end.
        guess: initial guess of (q, v) at the N + 1 interval boundaries, shape
            (N + 1, 2 n_q) (e.g. a tracking reference); the clock's guess is then k T / N.
            Default: the start state everywhere (no contact schedule).
        control_guess: initial guess of the physical controls, (n_u,) or (N, n_u);
            default zero (clipped to the bounds).
        goals: the task (`tfcontact.ocp.goals`: `EndPosition`, `Progress`, `Clearance`,
            `Moves`): checked on the plan's physical motion after the solve; a plan that
            misses one is not a success (status "goal_missed" or "no_motion"). Default
            none: only the physical checks are made, and the summary says so.
        periodicity: a `Periodicity` of the states at the interval boundaries (a gait
            repeating within the horizon; `stagewise_clock` puts boundary k at k T / N).
    """

    system: TimeFreezingSystem
    q0: np.ndarray
    v0: np.ndarray
    horizon: float
    n_intervals: int
    running_cost: ca.SX = field(default_factory=lambda: ca.SX(0))
    terminal_cost: ca.SX = field(default_factory=lambda: ca.SX(0))
    u_lower: np.ndarray | float | None = None
    u_upper: np.ndarray | float | None = None
    q_lower: np.ndarray | float | None = None
    q_upper: np.ndarray | float | None = None
    v_lower: np.ndarray | float | None = None
    v_upper: np.ndarray | float | None = None
    speed_of_time: tuple[float, float] = (1.0, 25.0)
    numerical_horizon: float | None = None
    stagewise_clock: bool = True
    path: Constraint | None = None
    terminal: Constraint | None = None
    guess: np.ndarray | None = None
    control_guess: np.ndarray | None = None
    goals: tuple[Goal, ...] = ()
    periodicity: Periodicity | None = None

    def __post_init__(self) -> None:
        tf = self.system
        if not isinstance(tf, TimeFreezingSystem) or tf.cls is None:
            raise InvalidInput(
                "`system` must be the TimeFreezingSystem of a CLS (from `time_freeze`)"
            )
        if tf.speed_of_time_index is not None or tf.cost_index is not None:
            raise InvalidInput(
                "`system` already has a speed of time or a cost state; pass the plain "
                "`time_freeze(cls)` result, the contact OCP adds both"
            )
        n_q = tf.cls.n_q
        n_u = tf.u.numel()
        for name in ("q0", "v0"):
            value = _vector(getattr(self, name), n_q, 0.0, name)
            object.__setattr__(self, name, value)
        if not (np.isfinite(self.horizon) and self.horizon > 0):
            raise InvalidInput(f"`horizon` must be a positive time [s], got {self.horizon!r}")
        positive_int(self.n_intervals, "n_intervals")
        s_min, s_max = self.speed_of_time
        if not 0 < s_min <= s_max:
            raise InvalidInput(
                f"`speed_of_time` must be (s_min, s_max) with 0 < s_min <= s_max, "
                f"got {self.speed_of_time}"
            )
        if self.numerical_horizon is not None and not self.numerical_horizon > 0:
            raise InvalidInput(
                f"`numerical_horizon` must be positive [s], got {self.numerical_horizon!r}")
        for name, n, default in (("u_lower", n_u, -np.inf), ("u_upper", n_u, np.inf),
                                 ("q_lower", n_q, -np.inf), ("q_upper", n_q, np.inf),
                                 ("v_lower", n_q, -np.inf), ("v_upper", n_q, np.inf)):
            object.__setattr__(self, name, _vector(getattr(self, name), n, default, name))
        for name in ("running_cost", "terminal_cost"):
            value = getattr(self, name)
            value = ca.SX(value) if not isinstance(value, ca.SX) else value
            if value.numel() != 1:
                raise InvalidInput(f"`{name}` must be a scalar SX expression")
            object.__setattr__(self, name, value)

        if self.guess is not None:
            guess = np.asarray(self.guess, dtype=float)
            shape = (self.n_intervals + 1, 2 * n_q)
            if guess.shape != shape or not np.all(np.isfinite(guess)):
                raise InvalidInput(
                    f"`guess` must be a finite array of (q, v) at the interval boundaries, "
                    f"shape {shape}, got shape {guess.shape}")
            object.__setattr__(self, "guess", guess)
        if self.control_guess is not None:
            control = np.asarray(self.control_guess, dtype=float)
            if control.shape == (n_u,):
                control = np.tile(control, (self.n_intervals, 1))
            if control.shape != (self.n_intervals, n_u) or not np.all(np.isfinite(control)):
                raise InvalidInput(
                    f"`control_guess` must be a finite array of shape ({n_u},) or "
                    f"(N, n_u) = ({self.n_intervals}, {n_u}), got shape {control.shape}")
            object.__setattr__(self, "control_guess", control)
        goals = tuple(self.goals)
        for goal in goals:
            if not isinstance(goal, Goal):
                raise InvalidInput(f"`goals` must hold Goal objects (EndPosition, Progress, "
                                   f"Clearance, Moves), got {type(goal).__name__}")
            goal.validate(tf.cls.q_names, tf.cls.n_contacts)
        object.__setattr__(self, "goals", goals)
        period = self.periodicity
        if period is not None:
            if not isinstance(period, Periodicity):
                raise InvalidInput(f"`periodicity` must be a Periodicity, got "
                                   f"{type(period).__name__}")
            if max(period.states) >= 2 * n_q:
                raise InvalidInput(f"`periodicity.states` must index x = (q, v) of "
                                   f"{2 * n_q} entries, got {list(period.states)}")
            if period.first + period.period > self.n_intervals:
                raise InvalidInput(
                    f"`periodicity`: boundary {period.first} plus the period of "
                    f"{period.period} intervals passes the last boundary N = "
                    f"{self.n_intervals}")
            if not self.stagewise_clock:
                raise InvalidInput("`periodicity` needs `stagewise_clock` (boundary k at "
                                   "k T / N, so that a period is a time)")

    @property
    def tau_horizon(self) -> float:
        return self.horizon if self.numerical_horizon is None else self.numerical_horizon


@dataclass(frozen=True)
class ContactSolverOptions:
    """How a contact OCP is discretised and solved.

    Defaults follow PROBLEMS.md 0.1 where they work here: FESD, Radau IIA with 2 stages,
    N_FE = 3, Scholtes relaxation, sigma_0 = 1, kappa = 0.1.

    Args:
        scheme: the IRK scheme.
        n_finite_elements: N_FE per control interval.
        method: `Fesd(...)` or `Standard()`.
        relaxation: the MPCC relaxation.
        homotopy: the sigma schedule and complementarity tolerance.
        nlp: IPOPT settings.
        verify: how the plan is checked (`tfcontact.verify.VerifyOptions`: the replay
            method, e.g. `AutoReplay()`, `ExactReplay()` or `FesdReplay(refinement=4)`,
            and the checks' tolerances).
        attempts: solves at most; a plan that fails (homotopy or checks) is solved again
            from its initial guess perturbed by `restart_noise` (seeded, so runs repeat).
            Which local solution IPOPT reaches depends on its path, and round-off moves
            that path: the hopper's short task from starts 1e-9 m apart failed its replay
            in 1 of 10 runs (benchmarks/hopper_bench.md).
        restart_noise: standard deviation of the Gaussian perturbation that a restart adds
            to the initial guess: to the states at the interval boundaries (not the start
            state, which is fixed) and to the controls (absolute, in their units).
    """

    scheme: Scheme = field(default_factory=lambda: RadauIIA(2))
    n_finite_elements: int = 3
    method: Fesd = field(default_factory=Fesd)
    relaxation: Relaxation = field(default_factory=Scholtes)
    homotopy: Homotopy = field(default_factory=lambda: Homotopy(tolerance=1e-7))
    nlp: Ipopt = field(default_factory=lambda: Ipopt(tol=1e-8, max_iter=2000))
    verify: VerifyOptions = field(default_factory=VerifyOptions)
    attempts: int = 1
    restart_noise: float = 1e-4

    def __post_init__(self) -> None:
        positive_int(self.attempts, "attempts")
        if not (np.isfinite(self.restart_noise) and self.restart_noise > 0):
            raise InvalidInput(
                f"`restart_noise` must be a positive number, got {self.restart_noise!r}")
        if not isinstance(self.verify, VerifyOptions):
            raise InvalidInput(f"`verify` must be a VerifyOptions, got {self.verify!r}")


@dataclass(frozen=True)
class Attempt:
    """One solve of a contact plan (`ContactSolverOptions.attempts`).

    Attributes:
        seed: the perturbation's seed (None: the unperturbed initial guess).
        status: as `ContactResult.status`.
        iterations: IPOPT iterations over the homotopy.
        solve_time, verify_time: seconds.
        end_state_deviation: the verification's end-state deviation.
        nlps: the homotopy's NLPs (`HomotopyStep`: sigma, iterations, residual, seconds,
            IPOPT's status), so that a record shows where a failed solve spent its time.
    """

    seed: int | None
    status: str
    iterations: int
    solve_time: float
    verify_time: float
    end_state_deviation: float
    nlps: tuple[HomotopyStep, ...] = ()


@dataclass(frozen=True, eq=False)
class ContactResult:
    """A contact plan: the OCP solution, its physical-time trajectory and its checks.

    Attributes:
        problem: the `ContactProblem`.
        system: the solved time-freezing system (with speed of time and cost state).
        ocp: the generic `OcpResult` (numerical time tau).
        tau, y: numerical time [s] and states at the element boundaries.
        u: physical controls per interval, (N, n_u); speed_of_time: (N,).
        physical: the `PhysicalTrajectory` (frozen pieces dropped, impacts as jumps).
        verification: the independent checks.
        timings: seconds by phase ("build", "solve", "verify", "total"), summed over all
            attempts.
        options: the `ContactSolverOptions` it was solved with.
        attempts: every solve (more than one after failed plans); this plan is
            `attempts[chosen]`.
        task: the problem's goals measured on the physical plan (`TaskReport`).
    """

    problem: ContactProblem
    system: TimeFreezingSystem
    ocp: OcpResult
    tau: np.ndarray
    y: np.ndarray
    u: np.ndarray
    speed_of_time: np.ndarray
    physical: PhysicalTrajectory
    verification: Verification
    timings: dict[str, float]
    options: ContactSolverOptions | None = None
    attempts: tuple[Attempt, ...] = ()
    task: TaskReport = field(default_factory=lambda: TaskReport(()))

    @property
    def success(self) -> bool:
        """Converged, passed the independent checks and met the task's goals."""
        return self.ocp.success and self.verification.passed and self.task.passed

    @property
    def status(self) -> str:
        return _status(self.ocp, self.verification, self.task)

    @property
    def chosen(self) -> int | None:
        """The index of this plan's solve in `attempts` (None: no attempts recorded)."""
        return nearest_success(self.attempts) if self.attempts else None

    @property
    def message(self) -> str:
        return (f"{self.ocp.message}; {self.verification.summary()}; "
                f"{self.task.summary().splitlines()[0]}")

    def summary(self) -> str:
        """A few lines for a terminal: status, objective, work, residual, time, checks."""
        o = self.ocp
        t = self.timings
        tried = []
        if len(self.attempts) > 1:
            tried = [f"attempts: {len(self.attempts)} (the wall times above are their sums, "
                     f"the other figures attempt {self.chosen + 1}'s, the one nearest "
                     f"success)"]
            tried += [f"  attempt {k + 1}: {a.status}, {a.iterations} IPOPT iterations, "
                      f"end-state deviation {a.end_state_deviation:.2e}"
                      + ("" if a.seed is None else f", guess perturbed (seed {a.seed})")
                      for k, a in enumerate(self.attempts)]
        return "\n".join([
            f"status: {self.status}",
            f"objective: {o.cost:.6g}   NLPs: {o.n_nlps}   IPOPT iterations: "
            f"{o.total_iterations}   complementarity residual: {o.residual:.2e}",
            f"wall time: build {t['build']:.2f} s, solve {t['solve']:.2f} s, "
            f"verify {t['verify']:.2f} s",
            f"impacts (fully frozen pieces of the plan) at t = "
            f"{np.round(self.physical.impact_times, 4).tolist()} s",
            self.verification.summary(),
            self.task.summary(),
            *tried,
        ])


def _status(ocp: OcpResult, verification: Verification, task: TaskReport) -> str:
    """The first thing that failed: the solver, the physics, the task; else "converged"."""
    if not ocp.success:
        return ocp.status.name.lower()
    if not verification.passed:
        return "verification_failed"
    return "converged" if task.passed else task.status


def nearest_success(attempts: Sequence[Attempt]) -> int:
    """The index of the attempt nearest success: a converged one; else a plan that is
    physical but misses its task, then a converged plan that fails its checks
    ("verification_failed"), then a failed homotopy; among equals the smallest end-state
    deviation (NaN last), then the earliest."""
    solver_failed = {s.name.lower() for s in MpccStatus if s is not MpccStatus.CONVERGED}

    def key(k: int) -> tuple[int, float, int]:
        a = attempts[k]
        rank = (0 if a.status == "converged" else 3 if a.status in solver_failed
                else 2 if a.status == "verification_failed" else 1)
        deviation = a.end_state_deviation
        return (rank, deviation if np.isfinite(deviation) else np.inf, k)

    if not attempts:
        raise InvalidInput("`attempts` is empty: no solve to choose from")
    return min(range(len(attempts)), key=key)


def task_report(problem: ContactProblem, physical: PhysicalTrajectory) -> TaskReport:
    """The problem's goals measured on a plan's physical trajectory."""
    cls = problem.system.cls
    motion = Motion(t=physical.t, q=physical.q, gaps=physical.gaps, names=cls.q_names)
    return check_goals(problem.goals, motion)


def perturbed_guess(ocp: OptimalControlProblem, noise: float,
                    seed: int) -> OptimalControlProblem:
    """The OCP with its initial guess at the interval boundaries (not the start state)
    and its control guess perturbed by Gaussian noise of standard deviation `noise`
    (seeded by `seed`), clipped to the bounds: a restart of `solve_contact`."""
    rng = np.random.default_rng(seed)
    n_int, n_x, n_u = ocp.n_intervals, ocp.x0.size, ocp.u_lower.size
    x = np.array(np.broadcast_to(ocp.x0 if ocp.x_guess is None else ocp.x_guess,
                                 (n_int + 1, n_x)))
    u = np.array(np.broadcast_to(0.0 if ocp.u_guess is None else ocp.u_guess, (n_int, n_u)))
    x[1:] += noise * rng.standard_normal((n_int, n_x))
    u += noise * rng.standard_normal(u.shape)
    return dataclasses.replace(ocp, x_guess=np.clip(x, ocp.x_lower, ocp.x_upper),
                               u_guess=np.clip(u, ocp.u_lower, ocp.u_upper))


def transcribe(problem: ContactProblem) -> tuple[OptimalControlProblem, TimeFreezingSystem]:
    """The generic OCP a contact problem becomes (what `solve_contact` solves): the
    time-freezing system with a cost state and the speed of time as last control, the
    clock constraints, the bounds and the initial guess; and that system."""
    tf = problem.system
    u_phys = tf.u
    # The running cost in physical time: the rate is L dt/dtau per mode (0 while frozen).
    tf = with_lagrange_cost(tf, problem.running_cost)
    tf = with_speed_of_time(tf)
    n_y = tf.n_y
    clock = tf.clock_index
    s_min, s_max = problem.speed_of_time
    lower = np.full(n_y, -np.inf)
    upper = np.full(n_y, np.inf)
    lower[tf.q_index], upper[tf.q_index] = problem.q_lower, problem.q_upper
    lower[tf.v_index], upper[tf.v_index] = problem.v_lower, problem.v_upper
    lower[clock] = 0.0
    y0 = tf.initial_state(problem.q0, problem.v0)
    # with_lagrange_cost and with_speed_of_time keep the original SX symbols, so costs
    # written in the plain system's y and u stay valid.
    mayer = problem.terminal_cost + tf.pss.x[tf.cost_index]
    n_int = problem.n_intervals
    T = problem.horizon

    period = problem.periodicity
    repeated = [] if period is None else [state_indices(tf)[i] for i in period.states]
    boundaries: dict[int, ca.SX] = {0: ca.SX(ca.DM(y0))}

    def clock_constraint(k: int, y_k: ca.SX) -> Constraint | None:
        # the hook sees the boundaries in order k = 1..N: it keeps them for the period
        boundaries[k] = y_k
        rows = []
        if problem.stagewise_clock or k == n_int:
            rows.append(y_k[clock] - k * T / n_int)
        if period is not None and k - period.period >= period.first:
            earlier = boundaries[k - period.period]
            rows += [y_k[i] - earlier[i] for i in repeated]
        return Constraint(ca.vertcat(*rows)) if rows else None

    n_u = u_phys.numel()
    u_lower = np.concatenate([problem.u_lower, [s_min]])
    u_upper = np.concatenate([problem.u_upper, [s_max]])
    controls = np.zeros((n_int, n_u)) if problem.control_guess is None else \
        problem.control_guess
    u_guess = np.hstack([np.clip(controls, problem.u_lower, problem.u_upper),
                         np.full((n_int, 1), np.clip(T / problem.tau_horizon, s_min, s_max))])
    terminal = problem.terminal
    x_guess = y0
    if problem.guess is not None:
        x_guess = np.tile(y0, (n_int + 1, 1))
        n_q = problem.q0.size
        x_guess[:, tf.q_index] = problem.guess[:, :n_q]
        x_guess[:, tf.v_index] = problem.guess[:, n_q:]
        x_guess[:, clock] = np.linspace(0.0, T, n_int + 1)
    ocp = OptimalControlProblem(
        system=tf.pss, x0=y0, horizon=problem.tau_horizon, n_intervals=n_int,
        mayer=mayer, u_lower=u_lower, u_upper=u_upper, x_lower=lower, x_upper=upper,
        path=problem.path, terminal=terminal, boundary_constraints=clock_constraint,
        x_guess=x_guess, u_guess=u_guess,
    )
    return ocp, tf


def _warm_start(ocp: OptimalControlProblem, previous: ContactResult,
                transcription: Transcription, system: TimeFreezingSystem
                ) -> tuple[OptimalControlProblem, np.ndarray | None]:
    """The OCP with `previous` as its initial guess, and the previous MPCC iterate when the
    discretisation is the same (else None: the guess at the boundaries is interpolated)."""
    if not isinstance(previous, ContactResult):
        raise InvalidInput(f"`initial_guess` must be a ContactResult, got "
                           f"{type(previous).__name__}")
    prev = previous.ocp
    n_int, n_x, n_u = ocp.n_intervals, ocp.x0.size, ocp.u_lower.size
    if prev.x_intervals.shape != (n_int + 1, n_x) or prev.u.shape != (n_int, n_u):
        raise InvalidInput(
            f"`initial_guess` must be a plan of the same system with N = {n_int} control "
            f"intervals: its boundary states have shape {prev.x_intervals.shape} (expected "
            f"{(n_int + 1, n_x)}), its controls {prev.u.shape} (expected {(n_int, n_u)})")
    guess = dataclasses.replace(ocp, x_guess=prev.x_intervals,
                                u_guess=np.clip(prev.u, ocp.u_lower, ocp.u_upper))
    disc = prev.build.discretization
    same = (disc.tableau.name == as_tableau(transcription.scheme).name
            and disc.grid.n_finite_elements == transcription.n_finite_elements
            and disc.method == transcription.method
            and _variable_sizes(previous.system) == _variable_sizes(system))
    return guess, (prev.mpcc_result.w.copy() if same else None)


def _variable_sizes(system: TimeFreezingSystem) -> tuple[int, ...]:
    """What sizes a time-freezing system's NLP variables per stage: its states, controls,
    steps alpha and auxiliary variables (the inverse-dynamics form's accelerations)."""
    pss = system.pss
    auxiliary = 0 if pss.auxiliary is None else pss.auxiliary.numel()
    return pss.x.numel(), pss.u.numel(), pss.alpha.numel(), auxiliary


def verify_plan(
    problem: ContactProblem,
    system: TimeFreezingSystem,
    ocp: OcpResult,
    physical: PhysicalTrajectory,
    options: ContactSolverOptions,
) -> Verification:
    """The independent checks of a contact plan (`tfcontact.verify.check_time_freezing_plan`
    with `options.verify`, see `Verification`)."""
    return check_time_freezing_plan(
        time_freezing_plan(problem, system, ocp, physical, options), options.verify)


def time_freezing_plan(problem: ContactProblem, system: TimeFreezingSystem, ocp: OcpResult,
                       physical: PhysicalTrajectory,
                       options: ContactSolverOptions) -> TimeFreezingPlan:
    """What the checks read of a solved contact OCP (`tfcontact.verify.TimeFreezingPlan`)."""
    return TimeFreezingPlan(
        system=system, start=np.concatenate([problem.q0, problem.v0]),
        horizon=problem.horizon, tau_horizon=problem.tau_horizon, tau=ocp.t, x=ocp.x,
        x_stages=ocp.x_stages, h=ocp.h, tableau=ocp.build.discretization.tableau,
        x_intervals=ocp.x_intervals, u=ocp.u, n_finite_elements=options.n_finite_elements,
        physical=physical, homotopy=options.homotopy, nlp=options.nlp)


def solve_contact(
    problem: ContactProblem,
    options: ContactSolverOptions | None = None,
    *,
    initial_guess: ContactResult | None = None,
    first_seed: int = 0,
    verbose: bool = True,
    throw: bool = False,
) -> ContactResult:
    """Solve a contact OCP with time-freezing + FESD + MPCC homotopy, then verify it.

    Main args:
        problem: the `ContactProblem`.
        options: discretisation, homotopy and verification settings.

    Other args:
        initial_guess: a previous plan of the same system with the same number of control
            intervals (another scheme, N_FE, cost or constraint is fine): its whole
            iterate is the start when the discretisation is the same, else its states
            and controls at the interval boundaries. Start the homotopy lower
            (`Homotopy(sigma_0=...)`) to stay near it.
        first_seed: the seed of the first solve's perturbed guess (0: the unperturbed
            guess); attempt k uses first_seed + k. A pipeline that runs a whole plan again
            after its later stage failed (`tfcontact.scenes.Plan.whole_attempts`) solves
            its k-th discovery with first_seed = k.
        verbose: one line per homotopy step and the summary.
        throw: raise `SolveFailed` (with the result) unless the plan succeeded.

    Returns:
        A `ContactResult`; `success` only if the homotopy converged and the plan passed
        the independent checks. With `options.attempts` > 1 a failed plan is solved again
        from a perturbed guess; the result is the first plan that succeeded, else the
        failed one nearest success (`nearest_success`), and `attempts` lists them all.
    """
    options = options if options is not None else ContactSolverOptions()
    if (isinstance(first_seed, bool) or not isinstance(first_seed, int | np.integer)
            or first_seed < 0):
        raise InvalidInput(f"`first_seed` must be an integer >= 0, got {first_seed!r}")
    first_seed = int(first_seed)
    start = time.perf_counter()
    ocp_problem, system = transcribe(problem)
    transcription = Transcription(scheme=options.scheme,
                                  n_finite_elements=options.n_finite_elements,
                                  method=options.method)
    w0 = None
    if initial_guess is not None:
        ocp_problem, w0 = _warm_start(ocp_problem, initial_guess, transcription, system)
    attempts: list[Attempt] = []
    solves: list[tuple] = []
    totals = {"build": 0.0, "solve": 0.0, "verify": 0.0}
    for k in range(options.attempts):
        seed = (first_seed + k) or None  # seed 0: the unperturbed guess
        attempt_problem, attempt_w0 = ocp_problem, w0
        if seed is not None:
            if verbose and attempts:
                last = attempts[-1]
                print(f"attempt {k + 1} of {options.attempts}: the last plan ended "
                      f"{last.status} (end-state deviation {last.end_state_deviation:.2e}); "
                      f"solving again from the initial guess perturbed by "
                      f"{options.restart_noise:g} (seed {seed})", flush=True)
            elif verbose:
                print(f"solving from the initial guess perturbed by "
                      f"{options.restart_noise:g} (seed {seed})", flush=True)
            attempt_problem = perturbed_guess(ocp_problem, options.restart_noise, seed)
            attempt_w0 = None
        result = solve(attempt_problem, discretization=transcription,
                       relaxation=options.relaxation, homotopy=options.homotopy,
                       nlp=options.nlp, w0=attempt_w0, verbose=verbose, throw=False)
        solved = time.perf_counter()
        physical = to_physical_time(system, result.t, result.x)
        verification = verify_plan(problem, system, result, physical, options)
        task = task_report(problem, physical)
        verify_time = time.perf_counter() - solved
        totals["build"] += result.build_time
        totals["solve"] += result.solve_time
        totals["verify"] += verify_time
        status = _status(result, verification, task)
        attempts.append(Attempt(seed=seed, status=status, iterations=result.total_iterations,
                                solve_time=result.solve_time, verify_time=verify_time,
                                end_state_deviation=verification.end_state_deviation,
                                nlps=result.mpcc_result.history))
        solves.append((result, physical, verification, task))
        if status == "converged":
            break
    # a failed plan's best attempt, not its last: the exact re-solve starts from it
    result, physical, verification, task = solves[nearest_success(attempts)]
    n_u = system.u.numel() - 1
    contact = ContactResult(
        problem=problem, system=system, ocp=result, tau=result.t, y=result.x,
        u=result.u[:, :n_u], speed_of_time=result.u[:, n_u], physical=physical,
        verification=verification, options=options,
        timings={**totals, "total": time.perf_counter() - start},
        attempts=tuple(attempts), task=task,
    )
    if verbose:
        print(contact.summary(), flush=True)
    if throw and not contact.success:
        raise SolveFailed(contact.message, contact)
    if result.status is MpccStatus.NLP_FAILED and verbose:
        print(f"IPOPT: {result.ipopt_status}", flush=True)
    return contact
