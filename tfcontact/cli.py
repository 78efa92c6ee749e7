"""The `tfcontact` command: plan, replay.

    tfcontact plan --list
    tfcontact plan hopper --out DIR [--task long] [--attempts N] [--quiet]
    tfcontact plan monoped --out DIR [--task reduced|hand-set]
    tfcontact replay DIR/trajectory.npz [--html OUT] [--open]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tfcontact.errors import TfcontactError


def _plan(args: argparse.Namespace) -> int:
    from tfcontact.scenes import PLANS, run_plan

    if args.list or args.name is None:
        print("Available plans:")
        for name, plan in PLANS.items():
            print(f"  {name:12s} {plan.summary}")
        return 0 if args.list else 2
    if args.name not in PLANS:
        print(f"tfcontact: unknown plan `{args.name}`; available: {', '.join(PLANS)}",
              file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path("out") / args.name
    report = run_plan(args.name, out, task=args.task, attempts=args.attempts,
                      verbose=not args.quiet)
    return 0 if report.success else 1


def _replay(args: argparse.Namespace) -> int:
    from tfcontact.viz import cli_replay

    return cli_replay(args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="tfcontact",
        description="Contact-rich motion planning with time-freezing and FESD.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    plan = sub.add_parser("plan", help="solve a robot plan and write trajectory, figures, replay")
    plan.add_argument("name", nargs="?", help="the plan to solve (see --list)")
    plan.add_argument("--list", action="store_true", help="list the available plans")
    plan.add_argument("--out", help="output folder (default out/NAME)")
    plan.add_argument("--task", default=None,
                      help="a variant of the plan (hopper: short, long; "
                           "monoped: full, reduced, hand-set)")
    plan.add_argument("--attempts", type=int, default=None,
                      help="solve a failed plan again from a perturbed guess, up to this "
                           "many solves in all (default: the plan's; hopper: 3 for the short task)")
    plan.add_argument("--quiet", action="store_true", help="no progress output")
    plan.set_defaults(func=_plan)

    replay = sub.add_parser("replay", help="replay a trajectory in the browser (meshcat)")
    replay.add_argument("trajectory", help="a trajectory .npz written by tfcontact")
    replay.add_argument("--html", help="write a standalone HTML replay to this file")
    replay.add_argument("--open", action="store_true", help="open the replay in a browser")
    replay.add_argument("--speed", type=float, default=1.0,
                        help="playback rate (1 = real time, 0.25 = four times slower)")
    replay.add_argument("--fps", type=float, default=30.0,
                        help="animation key frames per second of playback")
    replay.add_argument("--forces", action="store_true", help="draw contact force arrows")
    replay.add_argument("--plain-html", action="store_true",
                        help="write the HTML scripts uncompressed (browsers without "
                             "DecompressionStream)")
    replay.set_defaults(func=_replay)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except TfcontactError as error:
        print(f"tfcontact: error: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
