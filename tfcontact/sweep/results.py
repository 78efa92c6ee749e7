"""A sweep's results: one `CaseResult` per case (its own JSON file) and the `SweepResult`."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tfcontact.errors import TfcontactError, TimeLimitReached
from tfcontact.sweep.spec import GridValue, SweepCase, SweepSpec

if TYPE_CHECKING:
    from tfcontact.plan_format import Trajectory

CASE_FORMAT = 1
"""Version of the case files' layout (`CaseResult.to_dict`)."""

ERROR = "error"
"""The status of a case whose solve raised (the exception's type and message in `failure`)."""
TIME_LIMIT = "time_limit"
"""The status of a case stopped at the sweep's time limit per case (`run_sweep`'s
`case_time_limit`): failed, its start and times recorded, no plan."""


def _start_fields(case: SweepCase, plan: str, task: str, start: Any) -> dict[str, Any]:
    """A record's fields that name its case and its perturbed start (`start` a
    `PerturbedStart`)."""
    return {"case_id": case.case_id, "plan": plan, "task": task, "params": case.params,
            "start": case.start, "seed": case.seed, "offsets": dict(start.offsets),
            "q0": tuple(float(v) for v in start.q0), "v0": tuple(float(v) for v in start.v0)}


def _failed_stage(stages: list[dict], status: str) -> str:
    """The stage whose status the failed plan ended with: the last one that ran and
    reported it (a stage that did not start hands on the status before it; a discovery's
    relaxed plan may report "verification_failed" and its re-solve fail the same way),
    else the last (the collision check, whose own status is the report's)."""
    ran = [s for s in stages if stage_ran(s) and s["status"] == status]
    return ran[-1]["stage"] if ran else stages[-1]["stage"]


def stage_ran(stage: dict) -> bool:
    """Whether a case's stage entry ran (records from before `ran` was kept: unless it
    counted 0 iterations of its own, as a stage that did not start does)."""
    return bool(stage.get("ran", stage.get("iterations", 1) > 0))


class CaseFileError(TfcontactError):
    """A case file is unreadable or belongs to another sweep."""


def _recorded(value: float | None) -> float:
    """A figure as a trajectory records it: NaN when missing or null (the plan format
    writes a non-finite float as null, e.g. the end-state deviation of a replay that
    stopped before T)."""
    return math.nan if value is None else float(value)


