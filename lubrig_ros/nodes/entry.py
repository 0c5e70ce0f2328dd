"""Console entry points of the node executables (`ros2 run lubrig_ros <node>`, .venv/bin/<node>).

A node module imports rclpy, numpy and the session layers before its main() can install rclpy's
signal handling: half a second to a second in which a Ctrl-C, or the launcher stopping a run
that ended before the slowest node had started, raised KeyboardInterrupt inside some import and
printed its traceback into the node log (issue 11: no tracebacks on a clean stop). So the entry
point installs a SIGINT handler first that ends the process of the signal, as the default action
does, without a traceback, and puts Python's own handler back once the node module is imported.

SIGUSR1 writes the Python stack of every thread to stderr (the node log; faulthandler): the
launcher sends it to a node that has not stopped within its grace period, before SIGTERM, so a
wedged node leaves the evidence of where it hung.
"""

from __future__ import annotations

import faulthandler
import importlib
import os
import signal
from types import FrameType


def _die_of_sigint(_signum: int, _frame: FrameType | None) -> None:
    """SIGINT before the node is set up: end with the default action (exit status -2)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGINT)


def _run(name: str) -> int:
    signal.signal(signal.SIGINT, _die_of_sigint)
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    module = importlib.import_module(f"lubrig_ros.nodes.{name}")
    # imported: Python's own handler again, which rclpy's signal handling chains to (a SIGINT to a
    # running node is a KeyboardInterrupt that its main turns into a clean stop, exit status 0)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    return int(module.main() or 0)


def belt_drive() -> int:
    """The belt_drive node."""
    return _run("belt_drive")


def plant() -> int:
    """The plant node."""
    return _run("plant")


def analysis() -> int:
    """The analysis node."""
    return _run("analysis")


def recorder() -> int:
    """The recorder (plain options)."""
    return _run("recorder")


def replay() -> int:
    """The replay (plain options)."""
    return _run("replay")


def view() -> int:
    """The live view for Foxglove (plain options)."""
    return _run("view")
