"""`lubrig sweep SPEC.yaml --out DIR`: design maps over rig, friction and band parameters.

Every point is a full core simulation and summary (plus wavelet dominant frequency and the linear
verdict). Results go to DIR/results.parquet (spec in its metadata and in DIR/spec.yaml) and maps
to DIR/map_*.png. Finished points are kept in DIR/points/, so rerunning the same command after an
interruption computes only the missing points. See docs/sweeps.md.
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path
from typing import Any

from lubrig_ros.core.errors import InputError

from ..sweep.engine import LOCAL, SERIAL, check_scheduler, run_sweep
from ..sweep.spec import SweepSpec, load_spec
from .common import MAX_LOCAL_WORKERS, parse_finite, parse_workers

#: Longest --worker-timeout, s: a scheduler without a worker for an hour is not coming.
MAX_WORKER_TIMEOUT_S = 3600.0
#: Rig samples a whole sweep may integrate (points × samples per point): at about 1e5 samples per
#: second and core, hours on a workstation; a larger design is split into several sweeps.
MAX_SWEEP_SAMPLES = 10**10


def _worker_timeout(text: str) -> float:
    what = f"seconds in (0, {MAX_WORKER_TIMEOUT_S:g}]"
    value = parse_finite("--worker-timeout", text, what)
    if not 0.0 < value <= MAX_WORKER_TIMEOUT_S:
        raise InputError(f"--worker-timeout {text!r} is not valid; expected {what}")
    return value


def check_reachable(scheduler: str, timeout: float) -> None:
    """ValueError when a tcp:// scheduler address does not accept a connection within `timeout` s."""
    if not scheduler.startswith("tcp://"):
        return
    address = scheduler.removeprefix("tcp://")
    host, _, port_text = address.rpartition(":")
    try:
        port = int(port_text)
    except ValueError:
        raise InputError(f"--scheduler {scheduler!r} has no port; expected tcp://host:port") from None
    if not (host and 0 < port < 65536):
        raise InputError(f"--scheduler {scheduler!r} is not valid; expected tcp://host:port (port 1..65535)")
    try:
        socket.create_connection((host.strip("[]"), port), timeout=min(timeout, 10.0)).close()
    except OSError as exc:
        raise InputError(
            f"--scheduler {scheduler!r} cannot be reached ({exc.strerror or exc}); start it with "
            f"`dask scheduler --port {port}` or give another address"
        ) from None


def check_size(spec: SweepSpec) -> None:
    """ValueError for a sweep whose points together hold more than MAX_SWEEP_SAMPLES samples."""
    total = sum(
        round(p.config["simulation"]["duration"] * p.config["simulation"]["sample_rate"]) for p in spec.points
    )
    if total > MAX_SWEEP_SAMPLES:
        raise InputError(
            f"the sweep has {len(spec.points)} points of {total:.3g} samples in all; at most "
            f"{MAX_SWEEP_SAMPLES:.0e} (fewer points or shorter runs, or several sweeps)"
        )


def _run(args: argparse.Namespace) -> int:
    workers = None if args.workers is None else parse_workers(args.workers)
    worker_timeout = _worker_timeout(args.worker_timeout)
    check_scheduler(args.scheduler, workers)
    check_reachable(args.scheduler, worker_timeout)
    spec = load_spec(args.spec)  # whole spec validated before DIR is touched
    check_size(spec)
    result = run_sweep(
        spec,
        Path(args.out),
        workers=workers,
        scheduler=args.scheduler,
        retry_failed=args.retry_failed,
        figures=not args.no_figures,
        progress=None if args.quiet else sys.stderr,
        worker_timeout=worker_timeout,
    )
    print(
        f"sweep {spec.name}: {result.total} points ({result.resumed} resumed, {result.computed} computed, "
        f"{result.failed} failed) in {result.wall_seconds:.3g} s; table {result.table}"
    )
    for path in result.figures:
        print(f"  map {path}")
    return 0


def register(subparsers: Any) -> None:
    """Add the `sweep` subcommand."""
    parser = subparsers.add_parser(
        "sweep",
        help="parameter sweep of full runs: Parquet table and design maps (resumable)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("spec", help="sweep spec YAML (see config/sweeps/ and docs/sweeps.md)")
    parser.add_argument("--out", required=True, help="results directory (created; reused to resume)")
    parser.add_argument(
        "--scheduler",
        default=LOCAL,
        help=f"{LOCAL!r}: embedded Dask LocalCluster (default); {SERIAL!r}: this process only; "
        "or a Dask scheduler address such as tcp://host:8786",
    )
    parser.add_argument(
        "--workers", default=None, help=f"local worker processes 1..{MAX_LOCAL_WORKERS} (default: all cores)"
    )
    parser.add_argument(
        "--worker-timeout",
        default="60",
        metavar="S",
        help="remote scheduler: give up when no worker has joined after S seconds, at most "
        f"{MAX_WORKER_TIMEOUT_S:g} (default 60); the scheduler itself must answer within min(S, 10 s)",
    )
    parser.add_argument("--retry-failed", action="store_true", help="recompute points that failed before")
    parser.add_argument("--no-figures", action="store_true", help="write the table only")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(func=_run)