@dataclass(frozen=True)
class CaseResult:
    """What one case of a sweep did.

    Attributes:
        case_id, plan, task, params, start, seed: the `SweepCase` (and its sweep's plan).
        offsets: what the perturbation added to the nominal start, by coordinate name.
        q0, v0: the perturbed start state; q_names: the names of q0's entries.
        status: the plan's `ContactResult.status` ("converged", "nlp_failed",
            "not_converged", "verification_failed", "goal_missed", "no_motion"), "error"
            (the solve raised) or "time_limit" (stopped at the sweep's limit per case).
        success: converged and verified (the returned plan: `ContactResult.chosen`).
        first_attempt_success: the first attempt (unperturbed guess) was verified.
        attempts_used: solves made (`ContactSolverOptions.attempts` at most).
        attempt_statuses: each attempt's status.
        iterations: IPOPT iterations over all attempts.
        objective: the returned plan's OCP cost [cost] (nan: none).
        residual: its complementarity residual.
        end_state_deviation: its verification's end-state deviation [state units].
        times: seconds: "build", "solve", "verify" (summed over attempts, as
            `ContactResult.timings`), "wall" (the whole case on its worker, with the
            problem's construction) and "cpu" (its worker process's CPU seconds: on a
            shared machine the wall time also counts the waits for a core).
        failure: why the returned plan failed (None when it succeeded).
        failure_kind: a short class of `failure` for counting ("nlp_failed",
            "verification: end state", ...; None when it succeeded).
        verification: the verification's summary line ("" for an error).
        extra: the draws the feasible start took, each attempt (`Attempt` as a dict), the
            solver settings and the task's goals as measured (`TaskReport.to_dict`).
        trajectory: the case's plan as `tfcontact plan` would write it (a
            `tfcontact.plan_format.Trajectory`: the last stage's plan, failed or not), or
            None (a target without a robot to draw, an error). Not part of the JSON
            record: the sweep writes it beside it (`run_sweep`, `PLANS_FOLDER`).
    """

    case_id: str
    plan: str
    task: str
    params: tuple[tuple[str, GridValue], ...]
    start: int
    seed: int
    offsets: dict[str, float]
    q0: tuple[float, ...]
    v0: tuple[float, ...]
    q_names: tuple[str, ...]
    status: str
    success: bool
    first_attempt_success: bool
    attempts_used: int
    attempt_statuses: tuple[str, ...]
    iterations: int
    objective: float
    residual: float
    end_state_deviation: float
    times: dict[str, float]
    failure: str | None
    failure_kind: str | None
    verification: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    trajectory: Trajectory | None = field(default=None, compare=False, repr=False)

    @property
    def group(self) -> str:
        return SweepCase(self.params, self.start, self.seed).group

    @property
    def wall_time(self) -> float:
        return self.times.get("wall", math.nan)

    @classmethod
    def from_contact(cls, case: SweepCase, plan: str, task: str, start: Any, result: Any,
                     wall_time: float, *, cpu_time: float = math.nan) -> CaseResult:
        """The record of a solved case (`start` a `PerturbedStart`, `result` a
        `ContactResult`, the case's wall and CPU seconds on its worker)."""
        attempts = result.attempts
        failure, kind = (None, None) if result.success else failure_reason(result)
        return cls(
            **_start_fields(case, plan, task, start),
            q_names=tuple(result.problem.system.cls.q_names),
            status=result.status, success=bool(result.success),
            first_attempt_success=bool(attempts) and attempts[0].status == "converged",
            attempts_used=len(attempts),
            attempt_statuses=tuple(a.status for a in attempts),
            iterations=int(sum(a.iterations for a in attempts)),
            objective=float(result.ocp.cost), residual=float(result.ocp.residual),
            end_state_deviation=float(result.verification.end_state_deviation),
            times={**{k: float(result.timings[k]) for k in ("build", "solve", "verify")},
                   "wall": float(wall_time), "cpu": float(cpu_time)},
            failure=failure, failure_kind=kind, verification=result.verification.summary(),
            extra={"draws": start.tries, "attempts": [attempt_record(a) for a in attempts],
                   "options": _options_record(result.options),
                   "task": result.task.to_dict()},
        )

    @classmethod
    def from_stages(cls, case: SweepCase, plan: str, task: str, start: Any,
                    q_names: tuple[str, ...], outcome: Any, stages: list[dict],
                    wall_time: float, *, cpu_time: float = math.nan) -> CaseResult:
        """The record of a case with no discovery (a contact sequence given as data):
        its stages' `PlanOutcome` and entries (`after_stages`), one attempt."""
        return cls(
            **_start_fields(case, plan, task, start),
            q_names=q_names, status=outcome.status, success=bool(outcome.success),
            first_attempt_success=bool(outcome.success), attempts_used=1,
            # an exact plan along its stances: no relaxed complementarity, residual 0
            attempt_statuses=(outcome.status,), iterations=0, objective=math.nan,
            residual=0.0, end_state_deviation=math.nan,
            times={"wall": float(wall_time), "cpu": float(cpu_time)}, failure=None,
            failure_kind=None, extra={"draws": start.tries, "attempts": []},
        ).after_stages(outcome, stages)

    def after_runs(self, earlier: Sequence[Any]) -> CaseResult:
        """This record of a plan's last run (`Plan.whole_attempts`) with the discovery
        solves of the runs before it (their `ContactResult`s) counted first: attempts
        used, their statuses and records (`extra["attempts"]`), IPOPT iterations."""
        attempts = [a for result in earlier for a in result.attempts]
        return dataclasses.replace(
            self, attempts_used=len(attempts) + self.attempts_used,
            attempt_statuses=tuple(a.status for a in attempts) + self.attempt_statuses,
            iterations=sum(a.iterations for a in attempts) + self.iterations,
            extra={**self.extra,
                   "attempts": [attempt_record(a) for a in attempts] + self.extra["attempts"]})

    def after_stages(self, outcome: Any, stages: list[dict]) -> CaseResult:
        """This discovery's record with the outcome of the plan's later stages (a
        `PlanOutcome`, collisions checked): its status, success, cost and end-state
        deviation; the iterations add up; `extra["stages"]` has each stage's name, status,
        iterations and seconds (the discovery's figures stay in `attempts`), `extra["task"]`
        the plan's goals measured, `extra["discovery_task"]` its last discovery's."""
        trajectory = outcome.trajectory
        solver = {} if trajectory is None else trajectory.solver
        verification = {} if trajectory is None else trajectory.verification
        lines = [line.strip() for line in (outcome.summary or "").splitlines() if line.strip()]
        success = bool(outcome.success)
        failure = kind = None
        if not success:
            failing = [line for line in lines if any(
                word in line for word in ("FAILED", "not started", "missed"))]
            # else the line that states the status (a re-solve at IPOPT's cap), not the
            # summary's last line: that was a passed check ("motion: ... ok")
            named = [line for line in lines if outcome.status in line]
            failure = (failing or named or [outcome.status])[-1]
            kind = f"{_failed_stage(stages, outcome.status)}: {outcome.status}"
        return dataclasses.replace(
            self, status=outcome.status, success=success,
            # the whole plan from the discovery's first attempt (whose relaxed plan may
            # fail the reference that the later stage's plan passes)
            first_attempt_success=success and self.attempts_used == 1,
            # the discovery's entry has no iterations: its attempts counted them
            iterations=self.iterations + sum(int(s.get("iterations", 0)) for s in stages),
            objective=_recorded(solver.get("objective")),
            end_state_deviation=_recorded(verification.get("end_state_deviation")),
            failure=failure, failure_kind=kind,
            # the last stage's verdict: its line may carry the stage's prefix
            # ("stances: verification PASSED ...")
            verification=next((line for line in reversed(lines) if any(
                verdict in line for verdict in ("verification PASSED",
                                                "verification FAILED"))), ""),
            # the plan's goals replace the discovery's, which stay beside them (whether a
            # failed re-solve followed a relaxed plan that met the task: benchmarks/sweeps)
            extra={**self.extra, "stages": stages, "task": outcome.task,
                   **({"discovery_task": self.extra["task"]} if "task" in self.extra
                      else {})},
            trajectory=trajectory)

    @classmethod
    def from_error(cls, case: SweepCase, plan: str, task: str, error: BaseException,
                   wall_time: float = math.nan) -> CaseResult:
        """The record of a case whose solve raised `error` (no plan, no start known)."""
        return cls(
            case_id=case.case_id, plan=plan, task=task, params=case.params, start=case.start,
            seed=case.seed, offsets={}, q0=(), v0=(), q_names=(), status=ERROR, success=False,
            first_attempt_success=False, attempts_used=0, attempt_statuses=(), iterations=0,
            objective=math.nan, residual=math.nan, end_state_deviation=math.nan,
            times={"wall": float(wall_time)},
            failure=f"{type(error).__name__}: {error}", failure_kind=f"error: "
            f"{type(error).__name__}")

    @classmethod
    def from_time_limit(cls, case: SweepCase, plan: str, task: str, start: Any,
                        q_names: tuple[str, ...], error: TimeLimitReached, stage: str,
                        wall_time: float, *, cpu_time: float = math.nan) -> CaseResult:
        """The record of a case stopped at its time limit before any solve of it finished
        (`stopped_at`): its start (`start` a `PerturbedStart`) and times, no plan."""
        return cls(
            **_start_fields(case, plan, task, start),
            q_names=q_names, status=TIME_LIMIT, success=False, first_attempt_success=False,
            attempts_used=0, attempt_statuses=(), iterations=0, objective=math.nan,
            residual=math.nan, end_state_deviation=math.nan, times={}, failure=None,
            failure_kind=None, extra={"draws": start.tries, "attempts": []},
        ).stopped_at(error, stage, wall_time, cpu_time=cpu_time)

    def stopped_at(self, error: TimeLimitReached, stage: str, wall_time: float, *,
                   cpu_time: float = math.nan) -> CaseResult:
        """This record (of the discovery solves a case finished, or of none) as the case
        stopped at its time limit `error` in `stage` ("in discovery 2", ...): failed, status
        "time_limit", the case's wall and CPU seconds, the limit in `extra`."""
        return dataclasses.replace(
            self, status=TIME_LIMIT, success=False, first_attempt_success=False,
            times={**self.times, "wall": float(wall_time), "cpu": float(cpu_time)},
            failure=f"{error} ({stage})", failure_kind="time limit",
            extra={**self.extra, "time_limit": error.limit})

    def to_dict(self) -> dict:
        out = asdict(dataclasses.replace(self, trajectory=None))
        del out["trajectory"]  # a file of its own (`run_sweep`), not JSON
        out["params"] = dict(self.params)
        return {"format": CASE_FORMAT, **out}

    @classmethod
    def from_dict(cls, data: dict) -> CaseResult:
        if data.get("format") != CASE_FORMAT:
            raise CaseFileError(f"case format {data.get('format')!r}, expected {CASE_FORMAT}")
        names = {f.name for f in fields(cls)}
        values = {k: v for k, v in data.items() if k in names}
        missing = names - set(values) - {"verification", "extra", "trajectory"}
        if missing:
            raise CaseFileError(f"case record lacks {sorted(missing)}")
        values["params"] = tuple(values["params"].items())
        for key in ("q0", "v0", "q_names", "attempt_statuses"):
            values[key] = tuple(values[key])
        return cls(**values)

    def save(self, folder: Path) -> Path:
        """Write `folder/<case_id>.json` atomically (a stopped write leaves no torn file)."""
        path = folder / f"{self.case_id}.json"
        partial = path.with_suffix(".json.partial")
        partial.write_text(json.dumps(self.to_dict(), indent=1) + "\n")
        os.replace(partial, path)
        return path

    @classmethod
    def load(cls, path: Path, case: SweepCase, plan: str, task: str) -> CaseResult:
        """The record in `path`, checked to be `case`'s of this plan and task."""
        try:
            record = cls.from_dict(json.loads(path.read_text()))
        except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
            raise CaseFileError(f"unreadable case file {path}: {error}") from error
        if (record.plan, record.task, record.params, record.start, record.seed) != (
                plan, task, case.params, case.start, case.seed):
            raise CaseFileError(f"case file {path} holds another case ({record.plan} "
                                f"{record.task}, {dict(record.params)}, start {record.start}, "
                                f"seed {record.seed})")
        return record


