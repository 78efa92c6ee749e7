"""The `tfcontact sweep` sub-command (`add_sweep_parser`)."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from tfcontact.errors import InvalidInput
from tfcontact.sweep.spec import GRID_PARAMETERS, SweepSpec

EXIT_OK, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 2, 130

# The grid's command-line options: --friction, --a-n, --relaxation, --scheme.
_OPTIONS = {key: "--" + key.replace("_", "-") for key in GRID_PARAMETERS}


def add_sweep_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add `sweep` to `subparsers` (what `ArgumentParser.add_subparsers()` returns).

    Its `func(args)` returns the exit code: 0 when the sweep ran (whatever its cases'
    outcomes), 2 for bad input, 130 when interrupted (the finished cases stay saved: the
    same command resumes)."""
    parser = subparsers.add_parser(
        "sweep", help="solve a plan from many perturbed starts (and a parameter grid) on Dask",
        description="Stability sweep: solve PLAN from --starts seeded perturbed starts at "
                    "every point of the parameter grid, as Dask tasks; each case is saved as "
                    "OUT/cases/<case>.json as it finishes (a rerun skips them), then "
                    "OUT/table.md and OUT/chart.png are written.")
    parser.add_argument("plan", help="the plan: hopper, particle (TF-3), another plan of "
                                     "`tfcontact plan --list` that starts with a discovery "
                                     "(its later stages run too) or solves along a given "
                                     "contact sequence, or a task file")
    parser.add_argument("--task", default=None,
                        help="the plan's task (default its first; hopper: short, long, "
                             "bench; particle: tf3, reduced)")
    parser.add_argument("--starts", type=int, default=20,
                        help="perturbed starts per grid point (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the perturbations")
    for key, parameter in GRID_PARAMETERS.items():
        parser.add_argument(_OPTIONS[key], dest=key, nargs="+", default=None,
                            metavar="VALUE", help=f"grid values: {parameter.help}")
    parser.add_argument("--out", default=None, help="the sweep folder (default out/sweeps/PLAN)")
    parser.add_argument("--scheduler", default=None,
                        help="a running Dask scheduler, tcp://host:port (its workers need "
                             "tfcontact); default: a local cluster")
    parser.add_argument("--workers", type=int, default=2,
                        help="the local cluster's worker processes, one case each (default 2)")
    parser.add_argument("--threads", type=int, default=1,
                        help="IPOPT's threads in each case, element derivatives and BLAS "
                             "(default 1: one case per core); `--workers 1 --threads 2` "
                             "runs each case as `tfcontact plan` does on 2 cores, on its "
                             "rounding path")
    parser.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                        help="wall-clock seconds per case: a case still solving then stops "
                             "and is recorded as failed with status time_limit (a rerun "
                             "with a larger limit solves it again); default none")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    parser.set_defaults(func=sweep_command)
    return parser


def sweep_command(args: argparse.Namespace) -> int:
    """Run `tfcontact sweep` from parsed arguments; returns the exit code."""
    from tfcontact.sweep.run import run_sweep

    grid = {key: getattr(args, key) for key in GRID_PARAMETERS
            if getattr(args, key) is not None}
    out = Path(args.out) if args.out else Path("out") / "sweeps" / args.plan
    try:
        spec = SweepSpec(plan=args.plan, starts=args.starts, task=args.task, seed=args.seed,
                         grid=grid, threads_per_case=args.threads)
        result = run_sweep(spec, out, scheduler=args.scheduler, n_workers=args.workers,
                           progress=not args.quiet, case_time_limit=args.time_limit)
    except InvalidInput as error:
        print(f"tfcontact sweep: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        # distributed's own cancelled callback then logs a NameError traceback through
        # tornado (distributed 2026.8, utils.sync): noise after a clean stop
        logging.getLogger("tornado.application").setLevel(logging.CRITICAL)
        print(f"tfcontact sweep: interrupted; the finished cases are saved in {out}/cases, "
              "the same command resumes the sweep", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(result.summary())
    for path in result.files:
        print(f"  {path}")
    return EXIT_OK
