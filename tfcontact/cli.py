"""The `tfcontact` command: plan, replay.

    tfcontact plan --list
    tfcontact plan hopper --out DIR [--task long] [--attempts N] [--time-limit S] [--force]
    tfcontact plan monoped --out DIR [--task reduced|hand-set]
    tfcontact replay DIR/trajectory.npz [--html OUT] [--open]
    tfcontact check DIR/trajectory.npz
    tfcontact sweep hopper --starts 20 [--friction 0.5 0.8] [--scheduler ADDRESS]

Exit codes (`EXIT_CODES`): 0 plan verified (or command done), 1 plan failed (solver or
verification; the reason is printed), 2 bad input or usage (one line naming the problem
and the fix; `--debug` shows the traceback), 130 interrupted (Ctrl-C or SIGTERM; nothing
half-written, an earlier plan in the folder untouched). A plan stopped at its --time-limit
exits 1, with nothing written either.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tfcontact.errors import (
    FrameNotFound,
    IncompatibleOptions,
    Interrupted,
    InvalidInput,
    RobotLoadError,
    TfcontactError,
    TimeLimitReached,
    TrajectoryFileError,
)

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
EXIT_CODES = {
    EXIT_OK: "the plan is verified and does its task (other commands: done)",
    EXIT_FAILED: "the plan failed: solver, verification or task checks (reason printed), or "
                 "it was stopped at --time-limit (nothing written)",
    EXIT_USAGE: "bad input or usage: unknown plan, flag value, output folder, damaged file",
    EXIT_INTERRUPTED: "interrupted by Ctrl-C or SIGTERM: nothing half-written",
}
# Errors that mean the user's input is wrong (exit 2), as opposed to a failed solve (1).
_INPUT_ERRORS = (InvalidInput, IncompatibleOptions, RobotLoadError, FrameNotFound,
                 TrajectoryFileError)


def _positive(kind: type, name: str):
    """An argparse type: a positive `kind` (int or float), else a one-line usage error."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a positive "
                                             f"{kind.__name__}, got {text!r}") from None
        if not (value > 0 and value < float("inf")):
            raise argparse.ArgumentTypeError(f"{name} must be a positive "
                                             f"{kind.__name__}, got {text!r}")
        return value

    return parse


def _plan(args: argparse.Namespace) -> int:
    from tfcontact.scenes import PLANS, run_plan, task_plan
    from tfcontact.task import shipped_tasks

    if args.list or args.name is None:
        tasks = shipped_tasks()
        width = max(map(len, [*PLANS, *tasks]))  # one column for both lists
        print("Available plans:")
        for name, plan in PLANS.items():
            print(f"  {name:{width}s} {plan.summary}")
        print("Shipped task files (tfcontact plan NAME, or any PATH.toml of your own):")
        for name in tasks:
            print(f"  {name:{width}s} {task_plan(name).summary}")
        return EXIT_OK if args.list else EXIT_USAGE
    from tfcontact.interrupt import time_limit

    out = Path(args.out) if args.out else Path("out") / Path(args.name).stem
    with time_limit(args.time_limit):
        report = run_plan(args.name, out, task=args.task, attempts=args.attempts,
                          verbose=not args.quiet, force=args.force)
    if not report.success:
        print(f"tfcontact: plan {args.name} failed: {report.status} (written to "
              f"{report.out_dir} with its failed status)", file=sys.stderr)
    return EXIT_OK if report.success else EXIT_FAILED


def _replay(args: argparse.Namespace) -> int:
    from tfcontact.viz import cli_replay

    return cli_replay(args)


def _check(args: argparse.Namespace) -> int:
    from tfcontact.viz import cli_check

    return cli_check(args)


