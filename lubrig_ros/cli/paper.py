"""`lubrig paper --out DIR [--duration S]`: reproduce the study offline and write comparison.md."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..report.paper import run_paper
from .common import parse_finite


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig paper`."""
    duration = parse_finite("--duration", args.duration, "a rig time in s (>= 4)")
    started = time.perf_counter()
    page = run_paper(Path(args.out), duration)
    print(f"lubrig paper: done in {time.perf_counter() - started:.1f} s; comparison: {page}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig paper`."""
    parser = subparsers.add_parser(
        "paper",
        help="reproduce the study offline (curves, stick-slip, ten cases) and compare",
        description="Friction curve, stability map, stick-slip at 2e-8 m/s, the ten Table 1 cases "
        "(paper and physical conventions) and comparison.md against the model document.",
    )
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    parser.add_argument("--duration", default="20", metavar="S", help="rig time per case, s (20)")
    parser.set_defaults(func=run)