def attempt_record(attempt: Any) -> dict[str, Any]:
    """A discovery solve (`tfcontact.ocp.Attempt`) as JSON reads it back: its NLPs a list
    of dicts (`asdict` keeps the tuple, which a round trip through a case file does not)."""
    return {**asdict(attempt), "nlps": [asdict(step) for step in attempt.nlps]}


def _options_record(options: Any) -> dict[str, Any]:
    """The solver settings a case ran with, the ones a grid varies and the restarts."""
    if options is None:
        return {}
    return {"relaxation": options.relaxation.name, "method": repr(options.method),
            "scheme": repr(options.scheme), "n_finite_elements": options.n_finite_elements,
            "attempts": options.attempts, "ipopt_threads": options.nlp.threads}


def failure_reason(result: Any) -> tuple[str, str]:
    """(why, short class) of a failed `ContactResult`: the homotopy's status, the
    verification checks outside their tolerances, or the task's goals it missed."""
    ocp = result.ocp
    if not ocp.success:
        return (f"{result.status}: last IPOPT status {ocp.ipopt_status or 'none'}, "
                f"complementarity residual {ocp.residual:.2e} after {ocp.n_nlps} NLPs"), \
            result.status
    v = result.verification
    task = result.task
    if v.passed and not task.passed:  # the physics held, a goal missed
        missed = [c.line().strip() for c in task.checks if not c.passed]
        return "; ".join(missed) or task.summary(), f"task: {task.status}"
    tol = v.tolerances
    failed = []
    if v.end_state_deviation > tol.get("end_state", math.inf) and not v.open_loop_unstable:
        failed.append(("end state", f"end-state deviation {v.end_state_deviation:.2e} > "
                                    f"{tol['end_state']:.0e}"))
    if v.min_gap < -tol.get("gap", math.inf):
        failed.append(("gap", f"min gap {v.min_gap:.2e} m < -{tol['gap']:.0e}"))
    if not v.clock_monotone or v.clock_end_error > tol.get("clock", math.inf):
        failed.append(("clock", f"clock monotone {v.clock_monotone}, end error "
                                f"{v.clock_end_error:.2e} s"))
    if not failed:  # the cone's tolerance is relative to the plan's largest normal impulse
        failed.append(("cone", f"friction cone {v.friction_cone_violation:.2e} N s or "
                               f"maximal dissipation {v.dissipation_violation:.2e} N s above "
                               f"{tol.get('cone', math.nan):g} x the largest normal impulse"))
    kind = "verification: " + ", ".join(k for k, _ in failed)
    return "; ".join(text for _, text in failed), kind


