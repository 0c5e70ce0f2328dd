"""`lubrig sweep SPEC.yaml --out DIR`: design maps over rig, friction and band parameters.

Every point is a full core simulation and summary (plus wavelet dominant frequency and the linear
verdict). Results go to DIR/results.parquet (spec in its metadata and in DIR/spec.yaml) and maps
to DIR/map_*.png. Finished points are kept in DIR/points/, so rerunning the same command after an
interruption computes only the missing points. See docs/sweeps.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..sweep.engine import LOCAL, SERIAL, check_scheduler, run_sweep
from ..sweep.spec import load_spec
from .common import parse_finite


def _workers(text: str | None) -> int | None:
    if text is None:
        return None
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"--workers {text!r} is not an integer; expected an integer >= 1") from None
    return value


def _run(args: argparse.Namespace) -> int:
    workers = _workers(args.workers)
    worker_timeout = parse_finite("--worker-timeout", args.worker_timeout, "seconds > 0")
    if worker_timeout <= 0:
        raise ValueError(f"--worker-timeout {args.worker_timeout!r} must be > 0 s")
    check_scheduler(args.scheduler, workers)
    spec = load_spec(args.spec)  # whole spec validated before DIR is touched
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
    parser.add_argument("--workers", default=None, help="local worker processes (default: all cores)")
    parser.add_argument(
        "--worker-timeout",
        default="60",
        metavar="S",
        help="remote scheduler: give up when no worker has joined after S seconds (default 60)",
    )
    parser.add_argument(
        "--retry-failed", action="store_true", help="recompute points that failed before"
    )
    parser.add_argument("--no-figures", action="store_true", help="write the table only")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(func=_run)
