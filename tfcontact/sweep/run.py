"""Run a sweep's cases as Dask tasks, each case's record saved as it finishes."""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import signal
import sys
import time
import uuid
from abc import ABC, abstractmethod
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from tfcontact import interrupt
from tfcontact.errors import InvalidInput, TimeLimitReached, optional_positive, positive_int
from tfcontact.mpcc import Ipopt
from tfcontact.sweep.report import chart
from tfcontact.sweep.results import ERROR, TIME_LIMIT, CaseFileError, CaseResult, SweepResult
from tfcontact.sweep.spec import GRID_PARAMETERS, SweepCase, SweepSpec
from tfcontact.sweep.targets import SweepTarget

SWEEP_FILE = "sweep.json"
CASES_FOLDER = "cases"
PLANS_FOLDER = "plans"
"""Each case's plan as a trajectory file, `plans/<case_id>.npz` + `.json` (what
`tfcontact plan` writes as trajectory.npz: `tfcontact replay` and `check` read it), so a
failed case can be examined without solving it again."""
# What a resumed sweep must share with the one that wrote the folder: its cases' starts
# and solver setup. The grid and the number of starts may grow.
_SAME = ("plan", "task", "seed", "threads_per_case", "perturbation", "target")


def with_case_threads(nlp: Ipopt, threads: int) -> Ipopt:
    """IPOPT's settings for a case run on `threads` threads: the element derivatives on
    that many, the BLAS on at most that many and no more than the task states (a task's
    `blas_threads` is the count its discovery was measured on; quadruped-jump's 1 keeps
    it on the path where its homotopy converges)."""
    stated = threads if nlp.blas_threads is None else nlp.blas_threads
    return dataclasses.replace(nlp, threads=threads, blas_threads=min(stated, threads))


def solve_case(target: SweepTarget, task: str, case: SweepCase, threads: int,
               time_limit: float | None = None) -> CaseResult:
    """Solve one case (on a worker): build the plan with the case's grid point, draw its
    perturbed start, solve and verify it with `solve_contact`, then run the plan's later
    stages on that outcome and check its collisions as `tfcontact plan` does. With
    `time_limit` [s] the case stops at the first IPOPT iteration past it
    (`tfcontact.interrupt.time_limit`), recorded with status "time_limit" and what it had
    done by then (its discovery solves, which stage it was in)."""
    started, cpu = time.perf_counter(), time.process_time()
    progress = _CaseProgress()
    try:
        with interrupt.time_limit(time_limit):
            return _solve_case(target, task, case, threads, progress, started, cpu)
    except TimeLimitReached as error:
        if progress.start is None:  # stopped before its start was drawn: no IPOPT there
            raise
        wall, cpu_time = time.perf_counter() - started, time.process_time() - cpu
        solved = progress.discoveries
        if not solved:
            return CaseResult.from_time_limit(case, target.name, task, progress.start,
                                              progress.q_names, error, progress.stage, wall,
                                              cpu_time=cpu_time)
        return CaseResult.from_contact(
            case, target.name, task, progress.start, solved[-1], wall, cpu_time=cpu_time,
        ).after_runs(solved[:-1]).stopped_at(error, progress.stage, wall, cpu_time=cpu_time)


@dataclass
class _CaseProgress:
    """How far a case got (what `solve_case` records of a case stopped at its limit)."""

    start: Any = None
    q_names: tuple[str, ...] = ()
    discoveries: list = dataclasses.field(default_factory=list)
    stage: str = "in its discovery"


