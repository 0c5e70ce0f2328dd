"""`lubrig bag export|crop|filter|merge`: a bag's samples as tables, and new bags cut from bags.

Times (--start, --end) are seconds from the bag's first message (its first log time), as for
`lubrig replay --start`. Bad input (a bag that is missing or damaged, an unknown topic, --start
not before --end or past the bag's end, an output that exists or cannot be written) is one line
on stderr and exit status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.stream import OpenedBag, open_bag
from lubrig_ros.core.errors import InputError


def _open(path: str) -> OpenedBag:
    try:
        return open_bag(path)
    except BagError as exc:
        raise InputError(str(exc)) from exc


def _bounds(args: argparse.Namespace, bag: OpenedBag) -> tuple[int | None, int | None]:
    """(start, end) as absolute log times (ns) from --start / --end; InputError for bad values."""
    start, end = args.start, args.end
    for option, value in (("--start", start), ("--end", end)):
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise InputError(f"{option} {value:g} is invalid: expected seconds >= 0 from the bag's start")
    if start is not None and end is not None and start >= end:
        raise InputError(f"--start {start:g} is not before --end {end:g}: expected --start < --end")
    span = max(0, bag.end_ns - bag.start_ns) / 1e9
    if start is not None and start > span:
        raise InputError(f"--start {start:g} is invalid: the bag spans {span:g} s; expected a time within it")
    first = bag.start_ns
    return (
        None if start is None else first + round(start * 1e9),
        None if end is None else first + round(end * 1e9),
    )


def _check_topics(bag: OpenedBag, topics: list[str] | None) -> None:
    for topic in topics or ():
        if topic not in bag.types:
            held = ", ".join(bag.types) or "none"
            raise InputError(f"bag {str(bag.path)!r} holds no topic {topic!r}; its topics: {held}")


def _writable_dir(out: Path, force: bool) -> None:
    """InputError if `out` cannot become the export directory (before anything is read)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise InputError(f"--out {str(out)!r} exists and is not empty: pass --force or choose a new folder")
    parent = out.absolute()
    while not parent.exists():  # the folders still missing are created
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--out {str(out)!r} is not writable: {str(parent)!r} is not a writable directory")


def _new_bag(out: Path) -> None:
    from lubrig_ros.bag.writer import check_output_path

    try:
        check_output_path(out)
    except BagError as exc:
        raise InputError(str(exc).replace("output", "--out", 1)) from exc


def _export(args: argparse.Namespace) -> int:
    from lubrig_ros.bag.export import export_bag, select_topics

    bag = _open(args.bag)
    start, end = _bounds(args, bag)
    out = Path(args.out)
    _writable_dir(out, args.force)
    try:
        select_topics(bag, args.topics)
    except BagError as exc:
        raise InputError(str(exc)) from exc
    try:
        report = export_bag(bag, out, args.format, args.topics, start, end)
    except BagError as exc:
        raise InputError(str(exc)) from exc
    for s in report.streams.values():
        print(f"{s.topic}: {s.rows} rows -> {s.path}")
    if report.config is not None:
        print(f"run configuration -> {report.config}")
    return 0


def _copy(args: argparse.Namespace, paths: list[str]) -> int:
    from lubrig_ros.bag.edit import copy_bags

    bags = [_open(p) for p in paths]
    topics = getattr(args, "topics", None)
    for bag in bags:
        _check_topics(bag, topics)
    start, end = _bounds(args, bags[0])
    out = Path(args.out)
    _new_bag(out)
    try:
        report = copy_bags(bags, out, topics, start, end)
    except BagError as exc:
        raise InputError(str(exc)) from exc
    for topic, n in report.counts.items():
        print(f"{topic}: {n} messages")
    print(f"wrote {out} ({report.messages} messages)")
    return 0


def _crop(args: argparse.Namespace) -> int:
    return _copy(args, [args.bag])


def _merge(args: argparse.Namespace) -> int:
    if len(args.bags) < 2:
        raise InputError(f"merge takes two bags or more, got {len(args.bags)}")
    args.start = args.end = None
    return _copy(args, args.bags)


def _time_options(p: argparse.ArgumentParser, required: bool = False) -> None:
    p.add_argument(
        "--start", type=float, metavar="S", required=required, help="from S s after the bag's start"
    )
    p.add_argument("--end", type=float, metavar="S", required=required, help="to S s after the bag's start")


def register(sub: argparse._SubParsersAction) -> None:
    """Add export, crop, filter and merge to `lubrig bag`."""
    exp = sub.add_parser("export", help="write the sample streams as CSV or Parquet tables (one per stream)")
    exp.add_argument("bag", help="bag directory or .mcap file")
    exp.add_argument("--format", choices=("csv", "parquet"), default="csv")
    exp.add_argument(
        "--topics", nargs="+", metavar="T", help="only these topics (default: every sample stream)"
    )
    _time_options(exp)
    exp.add_argument("--out", metavar="DIR", required=True, help="output directory")
    exp.add_argument("--force", action="store_true", help="write into a non-empty --out")
    exp.set_defaults(func=_export)
    crop = sub.add_parser("crop", help="a new bag of a log-time range (whole messages)")
    crop.add_argument("bag", help="bag directory or .mcap file")
    _time_options(crop, required=True)
    crop.add_argument("--out", metavar="DIR", required=True, help="new bag directory")
    crop.set_defaults(func=_crop)
    flt = sub.add_parser("filter", help="a new bag of some topics (and a log-time range)")
    flt.add_argument("bag", help="bag directory or .mcap file")
    flt.add_argument("--topics", nargs="+", metavar="T", help="only these topics")
    _time_options(flt)
    flt.add_argument("--out", metavar="DIR", required=True, help="new bag directory")
    flt.set_defaults(func=_crop)
    mrg = sub.add_parser("merge", help="one new bag of the messages of several bags, by log time")
    mrg.add_argument("bags", nargs="+", metavar="BAG", help="bag directories or .mcap files")
    mrg.add_argument("--out", metavar="DIR", required=True, help="new bag directory")
    mrg.set_defaults(func=_merge)
