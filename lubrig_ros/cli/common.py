"""Helpers shared by the `lubrig` subcommands: number parsing that fails in one clear line."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..fileio import write_text_atomic

# argparse (Python < 3.13) takes "-1e-7" for an option; accept any signed float literal as a value.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)


def parse_finite(option: str, text: str, what: str) -> float:
    """Parse one command-line number; non-numbers and NaN/inf raise ValueError naming the value."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{option} {text!r} is not a number; expected {what}") from None
    if not math.isfinite(value):
        raise ValueError(f"{option} {text!r} is not finite; expected {what}")
    return value


def allow_negative_numbers(parser: argparse.ArgumentParser) -> None:
    """Let values such as "-1e-7" reach our own validation instead of argparse's option parsing."""
    parser._negative_number_matcher = NEGATIVE_NUMBER


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON atomically (temporary file, then rename) so a reader never sees half a file."""
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def run_script(
    prog: str,
    build_parser: Callable[[], argparse.ArgumentParser],
    run: Callable[[argparse.Namespace], int],
    argv: Sequence[str] | None,
    errors: tuple[type[BaseException], ...] = (ValueError, OSError),
) -> int:
    """Entry of a console script that takes plain options (ROS arguments after --ros-args ignored).

    A user error becomes one line `prog: error: …` on stderr and exit status 2.
    """
    args_list = list(sys.argv[1:] if argv is None else argv)
    if "--ros-args" in args_list:
        args_list = args_list[: args_list.index("--ros-args")]
    args = build_parser().parse_args(args_list)
    try:
        return run(args)
    except errors as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
