"""`lubrig bag info|check|repair BAG`: inspect, verify and repair recorded bags.

(`lubrig bag export|crop|filter|merge`: lubrig_ros.cli.bag_data.)

Exit status: 0 when the bag is fine (info, check) or was rebuilt and verifies / needed nothing
(repair); 1 when check / info --verify find a problem (the first one on stderr, by byte offset
and topic; every problem on stdout, one line each) or the rebuilt bag still does not verify;
2 for a bag that cannot be read at all or an unusable argument (one line on stderr).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lubrig_ros.bag import BagError, repair_bag
from lubrig_ros.bag.reader import summarize
from lubrig_ros.bag.repair import repaired_path
from lubrig_ros.bag.verify import Verification, verify_bag
from lubrig_ros.cli import bag_data
from lubrig_ros.core.errors import InputError


def _print_streams(v: Verification) -> None:
    if not v.streams:
        return
    print("Continuity:")
    width = max(len(t) for t in v.streams)
    for topic, rep in v.streams.items():
        print(f"  {topic:<{width}}  {rep.samples:>9} samples  {rep.format()}")


def _print_problems(v: Verification) -> None:
    for note in v.notes:
        print(f"note: {note}")
    for k, p in enumerate(v.problems, 1):
        print(f"problem {k}: {p.line()}")


def _check(args: argparse.Namespace) -> int:
    v = verify_bag(args.bag, full=True)
    if v.no_bag:  # not a bag at all: exit status 2, as for info
        raise InputError(v.problem_line())
    _print_streams(v)
    _print_problems(v)
    if v.problems:
        print(f"lubrig bag check: {v.problem_line()}", file=sys.stderr)
        return 1
    print(v.verdict())
    return 0


def _info(args: argparse.Namespace) -> int:
    v = verify_bag(args.bag, full=True)
    if v.structural:
        if args.verify:
            _print_problems(v)
            print(f"lubrig bag info: {v.problem_line()}", file=sys.stderr)
            return 1
        raise InputError(v.problem_line())
    summary = summarize(v, args.bag)  # the check above read the bag: no second read
    print(summary.format())
    if args.config and summary.run_config:
        print("--- run configuration ---")
        print(summary.run_config, end="" if summary.run_config.endswith("\n") else "\n")
    _print_streams(v)
    if args.verify:
        _print_problems(v)
        if v.problems:
            print(f"lubrig bag info: {v.problem_line()}", file=sys.stderr)
            return 1
        print(v.verdict())
    return 0


def _repair(args: argparse.Namespace) -> int:
    in_place = args.in_place or args.replace
    if in_place and args.output:
        raise InputError("--output and --in-place/--replace exclude each other: give one")
    try:
        output = None if in_place else (Path(args.output) if args.output else repaired_path(args.bag))
        report = repair_bag(args.bag, backup=not args.no_backup, force=args.force, output=output)
    except BagError as exc:
        raise InputError(str(exc)) from exc
    if not report.rewritten:
        print(
            f"{report.mcap}: verified intact, nothing to repair ({report.kept} messages; "
            "--force rebuilds anyway)"
        )
        return 0
    print(f"{args.bag}: {report.problems[0] if report.problems else 'rebuilt on request (--force)'}")
    if len(report.problems) > 1:
        print(f"  ({len(report.problems) - 1} more problem(s) found by verification)")
    print(f"rebuilt {report.output} with {report.kept} messages")
    for topic, n in report.counts.items():
        print(f"  kept {topic}: {n}")
    for line in report.damage:
        print(f"  dropped {line}")
    if report.dropped:
        print(f"  dropped {report.dropped} messages whose channel definition was lost")
    if not report.damage and not report.dropped:
        print("  dropped nothing: every message of the data section was kept")
    for line in report.not_kept:
        print(f"  not kept: {line}")
    if report.backup:
        print(f"  original kept as {report.backup}")
    elif not in_place:
        print(f"  original left untouched in {args.bag}")
    for line in report.remaining:
        print(f"  still wrong: {line}")
    if report.remaining:
        first = report.remaining[0]
        print(
            f"lubrig bag repair: the rebuilt bag {str(report.output)!r} does not verify: {first}",
            file=sys.stderr,
        )
        return 1
    print(f"  verified: {report.output} passes the structure and metadata checks of `lubrig bag check`")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `bag` subcommand with info, check, repair, export, crop, filter and merge."""
    p = subparsers.add_parser("bag", help="inspect, verify or repair recorded bags")
    sub = p.add_subparsers(dest="bag_command", required=True)
    info = sub.add_parser("info", help="print topics, types, counts, duration and gaps per stream")
    info.add_argument("bag", help="bag directory")
    info.add_argument("--config", action="store_true", help="also print the stored run config")
    info.add_argument(
        "--verify",
        action="store_true",
        help="also verify everything (as `lubrig bag check`); exit 1 on a problem",
    )
    info.set_defaults(func=_info)
    chk = sub.add_parser(
        "check", help="verify a bag: magic, header, chunk CRCs, index, summary, footer, counts, continuity"
    )
    chk.add_argument("bag", help="bag directory or .mcap file")
    chk.set_defaults(func=_check)
    rep = sub.add_parser("repair", help="rebuild summary, index and metadata.yaml from the data section")
    rep.add_argument("bag", help="bag directory")
    rep.add_argument("--output", metavar="DIR", help="repaired bag directory (default: BAG_repaired)")
    rep.add_argument("--in-place", action="store_true", help="replace the original (kept as .mcap.orig)")
    rep.add_argument("--replace", action="store_true", help="same as --in-place")
    rep.add_argument("--force", action="store_true", help="rebuild even a bag that verifies")
    rep.add_argument("--no-backup", action="store_true", help="with --in-place: do not keep .mcap.orig")
    rep.set_defaults(func=_repair)
    bag_data.register(sub)