@dataclass(frozen=True)
class SweepResult:
    """A sweep's outcome: its spec, one `CaseResult` per case and how this run went.

    Attributes:
        spec: the `SweepSpec`.
        out_dir: the sweep folder (`cases/`, `table.md`, `chart.png`, `sweep.json`).
        cases: the records in `spec.cases()` order.
        solved: cases solved by this run; resumed: cases read from their files.
        wall_time: this run's seconds.
        cluster: where the cases ran (e.g. "LocalCluster, 2 workers x 1 thread").
        files: the table and chart written.
        meta: the perturbation ranges, the machine (cores, load averages) and the date.
    """

    spec: SweepSpec
    out_dir: Path
    cases: tuple[CaseResult, ...]
    solved: int
    resumed: int
    wall_time: float
    cluster: str
    files: tuple[Path, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n_success(self) -> int:
        return sum(c.success for c in self.cases)

    @property
    def n_first_attempt(self) -> int:
        return sum(c.first_attempt_success for c in self.cases)

    @property
    def success_rate(self) -> float:
        return self.n_success / len(self.cases) if self.cases else math.nan

    @property
    def first_attempt_rate(self) -> float:
        return self.n_first_attempt / len(self.cases) if self.cases else math.nan

    @property
    def median_wall_time(self) -> float:
        times = [c.wall_time for c in self.cases if math.isfinite(c.wall_time)]
        return float(np.median(times)) if times else math.nan

    def table(self) -> str:
        """The markdown report: overall rates, per grid value, status counts, every case."""
        from tfcontact.sweep.report import markdown

        return markdown(self)

    def summary(self) -> str:
        n = len(self.cases)
        return (f"{self.spec.plan} ({self.spec.task}): {n} cases, verified "
                f"{self.n_success}/{n} ({100 * self.success_rate:.0f} %), at the first attempt "
                f"{self.n_first_attempt}/{n} ({100 * self.first_attempt_rate:.0f} %), median "
                f"wall time {self.median_wall_time:.1f} s; this run solved {self.solved}, "
                f"resumed {self.resumed}")
