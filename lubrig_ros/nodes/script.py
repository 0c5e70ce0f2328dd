"""Entry of the console scripts that take plain options (recorder, replay): one-line user errors."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence


def run_script(
    prog: str,
    build_parser: Callable[[], argparse.ArgumentParser],
    run: Callable[[argparse.Namespace], int],
    argv: Sequence[str] | None,
    errors: tuple[type[BaseException], ...] = (ValueError, OSError),
) -> int:
    """Parse argv (ROS arguments after --ros-args ignored) and run.

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
