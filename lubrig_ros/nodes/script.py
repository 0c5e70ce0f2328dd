"""Console scripts' common parts: one-line user errors, a bounded middleware teardown.

run_script is the entry of the scripts that take plain options (recorder, replay);
bounded_teardown ends every node process.
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence

from ..app.processes.lifetime import ExitTimer

#: Wall seconds a node's middleware teardown (destroy_node, executor and context shutdown) may
#: take before the process ends without it. It normally takes well under 0.1 s; Fast DDS's
#: participant deletion has been seen to hang for good (2 of 20 short `lubrig rig` runs: the
#: plant or the recorder blocked in Node.destroy_node until the launcher's SIGKILL).
TEARDOWN_S = 3.0
#: Seconds after TEARDOWN_S when a teardown that also stopped the timer thread is ended.
BACKSTOP_S = 2.0


@contextlib.contextmanager
def bounded_teardown(prog: str, status: Callable[[], int], seconds: float = TEARDOWN_S) -> Iterator[None]:
    """Run the enclosed teardown; after `seconds` unfinished, say so and end the process.

    The exit status is status(): the node's work is done and what it wrote is flushed. A hung
    teardown cannot be interrupted from Python (it blocks in C), so a timer thread ends the
    process; nothing the node owns is left unfinished by then (callers close files first).
    A call that blocks while holding the GIL (rclpy destroying a DDS participant) stops that
    thread too. Then faulthandler's thread writes every thread's stack to stderr after
    `seconds` + BACKSTOP_S / 2 and an ExitTimer (app/processes/lifetime.py), which runs no
    Python, ends the process with the same status at `seconds` + BACKSTOP_S.
    """

    def give_up() -> None:
        print(
            f"{prog}: middleware teardown did not finish within {seconds:g} s (a known Fast DDS "
            "participant-deletion hang); exiting without it",
            file=sys.stderr,
            flush=True,
        )
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        os._exit(status())

    timer = threading.Timer(seconds, give_up)
    timer.daemon = True
    timer.start()
    faulthandler.dump_traceback_later(seconds + BACKSTOP_S / 2)
    backstop = ExitTimer(seconds + BACKSTOP_S, status())
    try:
        yield
    finally:
        backstop.cancel()
        faulthandler.cancel_dump_traceback_later()
        timer.cancel()


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
