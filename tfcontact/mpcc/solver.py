"""Homotopy solution of an MPCC: a sequence of relaxed NLPs solved with IPOPT.

sigma_0 > sigma_1 = kappa sigma_0 > ...; each NLP is warm started from the last
one's solution, and the loop stops when the complementarity residual
max_i |G_i H_i| is at most `tolerance` (DESIGN.md 4.7). The NLP is built once
with sigma (and the MPCC's parameters p) as NLP parameters, so repeated solves
(a simulator stepping through time) pay the build once.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import sys
import time
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from tfcontact import interrupt
from tfcontact.errors import InvalidInput, SolveFailed, optional_positive, positive_int
from tfcontact.mpcc.derivatives import repeated_block_derivatives
from tfcontact.mpcc.problem import Mpcc
from tfcontact.mpcc.relaxation import Relaxation, Scholtes
from tfcontact.native import blas_threads

# IPOPT return statuses that mean the NLP was solved.
_IPOPT_SOLVED = {"Solve_Succeeded", "Solved_To_Acceptable_Level"}

PROGRESS_EVERY = 250
"""A verbose NLP prints a line every this many IPOPT iterations..."""
PROGRESS_SECONDS = 60.0
"""...or when this many seconds [s] have passed since its last line (a 3-D legged NLP
takes more than a second per iteration: 250 of them were six silent minutes)."""


class IterationProgress:
    """When a long NLP should say where it is: `every` iterations or `seconds` after its
    last line (or its start), whichever comes first (`due`, called once per iteration),
    so that a line on the clock is not followed by another a few iterations later."""

    def __init__(self, every: int | None = None, seconds: float | None = None) -> None:
        self.every = PROGRESS_EVERY if every is None else every
        self.seconds = PROGRESS_SECONDS if seconds is None else seconds
        self.start = self.last = time.perf_counter()
        self.last_iteration = 0

    @property
    def elapsed(self) -> float:
        """[s] since it was made."""
        return time.perf_counter() - self.start

    def due(self, iteration: int) -> bool:
        now = time.perf_counter()
        if iteration > 0 and (iteration - self.last_iteration >= self.every
                              or now - self.last >= self.seconds):
            self.last, self.last_iteration = now, iteration
            return True
        return False


@dataclass(frozen=True)
class Homotopy:
    """The homotopy schedule sigma_{k+1} = kappa sigma_k.

    Args:
        sigma_0: first relaxation parameter.
        kappa: reduction factor in (0, 1).
        tolerance: stop when max_i |G_i H_i| <= tolerance.
        max_nlps: at most this many steps of the schedule; by default enough for sigma
            to reach `tolerance`, plus one.
        max_refinements: if IPOPT fails on an NLP, solve again from the last solved NLP's
            solution with sigma halfway (geometrically) between that NLP's sigma and the
            failed one, and from there go on to the failed sigma; at most this many such
            extra NLPs in one homotopy (they do not count against `max_nlps`). A step of
            kappa that is too long for the warm start is thus cut instead of being taken
            from a failed iterate. 0 (the default) keeps the plain schedule: after a
            failure the next sigma starts from the failed NLP's last iterate.
        accept_residual: after a failed NLP (and its refinements), stop the homotopy when
            the last solved NLP's complementarity residual is at most this; the result
            reports that iterate (nlp_failed). For a caller that takes such an iterate as
            it is (the stance re-solve's `discovery_residual` reads its stances from it):
            the NLPs after a failure then only add time unless one recovers. None (the
            default): go on along the schedule.
        stop_residual: stop the homotopy at the first solved NLP whose complementarity
            residual is at most this, a stepping stone solved to `Ipopt.intermediate_tol`
            included; the result reports that iterate (not_converged unless it also meets
            `tolerance`). For a caller that reads only the contact sequence off the iterate
            (a stance re-solve following the discovery): the NLPs after it would tighten a
            relaxed plan that is not kept. None (the default): go on to `tolerance`.
    """

    sigma_0: float = 1.0
    kappa: float = 0.1
    tolerance: float = 1e-9
    max_nlps: int | None = None
    max_refinements: int = 0
    accept_residual: float | None = None
    stop_residual: float | None = None

    def __post_init__(self) -> None:
        if not self.sigma_0 > 0:
            raise InvalidInput(f"`sigma_0` must be positive, got {self.sigma_0}")
        if not 0 < self.kappa < 1:
            raise InvalidInput(f"`kappa` must lie in (0, 1), got {self.kappa}")
        if not self.tolerance > 0:
            raise InvalidInput(f"`tolerance` must be positive, got {self.tolerance}")
        if self.max_nlps is not None and self.max_nlps < 1:
            raise InvalidInput(f"`max_nlps` must be at least 1, got {self.max_nlps}")
        if isinstance(self.max_refinements, bool) or not isinstance(self.max_refinements, int) \
                or self.max_refinements < 0:
            raise InvalidInput(f"`max_refinements` must be a non-negative integer, got "
                               f"{self.max_refinements!r}")
        optional_positive(self.accept_residual, "accept_residual")
        optional_positive(self.stop_residual, "stop_residual")

    @property
    def n_max(self) -> int:
        if self.max_nlps is not None:
            return self.max_nlps
        if self.sigma_0 <= self.tolerance:
            return 1
        return math.ceil(math.log(self.tolerance / self.sigma_0) / math.log(self.kappa)) + 1


LINEAR_SOLVERS = ("mumps", "spral")
"""IPOPT's linear solvers in CasADi's wheel (HSL's ma27, ma57, ... are not in it)."""
BARRIERS = ("adaptive", "monotone")
"""IPOPT's updates of the barrier parameter (`mu_strategy`) a solve can ask for (a task's
`barrier`, a stance re-solve's `StanceOptions.barrier`)."""


@dataclass(frozen=True)
class Ipopt:
    """IPOPT settings.

    Args:
        tol: IPOPT's convergence tolerance.
        max_iter: iterations per NLP.
        print_level: IPOPT's own output, 0 (silent) to 12.
        options: further IPOPT options by name (without the "ipopt." prefix).
        intermediate_tol: if set, the homotopy's NLPs whose sigma lies above the
            homotopy's tolerance are solved only to this tolerance (IPOPT's `tol`,
            `constr_viol_tol` and `compl_inf_tol`): they are stepping stones, and a
            loosely solved one, still inside the interior, warm starts the next NLP in
            far fewer iterations than one driven to the bounds (the hopper's bench task:
            199-253 instead of 561-783 iterations with 0.1). The NLP that meets the
            homotopy's tolerance is always solved to `tol`. Off by default: the plans it
            reaches can be other local solutions, and as the FESD simulator's default it
            failed three time-freezing tests (benchmarks/timefreezing.md).
        element_derivatives: differentiate the MPCC's repeated blocks (the FESD
            elements) once each and scatter them (`tfcontact.mpcc.derivatives`) instead of
            letting CasADi differentiate the whole inlined graph: the hopper's NLP builds
            in 1 s instead of 3.5 s and evaluates as fast. The derivatives are equal up to
            round-off (sums in another order), but a homotopy's iterates then differ by
            round-off too, and round-off decides which local solution some problems
            reach. Off by default, so that the plans measured so far stay as they were;
            the hopper tasks use it.
        threads: threads that evaluate the element derivatives (CasADi's thread map);
            the values do not depend on it.
        blas_threads: threads of IPOPT's linear algebra (MUMPS on CasADi's OpenBLAS)
            during each NLP (`tfcontact.native.blas_threads`; None: as the environment
            sets it, OMP_NUM_THREADS or else the number of cores). IPOPT's path depends on
            the rounding and the rounding on this count: biped-walk-short's discovery
            with 1 thread (OMP_NUM_THREADS=1) took another path to a plan 5.8 cm short of
            its goal in all three attempts; with 2, the count CI tests the plans with on
            its 2-core machines, it converged. Fixed, a plan follows the same path
            whatever the environment and the number of cores; a task measured on another
            count states it (`Task.blas_threads`: quadruped-jump's 1).
        linear_solver: IPOPT's sparse symmetric indefinite solver, one of
            `LINEAR_SOLVERS`: "mumps" (default) or "spral" (STFC's open-source SSIDS, an
            alternative to HSL's solvers, which the wheel lacks; about 5x slower per
            iteration on the monoped, with another homotopy path:
            benchmarks/monoped_settings.md, fifth session).
        warm_start_push: if set, every NLP of the homotopy after the first starts from
            the last NLP's primal-dual solution: its bound and constraint multipliers too,
            not only its variables (IPOPT's `warm_start_init_point`), moved at least this
            far into the interior (`warm_start_bound_push`, `warm_start_mult_bound_push`;
            also `mu_init`). A cold start throws the last NLP's multipliers away: with
            1e-9 the 2-D ball's w = 3 pi plan took 62 + 89 instead of 133 + 196
            iterations in its second and third NLP; but from starts moved by 1e-9 m the
            spread stayed as wide as without (benchmarks/ball_in_box_speed.md), and 1e-6
            or 1e-12 cost more than a cold start there. Off by default: the iterates, and
            with round-off the local solution reached, change.
    """

    tol: float = 1e-10
    max_iter: int = 500
    print_level: int = 0
    options: dict[str, Any] = field(default_factory=dict)
    intermediate_tol: float | None = None
    element_derivatives: bool = False
    threads: int = 1
    blas_threads: int | None = 2
    linear_solver: str = "mumps"
    warm_start_push: float | None = None

    def __post_init__(self) -> None:
        if not self.tol > 0:
            raise InvalidInput(f"`tol` must be positive, got {self.tol}")
        if self.max_iter < 1:
            raise InvalidInput(f"`max_iter` must be at least 1, got {self.max_iter}")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise InvalidInput(
                f"`linear_solver` must be one of {', '.join(map(repr, LINEAR_SOLVERS))} (the "
                f"ones in CasADi's IPOPT build), got {self.linear_solver!r}")
        for key in ("tol", "max_iter", "print_level", "linear_solver"):
            if key in self.options:
                raise InvalidInput(f"give `{key}` as a field of Ipopt, not in `options`")
        if self.intermediate_tol is not None and not (
                math.isfinite(self.intermediate_tol) and self.intermediate_tol >= self.tol):
            raise InvalidInput(f"`intermediate_tol` must be a finite number >= `tol` "
                               f"({self.tol}), or None; got {self.intermediate_tol!r}")
        positive_int(self.threads, "threads")
        if self.blas_threads is not None:
            positive_int(self.blas_threads, "blas_threads")
        if self.warm_start_push is not None:
            if not (isinstance(self.warm_start_push, (int, float))
                    and not isinstance(self.warm_start_push, bool)
                    and 0 < self.warm_start_push < 0.5):
                raise InvalidInput(f"`warm_start_push` must be a number in (0, 0.5), or None; "
                                   f"got {self.warm_start_push!r}")
            for key in ("warm_start_init_point", "warm_start_bound_push",
                        "warm_start_mult_bound_push"):
                if key in self.options:
                    raise InvalidInput(f"`{key}` is set by `warm_start_push`; give it there, "
                                       f"not in `options`")

    def casadi_options(self, intermediate: bool = False,
                       warm: bool = False) -> dict[str, Any]:
        """CasADi's nlpsol options; `intermediate`: those of the homotopy's stepping-stone
        NLPs (`intermediate_tol`); `warm`: those of an NLP warm started from the last
        one's primal-dual solution (`warm_start_push`)."""
        ipopt = {
            "tol": self.tol,
            "max_iter": self.max_iter,
            "print_level": self.print_level,
            "sb": "yes",
            "mu_strategy": "adaptive",
            "mu_oracle": "quality-function",
            "bound_relax_factor": 0.0,
            "acceptable_tol": 1e-6,
        }
        if self.linear_solver != "mumps":  # IPOPT's default: left unset
            ipopt["linear_solver"] = self.linear_solver
        ipopt.update(self.options)
        if intermediate:
            if self.intermediate_tol is None:
                raise InvalidInput("this Ipopt has no `intermediate_tol`")
            loose = self.intermediate_tol
            ipopt.update(tol=loose, constr_viol_tol=loose, compl_inf_tol=loose,
                         acceptable_tol=max(loose, float(ipopt["acceptable_tol"])))
        if warm:
            if self.warm_start_push is None:
                raise InvalidInput("this Ipopt has no `warm_start_push`")
            push = float(self.warm_start_push)
            ipopt.update(warm_start_init_point="yes", warm_start_bound_push=push,
                         warm_start_mult_bound_push=push, mu_init=push)
        # IPOPT's own f, g and multipliers are kept: CasADi's recomputation of them after
        # the solve needs the gradient of the Lagrangian ("nlp_grad"), whose symbolic
        # build took 0.2 s of each solver's 0.25 s on the hopper; nothing here reads lam_p.
        return {"ipopt": ipopt, "print_time": False, "error_on_fail": False,
                "no_nlp_grad": True, "calc_f": False, "calc_g": False,
                "calc_lam_x": False, "calc_lam_p": False}


@dataclass(frozen=True)
class Multipliers:
    """IPOPT's multipliers of an NLP's variable bounds (x) and constraints (g)."""

    x: np.ndarray
    g: np.ndarray


class MpccStatus(enum.Enum):
    """How a homotopy ended."""

    CONVERGED = "converged: the complementarity residual reached the tolerance"
    NOT_CONVERGED = (
        "not converged: the NLPs solved but the complementarity residual stayed above the "
        "tolerance; allow more NLPs (Homotopy.max_nlps), a smaller kappa or another relaxation"
    )
    NLP_FAILED = (
        "NLP failed: IPOPT did not solve the last NLP (see `ipopt_status`); the problem may be "
        "infeasible, or needs a better initial guess, more iterations or a larger sigma_0"
    )


@dataclass(frozen=True)
class HomotopyStep:
    """One NLP of the homotopy. `evaluation_seconds`: the part of `seconds` spent in
    CasADi's function evaluations (objective, constraints, their derivatives); the rest
    is IPOPT's own work, mostly the KKT factorisations. `intermediate`: a stepping stone,
    solved to `Ipopt.intermediate_tol` only. `refined`: an NLP whose sigma lies off the
    schedule, warm started from the last solved NLP after a failure
    (`Homotopy.max_refinements`). `warm_started`: started from the last NLP's multipliers
    too (`Ipopt.warm_start_push`)."""

    sigma: float
    iterations: int
    objective: float
    residual: float
    seconds: float
    ipopt_status: str
    evaluation_seconds: float = 0.0
    intermediate: bool = False
    refined: bool = False
    warm_started: bool = False


@dataclass(frozen=True, eq=False)
class MpccResult:
    """The outcome of a homotopy: last iterate, status and work counters."""

    status: MpccStatus
    w: np.ndarray
    objective: float
    residual: float
    constraint_violation: float
    history: tuple[HomotopyStep, ...]
    build_time: float
    blocks: dict[str, np.ndarray]
    relaxation: str
    lam_g: np.ndarray | None = None

    @property
    def success(self) -> bool:
        return self.status is MpccStatus.CONVERGED

    @property
    def message(self) -> str:
        last = self.history[-1].ipopt_status if self.history else "no NLP solved"
        return (
            f"{self.status.value} (residual {self.residual:.2e}, {self.n_nlps} NLPs, "
            f"{self.total_iterations} IPOPT iterations, last IPOPT status {last})"
        )

    @property
    def ipopt_status(self) -> str:
        return self.history[-1].ipopt_status if self.history else ""

    @property
    def n_nlps(self) -> int:
        return len(self.history)

    @property
    def iterations(self) -> list[int]:
        return [s.iterations for s in self.history]

    @property
    def total_iterations(self) -> int:
        return sum(self.iterations)

    @property
    def nlp_times(self) -> list[float]:
        return [s.seconds for s in self.history]

    @property
    def solve_time(self) -> float:
        return sum(self.nlp_times)

    @property
    def evaluation_time(self) -> float:
        """Seconds of the NLP solves spent in function evaluations (`HomotopyStep`)."""
        return sum(s.evaluation_seconds for s in self.history)

    def value(self, block: str) -> np.ndarray:
        """The solution's entries of a named block of variables."""
        if block not in self.blocks:
            raise InvalidInput(f"no block `{block}`; blocks are {sorted(self.blocks)}")
        return self.w[self.blocks[block]]


class MpccSolver:
    """An MPCC with its relaxed NLP built once; solve it for many parameter values.

    Args:
        mpcc: the problem.
        relaxation: how the complementarity products enter the NLP.
        nlp: IPOPT settings.
    """

    def __init__(self, mpcc: Mpcc, *, relaxation: Relaxation | None = None,
                 nlp: Ipopt | None = None):
        self.mpcc = mpcc
        self.relaxation = relaxation if relaxation is not None else Scholtes()
        self.nlp = nlp if nlp is not None else Ipopt()
        if not isinstance(self.relaxation, Relaxation):
            raise InvalidInput(
                f"`relaxation` must be a Relaxation (Scholtes, L1Penalty, LinfPenalty), "
                f"got {type(self.relaxation).__name__}"
            )
        start = time.perf_counter()
        sigma = ca.SX.sym("sigma")
        products = mpcc.G * mpcc.H
        extra = self.relaxation.terms(products, sigma)
        x = ca.vertcat(mpcc.w, extra.w)
        self._n_w = mpcc.n_w
        self._lbx = np.concatenate([mpcc.lbw, extra.lbw])
        self._ubx = np.concatenate([mpcc.ubw, extra.ubw])
        self._x0_extra = extra.w0
        self._lbg = np.concatenate([mpcc.lbg, extra.lbg])
        self._ubg = np.concatenate([mpcc.ubg, extra.ubg])
        nlp_dict = {
            "x": x,
            "p": ca.vertcat(mpcc.p, sigma),
            "f": mpcc.f + extra.objective,
            "g": ca.vertcat(mpcc.g, extra.g),
        }
        # Ends an NLP at the next iteration after Ctrl-C (tfcontact.interrupt); kept here
        # because CasADi holds only a borrowed reference.
        self._stop_on_signal = interrupt.StopOnSignal()
        options = self.nlp.casadi_options()
        options["iteration_callback"] = self._stop_on_signal
        if self.nlp.element_derivatives and mpcc.repeated:
            options.update(repeated_block_derivatives(
                nlp_dict["x"], nlp_dict["p"], nlp_dict["f"], nlp_dict["g"], mpcc.repeated,
                threads=self.nlp.threads))
        self._solver = ca.nlpsol("mpcc", "ipopt", nlp_dict, options)
        # The same NLP with looser stopping tests (stepping stones, `intermediate_tol`)
        # and/or warm started from multipliers (`warm_start_push`), by (intermediate,
        # warm); they reuse the first solver's derivative functions, so they cost no
        # second symbolic differentiation.
        self._solvers = {(False, False): self._solver}
        for intermediate in ((False, True) if self.nlp.intermediate_tol is not None
                             else (False,)):
            for warm in ((False, True) if self.nlp.warm_start_push is not None
                         else (False,)):
                if (intermediate, warm) == (False, False):
                    continue
                options = self.nlp.casadi_options(intermediate=intermediate, warm=warm)
                options["iteration_callback"] = self._stop_on_signal
                for option, name in (("hess_lag", "nlp_hess_l"), ("jac_g", "nlp_jac_g"),
                                     ("grad_f", "nlp_grad_f")):
                    if self._solver.has_function(name):  # no Hessian with a quasi-Newton one
                        options[option] = self._solver.get_function(name)
                suffix = "_intermediate" * intermediate + "_warm" * warm
                self._solvers[intermediate, warm] = ca.nlpsol(f"mpcc{suffix}", "ipopt",
                                                              nlp_dict, options)
        self._intermediate_solver = self._solvers.get((True, False))
        self._diagnostics = ca.Function(
            "mpcc_diagnostics", [mpcc.w, mpcc.p], [products, mpcc.g, mpcc.f]
        )
        self.build_time = time.perf_counter() - start

    def nlp_function(self, name: str) -> ca.Function:
        """One of the NLP solver's derivative functions ("nlp_hess_l", "nlp_jac_g",
        "nlp_grad_f"), e.g. to see which form builds them."""
        return self._solver.get_function(name)

    def ipopt_stats(self) -> dict[str, Any]:
        """IPOPT's statistics of the last NLP solved to `Ipopt.tol` (CasADi's
        `stats()`: return status, iteration count, `t_wall_nlp_*` evaluation times, ...)."""
        return dict(self._solver.stats())

    @staticmethod
    def _progress_line(nlp: int) -> Any:
        """An `iteration_callback` hook printing where a long NLP is (`IterationProgress`)."""
        progress, count = IterationProgress(), [0]

        def tick() -> None:
            if progress.due(count[0]):
                print(f"      NLP {nlp}: iteration {count[0]}, {progress.elapsed:.0f} s",
                      flush=True)
            count[0] += 1

        return tick

    def _p_value(self, p: np.ndarray | None) -> np.ndarray:
        n_p = self.mpcc.p.numel()
        if p is None:
            if n_p:
                raise InvalidInput(f"this MPCC has {n_p} parameters: pass `p`")
            return np.zeros(0)
        p = np.asarray(p, dtype=float).reshape(-1)
        if p.size != n_p:
            raise InvalidInput(f"`p` has {p.size} entries, expected {n_p}")
        return p

    def diagnostics(self, w: np.ndarray, p: np.ndarray | None = None) -> tuple[float, float, float]:
        """(complementarity residual, constraint violation, objective) at w."""
        products, g, f = self._diagnostics(w, self._p_value(p))
        products = np.abs(np.asarray(products).reshape(-1))
        g = np.asarray(g).reshape(-1)
        residual = float(products.max()) if products.size else 0.0
        violation = 0.0
        if g.size:
            violation = float(max(np.max(self.mpcc.lbg - g), np.max(g - self.mpcc.ubg), 0.0))
        bounds = max(float(np.max(self.mpcc.lbw - w, initial=0.0)),
                     float(np.max(w - self.mpcc.ubw, initial=0.0)))
        return residual, max(violation, bounds), float(f)

    def _solve_nlp(self, x: np.ndarray, lam: Multipliers | None, p: np.ndarray,
                   sigma: float, intermediate: bool
                   ) -> tuple[np.ndarray, Multipliers | None, HomotopyStep, float]:
        """One relaxed NLP from x (and from the multipliers `lam` with `warm_start_push`):
        the new iterate (x and lam kept if IPOPT returned non-finite values), its
        multipliers, the step's record and the MPCC's constraint violation there."""
        warm = self.nlp.warm_start_push is not None and lam is not None
        solver = self._solvers[intermediate, warm]
        args = {"x0": x, "p": np.concatenate([p, [sigma]]), "lbx": self._lbx,
                "ubx": self._ubx, "lbg": self._lbg, "ubg": self._ubg}
        if warm:
            args.update(lam_x0=lam.x, lam_g0=lam.g)
        start = time.perf_counter()
        # Ctrl-C stops IPOPT and the homotopy (tfcontact.interrupt)
        with interrupt.guard(), blas_threads(self.nlp.blas_threads):
            sol = solver(**args)
        seconds = time.perf_counter() - start
        stats = solver.stats()
        x_new = np.asarray(sol["x"]).reshape(-1)
        lam_new = Multipliers(np.asarray(sol["lam_x"]).reshape(-1),
                              np.asarray(sol["lam_g"]).reshape(-1))
        if np.all(np.isfinite(x_new)):
            x = x_new
            if np.all(np.isfinite(lam_new.x)) and np.all(np.isfinite(lam_new.g)):
                lam = lam_new
        residual, violation, objective = self.diagnostics(x[: self._n_w], p)
        evaluations = evaluation_seconds(stats)
        step = HomotopyStep(sigma, int(stats.get("iter_count", 0)), objective, residual,
                            seconds, str(stats.get("return_status", "unknown")), evaluations,
                            intermediate, warm_started=warm)
        return x, lam, step, violation

    def solve(self, p: np.ndarray | None = None, w0: np.ndarray | None = None, *,
              homotopy: Homotopy | None = None, verbose: bool = False,
              feasibility_tol: float = 1e-6) -> MpccResult:
        """Run the homotopy.

        Args:
            p: values of the MPCC's parameters.
            w0: initial guess (default: the MPCC's w0).
            homotopy: the sigma schedule and stopping tolerance.
            verbose: print one line per NLP (sigma, iterations, objective, residual, seconds).
            feasibility_tol: a converged result must satisfy the MPCC's constraints to this
                tolerance; otherwise the status is NLP_FAILED.
        """
        homotopy = homotopy if homotopy is not None else Homotopy()
        p = self._p_value(p)
        w = self.mpcc.w0 if w0 is None else np.asarray(w0, dtype=float).reshape(-1)
        if w.size != self._n_w:
            raise InvalidInput(f"`w0` has {w.size} entries, expected {self._n_w}")
        x = np.concatenate([np.clip(w, self.mpcc.lbw, self.mpcc.ubw), self._x0_extra])
        history: list[HomotopyStep] = []
        sigma = homotopy.sigma_0
        status = MpccStatus.NOT_CONVERGED
        residual = violation = objective = math.inf
        lam: Multipliers | None = None
        if verbose:
            print(f"  {'NLP':>3} {'sigma':>9} {'iter':>5} {'objective':>12} "
                  f"{'residual':>9} {'time[s]':>8}  IPOPT", file=sys.stdout, flush=True)
        # The last NLP that IPOPT solved: if the homotopy ends on a failed NLP, the result
        # reports that iterate rather than the failed one.
        solved_x: np.ndarray | None = None
        solved_lam: Multipliers | None = None
        solved_sigma = solved_residual = math.inf
        target = sigma  # the schedule's sigma_k; `sigma` lies above it after a refinement
        k = refinements = 0
        while k < homotopy.n_max:
            refined = sigma > target * (1 + 1e-9)
            # Stepping stones (sigma above the tolerance) to `Ipopt.intermediate_tol`; one
            # that meets the tolerance anyway is solved again to `tol` at the same sigma.
            stepping_stone = (self._intermediate_solver is not None
                              and sigma > homotopy.tolerance * (1 + 1e-9))
            for intermediate in ((True, False) if stepping_stone else (False,)):
                if verbose:
                    self._stop_on_signal.on_iteration = self._progress_line(len(history) + 1)
                try:
                    x, lam, step, violation = self._solve_nlp(x, lam, p, sigma, intermediate)
                finally:
                    self._stop_on_signal.on_iteration = None
                step = dataclasses.replace(step, refined=refined)
                history.append(step)
                residual, objective = step.residual, step.objective
                if verbose:
                    notes = (f" (to tol {self.nlp.intermediate_tol:.0e})" if intermediate
                             else "") + (" (refined step)" if refined else "")
                    print(f"  {k + 1:>3} {sigma:9.2e} {step.iterations:5d} "
                          f"{objective:12.5e} {residual:9.2e} {step.seconds:8.3f}  "
                          f"{step.ipopt_status}{notes}", flush=True)
                solved = step.ipopt_status in _IPOPT_SOLVED
                if not (intermediate and solved and residual <= homotopy.tolerance):
                    break
            if solved:
                status = MpccStatus.NOT_CONVERGED
                solved_x, solved_lam, solved_sigma = x.copy(), lam, sigma
                solved_residual = residual
                if residual <= homotopy.tolerance and not intermediate:
                    status = MpccStatus.CONVERGED
                    break
                if homotopy.stop_residual is not None and residual <= homotopy.stop_residual:
                    if verbose:
                        print(f"  stopped: NLP {k + 1}'s residual {residual:.2e} is within "
                              f"`stop_residual` = {homotopy.stop_residual:g}", flush=True)
                    break
                if not refined:  # the schedule's step is done
                    k += 1
                    target *= homotopy.kappa
                sigma = target
                continue
            status = MpccStatus.NLP_FAILED
            if refinements < homotopy.max_refinements and solved_x is not None:
                # Cut the step: from the last solved NLP to the geometric midpoint.
                refinements += 1
                x, lam = solved_x.copy(), solved_lam
                sigma = math.sqrt(solved_sigma * sigma)
                continue
            if (homotopy.accept_residual is not None
                    and solved_residual <= homotopy.accept_residual):
                if verbose:
                    print(f"  stopped: NLP {k + 1} failed and the last solved one's residual "
                          f"{solved_residual:.2e} is within `accept_residual` = "
                          f"{homotopy.accept_residual:g}", flush=True)
                break
            # A failed relaxed NLP early in the homotopy often recovers with a smaller
            # sigma, warm started from its own last iterate (measured: restarting from
            # the last solved iterate instead made FESD simulation steps fail).
            k += 1
            target *= homotopy.kappa
            sigma = target
        if status is MpccStatus.NLP_FAILED and solved_x is not None:
            x, lam = solved_x, solved_lam
            residual, violation, objective = self.diagnostics(x[: self._n_w], p)
        if status is MpccStatus.CONVERGED and violation > feasibility_tol:
            status = MpccStatus.NLP_FAILED
        return MpccResult(
            status=status, w=x[: self._n_w].copy(), objective=objective, residual=residual,
            constraint_violation=violation, history=tuple(history),
            build_time=self.build_time, blocks=dict(self.mpcc.blocks),
            relaxation=self.relaxation.name, lam_g=None if lam is None else lam.g,
        )


def solve(mpcc: Mpcc, p: np.ndarray | None = None, *, relaxation: Relaxation | None = None,
          homotopy: Homotopy | None = None, nlp: Ipopt | None = None, verbose: bool = False,
          throw: bool = True) -> MpccResult:
    """Build the relaxed NLP of `mpcc` and run the homotopy once.

    Main args:
        mpcc: the problem; p: its parameter values.

    Other args:
        relaxation: `Scholtes()` (default), `L1Penalty()` or `LinfPenalty()`.
        homotopy: the sigma schedule and tolerance, `Homotopy()` by default.
        nlp: IPOPT settings, `Ipopt()` by default.
        verbose: one progress line per NLP.
        throw: raise `SolveFailed` (carrying the result) unless converged.

    Raises:
        SolveFailed: if `throw` and the homotopy did not converge.
    """
    solver = MpccSolver(mpcc, relaxation=relaxation, nlp=nlp)
    result = solver.solve(p, homotopy=homotopy, verbose=verbose)
    if throw and not result.success:
        raise SolveFailed(result.message, result)
    return result


def evaluation_seconds(stats: dict[str, Any]) -> float:
    """Seconds CasADi spent evaluating an NLP's functions during an IPOPT solve (the
    `t_wall_nlp_*` entries of a solver's `stats()`)."""
    return sum(float(v) for key, v in stats.items() if key.startswith("t_wall_nlp_"))
