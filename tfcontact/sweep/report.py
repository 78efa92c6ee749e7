"""A sweep's markdown table and chart (matplotlib's Agg canvas: no display, no pyplot)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tfcontact.sweep.results import stage_ran
from tfcontact.sweep.spec import GRID_PARAMETERS

if TYPE_CHECKING:
    from tfcontact.sweep.results import CaseResult, SweepResult


def outcome(case: CaseResult) -> str:
    """The class a case is counted in: verified at the first attempt, after restarts, or
    its failure's kind."""
    if case.success:
        return "verified, 1st attempt" if case.first_attempt_success else \
            "verified after restart"
    return case.failure_kind or case.status


def _median(values: Sequence[float], fmt: str) -> str:
    finite = [v for v in values if math.isfinite(v)]
    return format(float(np.median(finite)), fmt) if finite else "-"


def _rate(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else "-"


def _row(label: str, cases: Sequence[CaseResult]) -> str:
    n = len(cases)
    verified = [c for c in cases if c.success]
    return (f"| {label} | {n} | {_rate(len(verified), n)} | "
            f"{_rate(sum(c.first_attempt_success for c in cases), n)} | "
            f"{_median([c.wall_time for c in cases], '.1f')} | "
            f"{_median([c.times.get('cpu', math.nan) for c in cases], '.1f')} | "
            f"{_median([c.iterations for c in cases], '.0f')} | "
            f"{_median([c.objective for c in verified], '.4g')} |")


_HEADER = ("| {} | cases | verified | verified at the 1st attempt | median wall time [s] | "
           "median CPU time [s] | median IPOPT iterations | median cost of the verified |\n"
           "|---|---|---|---|---|---|---|---|")


def by_value(cases: Sequence[CaseResult]) -> dict[str, list[CaseResult]]:
    """The cases by grid value, each key's values in turn ({"all": cases} without a grid)."""
    groups: dict[str, list[CaseResult]] = {}
    for key in GRID_PARAMETERS:
        for c in cases:
            params = dict(c.params)
            if key in params:
                groups.setdefault(GRID_PARAMETERS[key].label(params[key]), []).append(c)
    return groups or {"all": list(cases)}


def by_point(cases: Sequence[CaseResult]) -> dict[str, list[CaseResult]]:
    """The cases by grid point, in their sweep's order."""
    groups: dict[str, list[CaseResult]] = {}
    for c in cases:
        groups.setdefault(c.group, []).append(c)
    return groups


def _runs(runs: Sequence[dict]) -> str:
    """Where and when the cases were solved, with the machine's load (1 min averages)."""
    parts = [f"{r['date']}: {r['solved']} cases on {r['cluster']} in {r['wall_time']:.0f} s"
             + (" (interrupted)" if r.get("interrupted") else "")
             + (f", at most {r['case_time_limit']:g} s each (a case stopped there: "
                "time limit)" if r.get("case_time_limit") else "")
             + f", {r['cores']} cores, load average {r['load_start']:.1f} at the start and "
               f"{r['load_end']:.1f} at the end"
             + (", the workers' " + ", ".join(f"{k}={v}" for k, v in
                                             r["worker_threads"].items())
                if r.get("worker_threads") else "") for r in runs]
    return ("Solved in " + "; ".join(parts) + ".") if parts else ""


def markdown(result: SweepResult) -> str:
    """The sweep's report: setup, rates overall and per grid value, outcomes, every case."""
    spec, cases = result.spec, result.cases
    meta = result.meta
    ranges = ", ".join(f"{name} [{lo:+g}, {hi:+g}]"
                       for name, (lo, hi) in meta.get("perturbation", {}).items())
    grid = "; ".join(f"{k}: {', '.join(str(v) for v in values)}" for k, values in spec.grid)
    lines = [
        f"# Stability sweep: {spec.plan} ({spec.task})",
        "",
        f"{spec.starts} perturbed starts per grid point (seed {spec.seed}; offsets drawn "
        f"uniformly: {ranges or 'none'}), grid: {grid or 'none (the plan as it is)'}. "
        f"IPOPT with {spec.threads_per_case} thread(s) per case. " + _runs(meta.get("runs", [])),
        "A case is *verified* when its plan converged and passed the independent checks "
        "(`ContactResult.success`); *at the 1st attempt* when its first solve (from the "
        "unperturbed guess) did; the plan's later attempts restart from a perturbed guess. "
        "Wall time: the whole case on its worker, all attempts; CPU time: its worker "
        "process's (on a shared machine the wall time also counts the waits for a core)."
        + _stages_text(cases),
        "",
        _HEADER.format(""),
        _row("all", cases),
    ]
    values = by_value(cases)
    if spec.grid:
        lines += ["", "## By grid value", "", _HEADER.format("value"),
                  *[_row(label, group) for label, group in values.items()]]
    points = by_point(cases)
    if len(spec.grid) > 1:
        lines += ["", "## By grid point", "", _HEADER.format("grid point"),
                  *[_row(label, group) for label, group in points.items()]]
    counts = {label: Counter(outcome(c) for c in group) for label, group in points.items()}
    kinds = sorted({k for count in counts.values() for k in count},
                   key=lambda k: (not k.startswith("verified"), k))
    lines += ["", "## Outcomes", "", "| outcome | " + " | ".join(counts) + " |",
              "|---|" + "---|" * len(counts)]
    lines += [f"| {kind} | " + " | ".join(str(count[kind]) for count in counts.values()) + " |"
              for kind in kinds]
    names = next((c.q_names for c in cases if c.q_names), ())
    offsets = [n for n in names if any(n in c.offsets for c in cases)]
    later_stages = any(len(c.extra.get("stages", ())) > 1 for c in cases)
    attempts_header = "attempts" + (", later stages" if later_stages else "")
    lines += ["", "## Cases", "",
              "| case | " + " | ".join(f"d{n}" for n in offsets)
              + f" | status | {attempts_header} | iterations | cost | wall [s] | CPU [s] "
              "| failure |",
              "|---|" + "---|" * (len(offsets) + 7)]
    for c in cases:
        deltas = " | ".join(f"{c.offsets[n]:+.4f}" if n in c.offsets else "-" for n in offsets)
        attempts = " > ".join(c.attempt_statuses) or "-"
        # a discovery's relaxed plan may fail its replay where the stage after it passes:
        # the row says what each later stage ended with
        later = c.extra.get("stages", [])[1:]
        by_run: dict[int, list[str]] = {}  # a plan run again whole: its "run 2: ..."
        for s in later:
            by_run.setdefault(s.get("run", 1), []).append(
                f"{s['stage']} {s['status'] if stage_ran(s) else 'not started'}")
        if later:
            attempts += "; then " + "; ".join((f"run {run}: " if run > 1 else "")
                                              + ", ".join(items)
                                              for run, items in by_run.items())
        failure = (c.failure or "").replace("|", "/")
        lines.append(f"| {c.case_id} | {deltas} | {c.status} | {attempts} | {c.iterations} | "
                     f"{c.objective:.4g} | {c.wall_time:.1f} | "
                     f"{c.times.get('cpu', math.nan):.1f} | {failure} |")
    return "\n".join(lines) + "\n"


def _stages_text(cases: Sequence[CaseResult]) -> str:
    """What a case ran after its discovery, if anything (`CaseResult.after_stages`)."""
    stages = next((c.extra["stages"] for c in cases if c.extra.get("stages")), None)
    if not stages:
        return ""
    if stages[0]["stage"] != "discover":  # a contact sequence given as data
        return (f" Each case ran the plan's stages ({', '.join(s['stage'] for s in stages)})"
                " as `tfcontact plan` does, with no discovery (the contact sequence is given"
                " as data: one solve, no restart): it is verified when its plan is verified,"
                " its task done and it is clear of the terrain.")
    later = [s["stage"] for s in stages[1:] if s.get("run", 1) == 1]
    return (f" Each case also ran the plan's later stages ({', '.join(later)}) as "
            "`tfcontact plan` does: it is verified when the whole plan succeeded (the last "
            "stage's plan verified, its task done, clear of the terrain), and its iterations "
            "count every stage's."
            + (" A case whose plan failed ran the whole plan again, its discovery from a "
               "perturbed guess (`run 2: ...`; the plan's `attempts`), and its attempts "
               "count every discovery." if any(s.get("run", 1) > 1 for c in cases
                                               for s in c.extra.get("stages", ())) else ""))


_MARKERS = {"verified, 1st attempt": ("o", "tab:green"),
            "verified after restart": ("s", "yellowgreen")}


def _starts_map(first, second, cases: Sequence[CaseResult], names: list[str]) -> None:
    """The start offsets, the first perturbed coordinate against the second (and the
    third), marked by outcome over all grid points."""
    pairs = [(names[0], n) for n in names[1:3]] if len(names) > 1 else []
    for ax, pair in zip((first, second), pairs + [None] * 2, strict=False):
        if pair is None:
            ax.set_axis_off()
            continue
        shown = set()
        for c in cases:
            if not all(n in c.offsets for n in pair):
                continue
            kind = outcome(c)
            marker, colour = _MARKERS.get(kind, ("x", "tab:red"))
            label = kind if kind in _MARKERS else "failed"
            ax.plot(c.offsets[pair[0]], c.offsets[pair[1]], marker, color=colour, ms=7,
                    label=None if label in shown else label)
            shown.add(label)
        ax.set_xlabel(f"start offset {pair[0]}")
        ax.set_ylabel(f"start offset {pair[1]}")
        ax.set_title("where the starts failed")
        if shown:
            ax.legend(fontsize=8)


def chart(result: SweepResult, path: Path) -> Path:
    """Six panels: verified rate per grid value (overall and at the 1st attempt), wall
    times and costs per grid point, outcome counts per grid point, and where in the
    perturbation's ranges the starts verified or failed."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cases = result.cases
    values, points = by_value(cases), by_point(cases)
    fig = Figure(figsize=(17, 8.5))
    FigureCanvasAgg(fig)  # Agg without pyplot: no global backend or figure state
    axes = fig.subplots(2, 3)
    ax = axes[0, 0]
    x = np.arange(len(values))
    rates = [100 * sum(c.success for c in g) / len(g) for g in values.values()]
    firsts = [100 * sum(c.first_attempt_success for c in g) / len(g) for g in values.values()]
    ax.bar(x - 0.2, rates, 0.4, label="verified", color="tab:green")
    ax.bar(x + 0.2, firsts, 0.4, label="verified at the 1st attempt", color="tab:olive")
    ax.set_xticks(x, list(values), rotation=20, ha="right")
    ax.set_ylim(0, 105)
    ax.set_ylabel("cases [%]")
    ax.set_title("success rate per grid value")
    ax.legend(loc="lower left", fontsize=8)

    labels = list(points)
    x = np.arange(len(labels))
    rng = np.random.default_rng(0)  # jitter only
    for ax, attr, ylabel, title in (
            (axes[0, 1], "wall_time", "wall time per case [s]", "time distribution"),
            (axes[1, 0], "objective", "cost", "cost distribution (hollow: not verified)")):
        data = [[getattr(c, attr) for c in points[label]
                 if math.isfinite(getattr(c, attr))] for label in labels]
        filled = [i for i, d in enumerate(data) if d]
        if filled:
            ax.boxplot([data[i] for i in filled], positions=filled, widths=0.5,
                       showfliers=False)
        for i, label in enumerate(labels):
            for c in points[label]:
                value = getattr(c, attr)
                if not math.isfinite(value):
                    continue
                ax.plot(i + rng.uniform(-0.15, 0.15), value, "o", ms=5,
                        mfc="tab:green" if c.success else "none",
                        mec="tab:green" if c.success else "tab:red")
        ax.set_xticks(x, labels, rotation=20, ha="right")
        ax.set_ylabel(ylabel)
        ax.set_title(title)

    ax = axes[1, 1]
    counts = {label: Counter(outcome(c) for c in points[label]) for label in labels}
    kinds = sorted({k for count in counts.values() for k in count},
                   key=lambda k: (not k.startswith("verified"), k))
    bottom = np.zeros(len(labels))
    # greens for the verified, the other tab10 colours (no green) for the failure kinds
    failures = iter([colormaps["tab10"](j) for j in (3, 1, 4, 5, 6, 7, 0, 8, 9)] * 3)
    colours = {"verified, 1st attempt": "tab:green", "verified after restart": "yellowgreen"}
    for kind in kinds:
        heights = np.array([counts[label][kind] for label in labels], dtype=float)
        colour = colours[kind] if kind in colours else next(failures)
        ax.bar(x, heights, 0.6, bottom=bottom, label=kind, color=colour)
        bottom += heights
    ax.set_xticks(x, labels, rotation=20, ha="right")
    ax.set_ylabel("cases")
    ax.set_title("what failed and why")
    ax.legend(fontsize=8)
    _starts_map(axes[0, 2], axes[1, 2], cases, list(result.meta.get("perturbation", {})))
    spec = result.spec
    fig.suptitle(f"{spec.plan} ({spec.task}): {len(cases)} cases, {spec.starts} perturbed "
                 f"starts per grid point; verified {result.n_success}, at the 1st attempt "
                 f"{result.n_first_attempt}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path
