"""What the exact re-solves (`polish`: one contact; `stances`: several) share: a contact
problem's rows and costs as functions of a node's state x = (q, v), its time and control,
a guess read off a sampled trajectory, the collocation equations of an element and a
shooting step as functions, the Delassus solves, an Opti solve that reports its progress,
stops on Ctrl-C within an iteration and says where its time went (`NlpTiming`), and the
rows an Opti problem repeats (`RepeatedRows`), differentiated once per function."""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact import interrupt
from tfcontact.mpcc import RepeatedBlock, evaluation_seconds, repeated_block_derivatives
from tfcontact.mpcc.solver import IterationProgress
from tfcontact.native import blas_threads

CAPPED = "Maximum_Iterations_Exceeded"
"""IPOPT's status at its iteration cap (the re-solves carry such an iterate on)."""


@dataclass(frozen=True, eq=False)
class NodeFunctions:
    """A `ContactProblem`'s rows and costs at a node (CasADi functions of the
    time-freezing state y and control u; `y_of` builds y from x = (q, v) and the time).

    Attributes:
        path, terminal: the problem's constraints (None: none); path_fn, terminal_fn their
            expressions as functions (None with them).
        running, terminal_cost: the costs as functions.
        lower, upper: the bounds of x = (q, v).
    """

    problem: object
    path: object
    path_fn: ca.Function | None
    running: ca.Function
    terminal_cost: ca.Function
    terminal: object
    terminal_fn: ca.Function | None
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def of(cls, problem) -> NodeFunctions:
        system = problem.system
        y_sym, u_sym = system.y, system.u
        path, terminal = problem.path, problem.terminal
        return cls(
            problem=problem, path=path,
            path_fn=None if path is None else ca.Function("path", [y_sym, u_sym],
                                                          [path.expression]),
            running=ca.Function("running", [y_sym, u_sym], [problem.running_cost]),
            terminal_cost=ca.Function("terminal_cost", [y_sym], [problem.terminal_cost]),
            terminal=terminal,
            terminal_fn=(None if terminal is None
                         else ca.Function("terminal", [y_sym], [terminal.expression])),
            lower=np.concatenate([problem.q_lower, problem.v_lower]),
            upper=np.concatenate([problem.q_upper, problem.v_upper]))

    def path_rows(self) -> tuple[ca.Function, np.ndarray, np.ndarray] | None:
        """The path rows as a function of a node's (x, u) with their bounds (`bounded_rows`),
        or None without path rows or when they depend on the time."""
        path, system = self.path, self.problem.system
        if path is None or ca.depends_on(path.expression, system.y[system.clock_index]):
            return None
        x = ca.SX.sym("x", 2 * system.cls.n_q)
        u = ca.SX.sym("u", system.cls.n_u)
        return bounded_rows("path_rows", [x, u],
                            [(path.lower, self.path_fn(self.y_of(x, 0.0), u), path.upper)])

    def y_of(self, x, t):
        """The time-freezing state of the problem's rows and costs from a node's x = (q, v)
        and time t (the other entries zero)."""
        system = self.problem.system
        n_q = system.cls.n_q
        entries = [ca.SX(0) if isinstance(x, ca.SX) else ca.MX(0)] * system.y.numel()
        for i in range(n_q):
            entries[system.q_index.start + i] = x[i]
            entries[system.v_index.start + i] = x[n_q + i]
        entries[system.clock_index] = t
        return ca.vertcat(*entries)


def bounded_rows(name: str, inputs: list[ca.SX], rows: list[tuple]
                 ) -> tuple[ca.Function, np.ndarray, np.ndarray]:
    """(function of `inputs` stacking the rows' values, lower bounds, upper bounds) of rows
    given as (lower, value, upper) triples, the bounds broadcast to each value's size."""
    values = [ca.reshape(value, -1, 1) for _, value, _ in rows]
    sizes = [v.shape[0] for v in values]
    lower = [np.broadcast_to(np.asarray(lo, dtype=float), n) for (lo, _, _), n
             in zip(rows, sizes, strict=True)]
    upper = [np.broadcast_to(np.asarray(up, dtype=float), n) for (_, _, up), n
             in zip(rows, sizes, strict=True)]
    return (ca.Function(name, inputs, [ca.vertcat(*values)]),
            np.concatenate(lower) if lower else np.zeros(0),
            np.concatenate(upper) if upper else np.zeros(0))


