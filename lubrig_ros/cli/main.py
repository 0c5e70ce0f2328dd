"""Entry point of the `lubrig` command: one subcommand per module in this package."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

from lubrig_ros.core.errors import LubrigError

# Each module exposes register(subparsers) which adds its parser with set_defaults(func=...).
SUBCOMMAND_MODULES: tuple[str, ...] = (
    "friction",
    "stability",
    "simulate",
    "analyze",
    "rig",
    "bag",
    "replay",
    "view",
    "report",
    "paper",
    "sweep",
    "fit",
)


class CommandError(LubrigError):
    """A user-facing failure: printed as one line, exit status 2."""


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (no usage block), exit status 2.

    Subcommand parsers are of the same class (argparse makes them with the parent's class).
    """

    def error(self, message: str) -> NoReturn:
        """Print `<prog>: error: <message>` and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The `lubrig` argument parser: every subcommand, or only `only` (its module alone imported).

    A subcommand module imports what it needs (numba kernels, scipy, matplotlib, rclpy) at import
    time, so importing all of them costs seconds; a command line that names its subcommand builds
    the parser with that one only.
    """
    parser = OneLineParser(prog="lubrig", description="Virtual lubricated test rig (lubrig_ros).")
    subparsers = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMAND_MODULES if only is None else (only,):
        importlib.import_module(f"lubrig_ros.cli.{name}").register(subparsers)
    return parser


def _subcommand(argv: Sequence[str]) -> str | None:
    """The subcommand a command line names (its first word), if it is one of ours."""
    first = next((a for a in argv if not a.startswith("-")), None)
    return first if first in SUBCOMMAND_MODULES and argv and argv[0] == first else None


def main(argv: Sequence[str] | None = None) -> int:
    """Run `lubrig`; the project's errors and OSError become one line on stderr and exit status 2.

    Any other exception is a bug and shows its traceback (core/errors.py).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_subcommand(argv))  # all of them for --help and for a wrong word
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (LubrigError, OSError) as exc:
        print(f"lubrig {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    # `python -m lubrig_ros.cli.main`: run the imported module's main, so that the CommandError
    # the subcommands raise (lubrig_ros.cli.main.CommandError) is the one caught, not __main__'s
    from lubrig_ros.cli.main import main as _main

    sys.exit(_main())
