"""`python -m tfcontact.sweep PLAN ...`: the `tfcontact sweep` sub-command on its own."""

import argparse
import sys

from tfcontact.sweep.cli import add_sweep_parser


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tfcontact.sweep")
    sub = parser.add_subparsers(dest="command", required=True)
    add_sweep_parser(sub)
    args = parser.parse_args(["sweep", *(sys.argv[1:] if argv is None else argv)])
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