def system_states(system, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The time-freezing states y (n, n_y) of nodes x = (q, v) (n, 2 n_q) at times t (n,)
    (the other entries zero): what the problem's path and terminal rows take."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    n_q = system.cls.n_q
    y = np.zeros((len(x), system.y.numel()))
    y[:, system.q_index] = x[:, :n_q]
    y[:, system.v_index] = x[:, n_q:]
    y[:, system.clock_index] = t
    return y


def bound_violation(values: np.ndarray, lower, upper) -> float:
    """The largest violation of lower <= values <= upper (bounds broadcast along the last
    axis); 0 where every value is within them."""
    values = np.atleast_2d(np.asarray(values, dtype=float))
    lower = np.broadcast_to(np.asarray(lower, dtype=float), values.shape[1:])
    upper = np.broadcast_to(np.asarray(upper, dtype=float), values.shape[1:])
    return float(max(0.0, np.max(lower - values), np.max(values - upper)))


def interpolate(t: np.ndarray, x: np.ndarray, at: float,
                left_limit: bool = False) -> np.ndarray:
    """The samples x (rows at times t) linearly interpolated at `at` (clipped to [t_0, t_n]).
    At a repeated time, an impact's two samples: the later one (the post-impact state), or
    with `left_limit` the earlier one (the state a piece ending at the impact reaches;
    the later one there starts a re-solve's collocation rows off by the velocity jump)."""
    side = "left" if left_limit else "right"
    i = int(np.clip(np.searchsorted(t, at, side=side) - 1, 0, len(t) - 2))
    w = float(np.clip((at - t[i]) / max(t[i + 1] - t[i], 1e-12), 0.0, 1.0))
    return (1 - w) * x[i] + w * x[i + 1]


def ipopt_solver(opti: ca.Opti, plugin: dict, ipopt: dict) -> interrupt.StopOnSignal:
    """`opti.solver("ipopt", plugin, ipopt)` with `StopOnSignal` as IPOPT's iteration
    callback, so that Ctrl-C and SIGTERM end a solve within an iteration: Opti's own
    `opti.callback` replaces that option, and a signal arriving in CasADi's glue is only
    recorded (measured: SIGINT 0.3 s into a 5000-iteration Opti solve with a progress
    callback stopped it after all 5000, 131 s).

    Returns the callback (`report_progress` arms it): keep it for as long as the solver
    (CasADi holds only a borrowed reference)."""
    stop = interrupt.StopOnSignal()
    opti.solver("ipopt", {**plugin, "iteration_callback": stop}, ipopt)
    return stop


def report_progress(stop: interrupt.StopOnSignal) -> None:
    """Progress lines of the next solve with `stop` (`ipopt_solver`): the time its set-up
    took (from now to IPOPT's first iteration), then the objective and the elapsed time as
    `IterationProgress` says (every 250 iterations or each minute)."""
    set_up = time.perf_counter()
    progress = IterationProgress()  # made again at IPOPT's first iteration
    count = 0

    def report() -> None:
        nonlocal progress, count
        if count == 0:
            print(f"    IPOPT started ({time.perf_counter() - set_up:.0f} s setting up its "
                  "solver)", flush=True)
            progress = IterationProgress()  # the lines' seconds count from here
        elif progress.due(count):
            print(f"    iteration {count}: objective {stop.objective:.6g}, "
                  f"{progress.elapsed:.0f} s", flush=True)
        count += 1

    stop.on_iteration = report


def solve_guarded(opti: ca.Opti, threads: int | None):
    """`opti.solve()` with Ctrl-C stopping it (`tfcontact.interrupt.guard`) and IPOPT's BLAS
    on `threads` threads; a failed solve's last iterate (`opti.debug`) instead of
    CasADi's exception."""
    try:
        with interrupt.guard(), blas_threads(threads):
            return opti.solve()
    except RuntimeError:
        return opti.debug


@dataclass(frozen=True)
class NlpTiming:
    """Where a re-solve's time went [s]: `build` (the NLP and its derivatives, before
    IPOPT's first iteration), `ipopt` (IPOPT in all) and, inside it, `evaluations`
    (CasADi's evaluations of the NLP's functions; the rest is IPOPT's own, mostly MUMPS);
    and the NLP's size."""

    build: float
    ipopt: float
    evaluations: float
    n_variables: int
    n_constraints: int

    def summary(self) -> str:
        return (f"{self.n_variables} variables, {self.n_constraints} constraints; build "
                f"{self.build:.1f} s, IPOPT {self.ipopt:.1f} s (evaluations "
                f"{self.evaluations:.1f} s)")


def solve_timed(opti: ca.Opti, threads: int | None) -> tuple[object, float, float, float]:
    """`solve_guarded` and its seconds: (solution, building the solver (Opti builds it
    in its first solve after `opti.solver`), in IPOPT, in CasADi's evaluations). The
    solver must record its time (`record_time`)."""
    begin = time.perf_counter()
    sol = solve_guarded(opti, threads)
    stats = sol.stats()
    in_ipopt = float(stats.get("t_wall_total", 0.0))
    return sol, time.perf_counter() - begin - in_ipopt, in_ipopt, evaluation_seconds(stats)


def shooting_function(rk4: ca.Function, name: str) -> ca.Function:
    """(x, u, h, x_next) -> x_next - rk4(x, u, h): one shooting node's equations, from the
    steps `rk4` (x, u, h) -> x+."""
    x, u = ca.SX.sym("x", rk4.size1_in(0)), ca.SX.sym("u", rk4.size1_in(1))
    h, x_next = ca.SX.sym("h"), ca.SX.sym("x_next", rk4.size1_in(0))
    return ca.Function(name, [x, u, h, x_next], [x_next - rk4(x, u, h)])


def collocation_function(rhs: ca.Function, tableau, name: str) -> ca.Function:
    """(x, z_1, ..., z_s, u, h) -> one collocation element's equations
    (`collocation_residuals` of `rhs` (x, u) -> dx/dt, stacked)."""
    x, u, h = ca.SX.sym("x", rhs.size1_in(0)), ca.SX.sym("u", rhs.size1_in(1)), ca.SX.sym("h")
    stages = [ca.SX.sym(f"z{j}", rhs.size1_in(0)) for j in range(tableau.stages)]
    residuals = collocation_residuals(rhs, tableau, x, stages, u, h)
    return ca.Function(name, [x, *stages, u, h], [ca.vertcat(*residuals)])


def collocation_residuals(rhs, tableau, x, stages, u, h) -> list:
    """The collocation equations of one element from state x over [0, h]:
    z_j - x - h sum_m A_jm rhs(z_m, u), one per stage state z_j (each zero at a solution;
    with Radau IIA the last stage is the element's end). Numbers or CasADi expressions."""
    return collocation_rows(tableau, x, stages, [rhs(z, u) for z in stages], h)


def collocation_rows(tableau, x, stages, slopes, h) -> list:
    """`collocation_residuals` with the stages' slopes given (e.g. (v, a) with the
    accelerations a as variables of the inverse-dynamics form)."""
    return [z - x - h * sum(tableau.A[j, m] * slopes[m] for m in range(len(stages)))
            for j, z in enumerate(stages)]


def spd_solve(matrix: ca.SX, rhs: ca.SX) -> ca.SX:
    """matrix^-1 rhs for a symmetric positive definite SX matrix (a Delassus matrix) by its
    symbolic LDL^T, which needs no pivoting there. With it and M(q)'s sparse LDL^T
    (`solve_mass`) instead of CasADi's symbolic QR (`casadi.solve`), bolt's double-stance
    right-hand side's Hessian took 39.6k instead of 116.6k instructions (benchmarks/legged.md)."""
    d, lt, p = ca.ldl(matrix)
    return ca.ldl_solve(rhs, d, lt, p)


class RepeatedRows:
    """Rows of an Opti problem that one function gives at many places (a shooting step's
    or a collocation element's equations, one per step), recorded as they are added so
    that the solver differentiates each function once and scatters its derivatives
    (`tfcontact.mpcc.derivatives`) instead of differentiating the inlined graph of every
    copy. The values, and so the NLP, are the same; its derivatives agree up to
    round-off (sums in another order)."""

    def __init__(self, opti: ca.Opti) -> None:
        self.opti = opti
        self._groups: dict[int, tuple[ca.Function, list, list]] = {}

    def zero(self, function: ca.Function, *arguments) -> None:
        """Constrain function(*arguments) == 0 (one column output; each argument a column
        of Opti variables, parameters or constants) and record its rows."""
        self.bounded(0.0, function, 0.0, *arguments)

    def bounded(self, lower, function: ca.Function, upper, *arguments) -> None:
        """Constrain lower <= function(*arguments) <= upper and record its rows."""
        value = function(*arguments)
        if np.all(np.asarray(lower) == np.asarray(upper)):
            self.opti.subject_to(value == lower)
        else:
            self.opti.subject_to(self.opti.bounded(lower, value, upper))
        _, calls, values = self._groups.setdefault(id(function), (function, [], []))
        calls.append(arguments)
        values.append(value)

    def _rows(self) -> dict[int, np.ndarray] | None:
        """The rows of g of each recorded value (by the hash of its node), or None if Opti
        laid g out otherwise. (Opti's g stacks the constraints' expressions in order, each
        its value itself for `value == c` and bounds; asking Opti for its row count after
        each constraint instead rebuilds g each time, quadratic in the rows.)"""
        g = self.opti.g
        parts = ([g.dep(i) for i in range(g.n_dep())] if g.is_op(ca.OP_VERTCAT) else [g])
        offsets = np.cumsum([0] + [part.numel() for part in parts])
        if offsets[-1] != self.opti.ng:
            return None
        rows = {hash(part): np.arange(offsets[i], offsets[i + 1])
                for i, part in enumerate(parts)}
        recorded = [hash(v) for _, _, values in self._groups.values() for v in values]
        return rows if all(h in rows for h in recorded) else None

    def derivative_options(self, threads: int = 1) -> dict[str, ca.Function]:
        """nlpsol options `jac_g` and `hess_lag` for the Opti problem as it stands (call
        after its last row and objective); empty (CasADi's own derivatives) if nothing was
        recorded or Opti's rows cannot be matched to the recorded ones."""
        if not self._groups:
            return {}
        opti = self.opti
        rows_of = self._rows()
        if rows_of is None:  # CasADi's own derivatives
            return {}
        x, p = ca.SX.sym("x", opti.nx), ca.SX.sym("p", opti.np)
        f, g = ca.Function("nlp", [opti.x, opti.p], [opti.f, opti.g]).expand()(x, p)
        groups = list(self._groups.values())
        columns = [ca.horzcat(*[ca.vertcat(call[i]) for call in calls])
                   for function, calls, _ in groups for i in range(function.n_in())]
        values = ca.Function("arguments", [opti.x, opti.p], columns).expand()(x, p)
        values = [values] if isinstance(values, ca.SX) else list(values)
        blocks = []
        for function, _, outputs in groups:
            arguments, values = values[:function.n_in()], values[function.n_in():]
            rows = np.array([rows_of[hash(output)] for output in outputs])
            blocks.append(RepeatedBlock(function=function, arguments=tuple(arguments),
                                        rows=rows))
        return repeated_block_derivatives(x, p, f, g, tuple(blocks), threads=threads)
