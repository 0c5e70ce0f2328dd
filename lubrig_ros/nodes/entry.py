"""Console entry points of the node executables (`ros2 run lubrig_ros <node>`, .venv/bin/<node>).

A node module imports rclpy, numpy and the session layers before its main() can install rclpy's
signal handling: half a second to a second in which a Ctrl-C, or the launcher stopping a run
that ended before the slowest node had started, raised KeyboardInterrupt inside some import and
printed its traceback into the node log (a clean stop prints no traceback). So the entry
point installs a SIGINT handler first that ends the process of the signal, as the default action
does, without a traceback, and puts Python's own handler back once the node module is imported.

Numerical libraries run single-threaded in a node (`SINGLE_THREADED`, set before the node module
imports numpy, where the environment does not say otherwise): a rig node is one thread of
numerics on a machine shared with the other nodes and the real-time loop, and OpenBLAS's worker
threads spin while they wait, so a small matrix product of the analysis costs many times more
wall and CPU time with them than without (docs/benchmarks.md, online wavelet).

SIGUSR1 writes the Python stack of every thread to stderr (the node log; faulthandler): the
launcher sends it to a node that has not stopped within its grace period, before SIGTERM, so a
wedged node leaves the evidence of where it hung.

Start gate (`lubrig rig`): with LUBRIG_START_GATE=FD in its environment, the process imports
its node module and nodes/common.py and runs the module's `prepare()`, if it has one (work of the
node's start that needs neither its configuration nor the graph), then reads one byte from pipe FD
before it builds anything: it is started while
the launcher still checks that the rig's namespace is free (cli/rig_gate.py), so its imports
overlap that check, and it joins the ROS graph only once the check has passed. End of file
instead of the byte (the namespace is taken): the process exits 0 without starting the node.

`-h` / `--help` before any ROS arguments prints the node's usage and parameters (from the
contract, without importing rclpy) and exits 0 without starting the node.
"""

from __future__ import annotations

import faulthandler
import importlib
import os
import signal
import sys
from types import FrameType

from ..app.processes.startup_trace import mark

#: What each rig node does, for --help (the recorder, replay and view have argparse of their own).
NODE_SUMMARIES = {
    "plant": "the rig: integrates the mass on the band from band velocity input (modes sim, "
    "lockstep, realtime, rig_in_loop) and publishes its state",
    "belt_drive": "the band velocity of a profile, sent to the plant in blocks",
    "analysis": "online wavelet analysis and stability flags of the plant's samples",
}


def node_help(name: str) -> str:
    """Usage and parameters of rig node `name` (app/interface/contract.py), as `<node> --help` prints them."""
    from lubrig_ros.app.interface.contract import NODE_PARAMETERS

    lines = [
        f"usage: {name} [-h] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] [-r __ns:=/NS] ...]",
        "",
        f"{name}: {NODE_SUMMARIES[name]}.",
        "A ROS 2 node: parameters are ROS parameters (-p, --params-file, e.g. config/nodes.yaml);",
        "the namespace defaults to /lubrig. Topics, services, modes: docs/nodes.md, docs/topics.md.",
        "",
        "parameters:",
    ]
    for p in NODE_PARAMETERS[name]:
        default = "from the run configuration" if p.default is None else repr(p.default)
        lines.append(f"  {p.name} ({p.type}, default {default}; valid: {p.expected()})")
        lines.append(f"      {p.description}")
    return "\n".join(lines)


#: Environment of a node process's numerical libraries: one thread each (see the module docstring).
SINGLE_THREADED = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def single_threaded_numerics() -> None:
    """Ask numpy's BLAS for one thread (before numpy is imported; an explicit setting is kept)."""
    for key, value in SINGLE_THREADED.items():
        os.environ.setdefault(key, value)


#: Environment variable naming the read end of the start gate's pipe (see the module docstring).
GATE_VARIABLE = "LUBRIG_START_GATE"


def pass_start_gate() -> bool:
    """Wait at the start gate if there is one; False if the launcher closed it (do not start)."""
    fd = os.environ.pop(GATE_VARIABLE, None)
    if fd is None:
        return True
    try:
        return os.read(int(fd), 1) == b"1"
    finally:
        os.close(int(fd))


def _die_of_sigint(_signum: int, _frame: FrameType | None) -> None:
    """SIGINT before the node is set up: end with the default action (exit status -2)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGINT)


def _run(name: str) -> int:
    own = sys.argv[1:]
    own = own[: own.index("--ros-args")] if "--ros-args" in own else own
    if name in NODE_SUMMARIES and ("-h" in own or "--help" in own):
        print(node_help(name))
        return 0
    signal.signal(signal.SIGINT, _die_of_sigint)
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    single_threaded_numerics()
    mark(name, "entry point")
    module = importlib.import_module(f"lubrig_ros.nodes.{name}")
    mark(name, "imports done")
    prepare = getattr(module, "prepare", None)
    # the node's handler module (rclpy, numpy): imported before the gate, where the recorder's
    # module has not (after it, 0.3 s on the recorder's path to its first match)
    from .common import interrupt

    if prepare is not None and GATE_VARIABLE in os.environ:  # work for the wait at the gate
        prepare()
        mark(name, "prepared")
    if not pass_start_gate():
        return 0
    mark(name, "start gate passed")
    # imported: a Python handler again, which rclpy's signal handling chains to (a SIGINT to a
    # running node is a clean stop, exit status 0: common.interrupt says how)
    signal.signal(signal.SIGINT, interrupt)
    try:
        status = int(module.main() or 0)
    except KeyboardInterrupt:  # a second Ctrl-C that came before the node ignored SIGINT: stopped
        return 0
    if status and name in NODE_SUMMARIES:  # in the node's log: the status came from its main
        print(f"{name}: main() ended with exit status {status}", file=sys.stderr, flush=True)
    return status


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