def _solve_case(target: SweepTarget, task: str, case: SweepCase, threads: int,
                progress: _CaseProgress, started: float, cpu: float) -> CaseResult:
    """`solve_case`'s solve, telling `progress` how far it got."""
    from tfcontact.ocp.contact import solve_contact

    problem_params = {k: v for k, v in case.params if GRID_PARAMETERS[k].level == "problem"}
    setup = target.setup(task, problem_params)
    options = setup.options
    for key, value in case.params:
        if GRID_PARAMETERS[key].level == "options":
            options = GRID_PARAMETERS[key].apply(options, value)
    options = dataclasses.replace(options, nlp=with_case_threads(options.nlp, threads))
    rng = np.random.default_rng([case.seed, case.start])
    start = target.perturbation(setup).sample(setup.problem, rng)
    problem = target.from_start(setup, task, problem_params, start)
    progress.start, progress.q_names = start, tuple(problem.system.cls.q_names)
    given = target.given_sequence(task)
    if given is not None:  # no discovery: the sequence's solve from the perturbed start
        progress.stage = f"in its {given.name}"
        moved = dataclasses.replace(setup, problem=problem, options=options)
        stage = dataclasses.replace(given, build=lambda _: moved).with_threads(threads)
        outcome, stage_times = run_later_stages(target.name, task, (stage,), None)
        return CaseResult.from_stages(case, target.name, task, start,
                                      tuple(problem.system.cls.q_names), outcome,
                                      stage_times, time.perf_counter() - started,
                                      cpu_time=time.process_time() - cpu)
    from tfcontact.scenes.pipeline import discovery_outcome

    # a continued discovery's own task is stated from the case's start too
    stages = tuple(s.at_start(start.q0, start.v0).with_threads(threads)
                   for s in target.later_stages(task))
    discovered = target.discovery_problem(task, problem)
    if not stages:
        result = solve_contact(discovered, options, verbose=False)
        record = CaseResult.from_contact(case, target.name, task, start, result,
                                         time.perf_counter() - started,
                                         cpu_time=time.process_time() - cpu)
        if setup.robot is None:  # a point mass of a reference problem: nothing to draw
            return record
        solved = discovery_outcome(result, dataclasses.replace(setup, problem=problem))
        return dataclasses.replace(record, trajectory=solved.trajectory)
    from tfcontact.scenes.plans import run_whole

    runs = target.whole_attempts(task)
    if runs is not None:  # as `tfcontact plan`: each run's discovery one seeded solve
        options = dataclasses.replace(options, attempts=1)
    results = progress.discoveries

    def run_once(seed: int) -> tuple:
        began = time.perf_counter()
        progress.stage = f"in discovery {len(results) + 1}"
        result = solve_contact(discovered, options, first_seed=seed, verbose=False)
        results.append(result)
        progress.stage = (f"in the stages after discovery {len(results)} "
                          f"({result.status}): {', '.join(s.name for s in stages)}")
        found = discovery_outcome(result, dataclasses.replace(setup, problem=problem))
        entry = {"stage": "discover", "status": result.status, "ran": True,
                 "seconds": time.perf_counter() - began}
        outcome, stage_times = run_later_stages(target.name, task, stages, found)
        return outcome, [entry, *stage_times], None, None

    outcome, stage_times, _, _ = run_whole(runs or 1, run_once, plan=target.name, task=task)
    record = CaseResult.from_contact(case, target.name, task, start, results[-1],
                                     time.perf_counter() - started,
                                     cpu_time=time.process_time() - cpu)
    return record.after_runs(results[:-1]).after_stages(outcome, stage_times)


def run_later_stages(plan: str, task: str, stages, outcome) -> tuple[Any, list[dict]]:
    """The outcome of a plan's `stages` after its discovery (whose `PlanOutcome` is
    `outcome`; None: the stages start the plan), collisions checked, and each stage's
    entry (`tfcontact.scenes.plans.run_checked`, as `tfcontact plan` runs them)."""
    import tempfile

    from tfcontact.scenes.plans import run_checked

    with tempfile.TemporaryDirectory(prefix="tfcontact-case-") as out:
        outcome, times, _, _ = run_checked(plan, task, stages, Path(out), outcome=outcome)
    return outcome, times


class Progress(ABC):
    """What a sweep tells as it runs (strategy: lines, nothing, or a test's hook).

    `heartbeat` [s]: while no case finishes, `running` is told this often (a solo12 case
    runs 11 minutes or more: without it a sweep is silent that long)."""

    heartbeat: float = 60.0

    @abstractmethod
    def started(self, total: int, pending: int, cluster: str) -> None:
        """Before the first case: `total` cases, `pending` of them to solve."""

    @abstractmethod
    def finished(self, record: CaseResult, done: int, pending: int, elapsed: float) -> None:
        """A case's record was saved: `done` of `pending` solved in `elapsed` seconds."""

    @abstractmethod
    def note(self, text: str) -> None:
        """Something the user should know (a case file re-solved, ...)."""

    def running(self, done: int, pending: int, elapsed: float) -> None:  # noqa: B027
        """No case finished for `heartbeat` seconds: `done` of `pending` solved so far."""


