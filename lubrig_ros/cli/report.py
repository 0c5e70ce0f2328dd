"""`lubrig report BAG --out DIR [--force]`: figures, summary.json, report.md and report.html."""

from __future__ import annotations

import argparse
from pathlib import Path

from lubrig_ros.core.errors import InputError

from ..app.rundir import prepare_output_dir
from ..bag.errors import BagError
from ..report import open_bag, write_report
from .common import add_force


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig report`."""
    bag = Path(args.bag)
    out = Path(args.out) if args.out else bag.parent / "report"
    prepare_output_dir(out, args.force)  # refuses a non-empty --out first; removes nothing
    source = open_bag(bag)  # the one read of the bag: its check and the messages reported on
    try:  # `lubrig bag check` but continuity, first: a damaged bag is refused in one line
        source.refuse_damaged("lubrig report")
    except BagError as exc:
        raise InputError(str(exc)) from None
    page = write_report(source, out, force=args.force)
    print(f"report: {page}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig report`."""
    parser = subparsers.add_parser(
        "report",
        help="report of a recorded bag (wavelet, time history, phase, friction figures)",
        description="Rebuild the run from a bag written by the recorder and write study-style "
        "figures, summary.json, report.md and report.html (figures embedded) to --out. An existing "
        "non-empty --out is refused unless --force.",
    )
    parser.add_argument("bag", metavar="BAG", help="bag directory written by the recorder")
    parser.add_argument("--out", metavar="DIR", help="output directory (default: BAG/../report)")
    add_force(parser)
    parser.set_defaults(func=run)
