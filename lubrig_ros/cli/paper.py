"""`lubrig paper --out DIR`: reproduce the study offline, score every statement, write comparison.md.

The coupling scan is read from the committed table (docs/study/coupling_scan.csv) unless
--recompute-scan runs it again on the sweep engine (serial, or --workers N local Dask workers); the
runs of the page go to --workers N processes (default: the CPUs available, at most 2);
--docs DOCS copies the page to DOCS/study.md and its figures to DOCS/study/.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from lubrig_ros.core.errors import InputError

from ..app.rundir import prepare_output_dir
from ..core.presets import config_dir, default_config
from ..core.schema import SIMULATION_FIELDS
from ..study.page import HTML_PAGE
from ..study.reproduce import MIN_DURATION, PAGE_OUTPUTS, copy_to_docs, run_paper, total_rig_time
from ..study.runs import read_scan_csv, write_scan_csv
from .common import add_force, check_fits_in_memory, parse_finite, parse_workers
from .progress import Progress

SCAN_TABLE = "coupling_scan.csv"


def committed_scan() -> Path:
    """The scan table committed with the repository (docs/study/coupling_scan.csv)."""
    return config_dir().parent / "docs" / "study" / SCAN_TABLE


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig paper`."""
    duration = parse_finite("--duration", args.duration, "a rig time in s (>= 4)")
    if duration < MIN_DURATION:
        raise InputError(f"--duration {duration!r} is not valid; expected at least {MIN_DURATION:g} s")
    SIMULATION_FIELDS["duration"].check(duration, "--duration")
    rate = default_config().sample_rate  # every run of the study samples at the default rate
    check_fits_in_memory(round(duration * rate), rate)
    out = prepare_output_dir(Path(args.out), args.force, "--out", (*PAGE_OUTPUTS, SCAN_TABLE, "scan"))
    started = time.perf_counter()
    workers = parse_workers(args.workers) if args.workers is not None else None
    if args.recompute_scan:
        from ..study.scan import run_scan
        from ..sweep.engine import LOCAL, SERIAL

        scan = run_scan(out / "scan", scheduler=LOCAL if workers else SERIAL, workers=workers)
        source = f"recomputed in {time.perf_counter() - started:.0f} s"
    else:
        path = Path(args.scan) if args.scan else committed_scan()
        if not path.is_file():
            raise InputError(f"scan table {str(path)!r} not found; pass --scan CSV or --recompute-scan")
        scan = read_scan_csv(path)
        source = f"read from {SCAN_TABLE}"
    out.mkdir(parents=True, exist_ok=True)
    write_scan_csv(out / SCAN_TABLE, scan)
    bar = Progress("lubrig paper", total_rig_time(duration))
    try:
        page = run_paper(
            out, duration, scan=scan, scan_source=source, force=True, progress=bar.update, workers=workers
        )
    finally:
        bar.finish()
    print(f"lubrig paper: done in {time.perf_counter() - started:.1f} s; comparison: {page}")
    print(f"lubrig paper: the same page with every figure embedded: {page.parent / HTML_PAGE}")
    if args.docs:
        docs = Path(args.docs)
        target = copy_to_docs(page, docs)
        if args.recompute_scan:
            write_scan_csv(docs / "study" / SCAN_TABLE, scan)
        print(f"lubrig paper: copied to {target} and {docs / 'study'}/")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig paper`."""
    parser = subparsers.add_parser(
        "paper",
        help="reproduce the study offline and score every statement per velocity-coupling reading",
        description="Friction curve, stability maps, stick-slip at 2e-8 m/s and the ten Table 1 cases "
        "for every named velocity coupling (physical, paper, hertz), the scorecard of every statement "
        "of the study, the coupling scan's figures, comparison.md with every figure linked and "
        "comparison.html with every figure embedded. Progress is shown on a terminal.",
    )
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    add_force(parser)
    parser.add_argument("--duration", default="20", metavar="S", help="rig time per case, s (20)")
    scan = parser.add_mutually_exclusive_group()
    scan.add_argument("--scan", metavar="CSV", help="coupling-scan table (default: the committed one)")
    scan.add_argument(
        "--recompute-scan", action="store_true", help="run the coupling scan on the sweep engine"
    )
    parser.add_argument(
        "--workers",
        metavar="N",
        help="worker processes for the runs (default: the CPUs available, at most 2); with "
        "--recompute-scan also the scan's local Dask workers",
    )
    parser.add_argument(
        "--docs", metavar="DOCS", help="copy the page to DOCS/study.md, figures to DOCS/study/"
    )
    parser.set_defaults(func=run)