class Silent(Progress):
    def started(self, total: int, pending: int, cluster: str) -> None:
        pass

    def finished(self, record: CaseResult, done: int, pending: int, elapsed: float) -> None:
        pass

    def note(self, text: str) -> None:
        pass


class ProgressLines(Progress):
    """One line per finished case with the counts so far and the time left (log-friendly,
    unlike a redrawn bar)."""

    def __init__(self, stream: TextIO | None = None, heartbeat: float = Progress.heartbeat):
        self.stream = stream
        self.verified = 0
        self.heartbeat = heartbeat

    def _print(self, text: str) -> None:
        print(text, file=self.stream or sys.stdout, flush=True)

    def started(self, total: int, pending: int, cluster: str) -> None:
        resumed = total - pending
        self._print(f"sweep: {total} cases, {resumed} done before, {pending} to solve on "
                    f"{cluster}")

    def finished(self, record: CaseResult, done: int, pending: int, elapsed: float) -> None:
        self.verified += record.success
        offsets = ", ".join(f"{k} {v:+.3f}" for k, v in record.offsets.items())
        how = (f"attempt {record.attempts_used}" if record.success else
               (record.failure_kind or record.status))
        left = elapsed / done * (pending - done)
        width = len(str(pending))
        self._print(f"[{done:{width}d}/{pending}] {record.case_id} ({offsets}): "
                    f"{record.status} ({how}), {record.iterations} it, "
                    f"{record.wall_time:.1f} s (CPU {record.times.get('cpu', 0.0):.1f} s) | "
                    f"verified {self.verified}/{done}, "
                    f"{elapsed:.0f} s elapsed, ~{left:.0f} s left")

    def note(self, text: str) -> None:
        self._print(f"sweep: {text}")

    def running(self, done: int, pending: int, elapsed: float) -> None:
        self._print(f"sweep: {done}/{pending} solved, the others running or queued, "
                    f"{elapsed:.0f} s elapsed")