def main(argv: list[str] | None = None) -> int:
    codes = "\n".join(f"  {code:<4} {meaning}" for code, meaning in EXIT_CODES.items())
    parser = argparse.ArgumentParser(
        prog="tfcontact",
        description="Contact-rich motion planning with time-freezing and FESD.",
        epilog=f"exit codes:\n{codes}",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error instead of one line")
    sub = parser.add_subparsers(dest="command", required=True)

    plan = sub.add_parser(
        "plan", help="solve a robot plan and write trajectory, figures, replay",
        epilog=f"exit codes:\n{codes}\n\nThe folder is checked before solving; the plan is "
               "written to a staging folder beside it and moved into place at once. Ctrl-C "
               "stops the solve within an IPOPT iteration and leaves the folder untouched.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    plan.add_argument("name", nargs="?",
                      help="the plan to solve (see --list), or a task file PATH.toml")
    plan.add_argument("--list", action="store_true", help="list the available plans")
    plan.add_argument("--out", help="output folder (default out/NAME)")
    plan.add_argument("--force", action="store_true",
                      help="replace the output folder if it already holds files (a plan)")
    plan.add_argument("--task", default=None,
                      help="a variant of the plan (its summary in --list names them)")
    plan.add_argument("--attempts", type=_positive(int, "--attempts"), default=None,
                      help="solve a failed plan again from a perturbed guess, up to this "
                           "many solves in all (default: the plan's; hopper: 3 for the short "
                           "task); a task with exact_resolve runs its whole plan again")
    plan.add_argument("--time-limit", type=_positive(float, "--time-limit"), default=None,
                      metavar="SECONDS",
                      help="stop the plan at the first IPOPT iteration after this many "
                           "seconds of wall-clock time: exit 1, nothing written, the output "
                           "folder as it was (default: no limit)")
    plan.add_argument("--quiet", action="store_true", help="no progress output")
    plan.set_defaults(func=_plan)

    replay = sub.add_parser("replay", help="replay a trajectory in the browser (meshcat)")
    replay.add_argument("trajectory", help="a trajectory .npz written by tfcontact")
    replay.add_argument("--html", help="write a standalone HTML replay to this file")
    replay.add_argument("--open", action="store_true", help="open the replay in a browser")
    replay.add_argument("--speed", type=_positive(float, "--speed"), default=1.0,
                        help="playback rate (1 = real time, 0.25 = four times slower)")
    replay.add_argument("--fps", type=_positive(float, "--fps"), default=30.0,
                        help="animation key frames per second of playback")
    replay.add_argument("--forces", action="store_true", help="draw contact force arrows")
    replay.add_argument("--plain-html", action="store_true",
                        help="write the HTML scripts uncompressed (browsers without "
                             "DecompressionStream)")
    replay.set_defaults(func=_replay)

    check = sub.add_parser(
        "check", help="check a trajectory file: checksums, format version and physics",
        epilog="exit codes: 0 intact and physical, 1 a physics check fails, 2 the file is "
               "missing, damaged or foreign")
    check.add_argument("trajectory", help="a trajectory .npz (or its .json sidecar)")
    check.add_argument("--penetration", type=_positive(float, "--penetration"), default=1e-3,
                       help="largest allowed penetration of a contact [m] (default 1e-3)")
    check.add_argument("--tol", type=_positive(float, "--tol"), default=1e-6,
                       help="tolerance of the clock and momentum checks (default 1e-6)")
    check.set_defaults(func=_check)

    from tfcontact.sweep.cli import add_sweep_parser

    add_sweep_parser(sub)

    args = parser.parse_args(argv)  # a usage error exits 2 here, with one line
    from tfcontact.interrupt import stop_on_signals

    try:
        with stop_on_signals():  # SIGINT and SIGTERM stop a plan cleanly, exit 130
            return args.func(args)
    except KeyboardInterrupt as error:
        if args.debug:
            raise
        name = str(error) if isinstance(error, Interrupted) else "interrupted by SIGINT"
        print(f"tfcontact: {name}; stopped, nothing half-written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except TimeLimitReached as error:
        if args.debug:
            raise
        print(f"tfcontact: plan {args.name} stopped at the time limit of {error.limit:g} s "
              f"(--time-limit; {error.elapsed:.0f} s elapsed): nothing written, the output "
              "folder as it was; allow it more time", file=sys.stderr)
        return EXIT_FAILED
    except _INPUT_ERRORS as error:
        if args.debug:
            raise
        print(f"tfcontact: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except TfcontactError as error:
        if args.debug:
            raise
        print(f"tfcontact: error: {error}", file=sys.stderr)
        return EXIT_FAILED
    except OSError as error:  # a path the checks could not foresee (disk full, removed)
        if args.debug:
            raise
        where = f" {error.filename}" if error.filename else ""
        print(f"tfcontact: error: cannot write or read{where}: {error.strerror or error}; "
              "check the path and its permissions", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
