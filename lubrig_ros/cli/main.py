"""Entry point of the `lubrig` command: one subcommand per module in this package."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

# Each module exposes register(subparsers) which adds its parser with set_defaults(func=...).
SUBCOMMAND_MODULES: tuple[str, ...] = (
    "friction",
    "stability",
    "simulate",
    "analyze",
    "rig",
    "bag",
    "replay",
    "report",
    "paper",
    "sweep",
)


class CommandError(Exception):
    """A user-facing failure: printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    """The full `lubrig` argument parser."""
    parser = argparse.ArgumentParser(
        prog="lubrig", description="Virtual lubricated test rig (lubrig_ros)."
    )
    subparsers = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"lubrig_ros.cli.{name}").register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run `lubrig`; user errors become one line on stderr and exit status 2."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (CommandError, ValueError, OSError) as exc:
        print(f"lubrig {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