def run_sweep(spec: SweepSpec, out_dir: Path | str, *, scheduler: str | None = None,
              n_workers: int = 2, progress: bool | Progress = True,
              case_time_limit: float | None = None) -> SweepResult:
    """Run every case of `spec` as a Dask task and write the sweep folder.

    Each case's `CaseResult` is saved as `out_dir/cases/<case_id>.json` as soon as it
    finishes, its plan (when the target has a robot to draw) as the trajectory file
    `out_dir/plans/<case_id>.npz` just before, so a stopped sweep loses only the cases
    running; a rerun on the same folder solves only the cases without a file (and those
    whose solve raised, status "error", and those stopped at a smaller `case_time_limit`).
    At the end `table.md` (`SweepResult.table`) and `chart.png` are written from all the
    spec's case files.

    Main args:
        spec: the `SweepSpec`.
        out_dir: the sweep folder (created; one folder per sweep).

    Other args:
        scheduler: the address of a running Dask scheduler ("tcp://host:8786"), whose
            workers have tfcontact installed; default: a `distributed.LocalCluster` of
            `n_workers` processes with one thread each, closed at the end.
        n_workers: the LocalCluster's processes (one case each at a time).
        progress: a line per finished case (True), none (False) or a `Progress`.
        case_time_limit: wall-clock seconds per case; a case still solving then stops at
            its next IPOPT iteration and is recorded as failed with status "time_limit"
            (`tfcontact.interrupt.time_limit`): a case that runs to its iteration caps can
            otherwise take an hour. None (default): no limit. Each run of the folder
            records its limit in the sweep file.

    Returns:
        The `SweepResult`.

    Raises:
        InvalidInput: a bad argument, or `out_dir` holds a sweep of another plan, task,
            seed, thread count or perturbation.
        KeyboardInterrupt: on Ctrl-C, after cancelling the cases still running and
            closing the cluster; the finished cases' files stay for a rerun.
    """
    if not isinstance(spec, SweepSpec):
        raise InvalidInput(f"`spec` must be a SweepSpec, got {type(spec).__name__}")
    positive_int(n_workers, "n_workers")
    optional_positive(case_time_limit, "case_time_limit")
    if scheduler is not None and not (isinstance(scheduler, str) and scheduler):
        raise InvalidInput(f"`scheduler` must be an address such as 'tcp://host:8786', "
                           f"got {scheduler!r}")
    reporter = progress if isinstance(progress, Progress) else (
        ProgressLines() if progress else Silent())
    began = time.perf_counter()
    target = spec.target
    perturbation = target.perturbation(target.setup(spec.task, {}))
    out = Path(out_dir)
    cases_dir = out / CASES_FOLDER
    header = {**spec.to_dict(), "perturbation": perturbation.to_dict(),
              "target": target.description()}
    runs = _previous_runs(out / SWEEP_FILE, header)

    records: dict[str, CaseResult] = {}
    pending: list[SweepCase] = []
    for case in spec.cases():
        path = cases_dir / f"{case.case_id}.json"
        if not path.exists():
            pending.append(case)
            continue
        try:
            record = CaseResult.load(path, case, spec.plan, spec.task)
        except CaseFileError as error:
            reporter.note(f"solving {case.case_id} again: {error}")
            pending.append(case)
            continue
        if record.status == ERROR:
            pending.append(case)  # a crash may not repeat (a worker killed, ...)
        elif record.status == TIME_LIMIT and (
                case_time_limit is None
                or case_time_limit > record.extra.get("time_limit", math.inf)):
            pending.append(case)  # more time now than it was stopped at
        else:
            records[case.case_id] = record
    resumed = len(records)

    cluster = (f"the scheduler at {scheduler}" if scheduler is not None else
               f"a LocalCluster of {n_workers} worker processes x 1 thread")
    reporter.started(len(spec.cases()), len(pending), cluster if pending else "nothing")
    solved: list[CaseResult] = []
    if pending:
        # Connected (or the cluster started) before the folder is written: a bad address
        # leaves no trace.
        with _client(scheduler, n_workers) as client:
            cases_dir.mkdir(parents=True, exist_ok=True)
            run = {"date": _now(), "cluster": cluster, "cores": os.cpu_count(),
                   "load_start": round(os.getloadavg()[0], 2),
                   "worker_threads": worker_threads(client),
                   "case_time_limit": case_time_limit}
            try:
                _solve(client, pending, spec, target, reporter, cases_dir, solved,
                       case_time_limit)
            finally:  # also when interrupted: the folder tells which runs made its cases
                run.update(solved=len(solved), interrupted=len(solved) < len(pending),
                           wall_time=round(time.perf_counter() - began, 1),
                           load_end=round(os.getloadavg()[0], 2))
                runs.append(run)
                _write_json(out / SWEEP_FILE, {**header, "runs": runs})
    else:
        _write_json(out / SWEEP_FILE, {**header, "runs": runs})
    records.update((r.case_id, r) for r in solved)

    cases = tuple(records[c.case_id] for c in spec.cases())
    meta = {"perturbation": perturbation.to_dict(), "runs": runs}
    result = SweepResult(spec=spec, out_dir=out, cases=cases, solved=len(solved),
                         resumed=resumed, wall_time=time.perf_counter() - began,
                         cluster=cluster if pending else "nothing (every case done before)",
                         meta=meta)
    table = out / "table.md"
    table.write_text(result.table())
    figure = chart(result, out / "chart.png")
    return dataclasses.replace(result, files=(table, figure))


def _now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")


def _write_json(path: Path, data: dict) -> None:
    partial = path.with_suffix(".json.partial")
    partial.write_text(json.dumps(data, indent=1) + "\n")
    os.replace(partial, path)


def _previous_runs(path: Path, header: dict) -> list[dict]:
    """The runs recorded in the folder's sweep file, after checking that it is the same
    sweep (`_SAME`); none for a new folder."""
    if not path.exists():
        return []
    try:
        before = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise InvalidInput(f"{path} is unreadable ({error}); remove it or choose another "
                           "folder") from error
    # A sweep file from before targets described themselves: the target's defaults then.
    differ = [k for k in _SAME if before.get(k, {} if k == "target" else None) != header[k]]
    if differ:
        shown = "; ".join(f"{k}: {before.get(k)!r} there, {header[k]!r} here" for k in differ)
        raise InvalidInput(f"{path.parent} holds another sweep ({shown}); choose another "
                           "folder (--out) or remove it")
    return list(before.get("runs", []))


def _ignore_interrupts() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _client(scheduler: str | None, n_workers: int) -> Iterator[Any]:
    """A `distributed.Client` of a new LocalCluster (closed at the end) or of `scheduler`."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s")
        except OSError as error:  # includes the connection's timeout
            raise InvalidInput(f"no Dask scheduler answers at {scheduler} ({error}); start "
                               "one (`dask scheduler`) with workers that have tfcontact "
                               "installed (`dask worker ADDRESS --nthreads 1`)") from error
        try:
            yield client
        finally:
            client.close()
        return
    # The scheduler's HTTP server (the dashboard with bokeh) on any free port: two sweeps
    # at once would otherwise both claim 8787 (the second with a warning).
    # Starting the workers sets OMP_NUM_THREADS=1 and the like in this process's
    # environment too, where a solver library loaded later would take them up and round
    # differently (a stance re-solve then ended 4e-3 from its replay instead of 1e-6):
    # the caller gets its environment back.
    saved = dict(os.environ)
    try:
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
        try:
            # Ctrl-C in a terminal reaches the whole process group: the workers leave it
            # to this process, which cancels the cases and closes them (no tracebacks).
            client.run(_ignore_interrupts)
            yield client
        finally:
            client.close()
            cluster.close()
    finally:
        _restore_environment(saved)


def _restore_environment(saved: dict[str, str]) -> None:
    for name in [n for n in os.environ if n not in saved]:
        del os.environ[name]
    os.environ.update({n: v for n, v in saved.items() if os.environ.get(n) != v})


THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""The environment that sets the threads of a worker's linear algebra: IPOPT's path
depends on the rounding, so a sweep's table says what its workers had."""


def _thread_environment() -> dict[str, str]:
    return {n: os.environ.get(n, "unset") for n in THREAD_VARIABLES}


def worker_threads(client: Any) -> dict[str, str]:
    """The workers' `THREAD_VARIABLES` (values that differ between workers joined by
    '/'), as Dask started them: a LocalCluster's workers get 1 for each."""
    seen = list(client.run(_thread_environment).values())
    return {n: "/".join(sorted({env[n] for env in seen})) for n in THREAD_VARIABLES}


def _as_finished(futures: list, reporter: Progress, began: float) -> Iterator[Any]:
    """`futures` as they finish; `reporter.running` whenever none finishes for its
    `heartbeat` seconds."""
    from distributed import wait

    remaining, done = list(futures), 0
    while remaining:
        try:
            finished, _ = wait(remaining, timeout=reporter.heartbeat,
                               return_when="FIRST_COMPLETED")
        except TimeoutError:
            reporter.running(done, len(futures), time.perf_counter() - began)
            continue
        for future in [f for f in remaining if f in finished]:  # in submission order
            remaining.remove(future)
            done += 1
            yield future


def _solve(client: Any, pending: list[SweepCase], spec: SweepSpec, target: SweepTarget,
           reporter: Progress, cases_dir: Path, solved: list[CaseResult],
           time_limit: float | None) -> None:
    """Solve the pending cases (each within `time_limit` [s], None: none), saving,
    reporting and appending to `solved` each record as it finishes; on any exit the
    cases still running are cancelled."""
    futures = []
    try:
        token = uuid.uuid4().hex[:8]
        futures = [client.submit(solve_case, target, spec.task, case, spec.threads_per_case,
                                 time_limit, key=f"sweep-{token}-{case.case_id}", pure=False)
                   for case in pending]
        by_key = {f.key: case for f, case in zip(futures, pending, strict=True)}
        began = time.perf_counter()
        for done, future in enumerate(_as_finished(futures, reporter, began), start=1):
            case = by_key[future.key]
            error = future.exception()
            if error is None:
                record = future.result()
            else:  # the case raised on its worker (or the worker died): record why
                record = CaseResult.from_error(case, spec.plan, spec.task, error)
            future.release()
            if record.trajectory is not None:
                # before the record, whose file marks the case done: a sweep stopped
                # between the two solves the case again and writes both
                from tfcontact.plan_format import save_trajectory

                plans_dir = cases_dir.parent / PLANS_FOLDER
                plans_dir.mkdir(exist_ok=True)
                save_trajectory(plans_dir / f"{record.case_id}.npz", record.trajectory)
                record = dataclasses.replace(record, trajectory=None)
            record.save(cases_dir)
            solved.append(record)
            reporter.finished(record, done, len(pending), time.perf_counter() - began)
    finally:
        # Also on Ctrl-C: stop what still runs; the saved case files stay for a rerun.
        unfinished = [f for f in futures if not f.done()]
        if unfinished:
            client.cancel(unfinished)
