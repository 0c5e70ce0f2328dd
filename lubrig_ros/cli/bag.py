"""`lubrig bag info|repair DIR`: inspect and repair recorded bags."""

from __future__ import annotations

import argparse

from lubrig_ros.bag import BagError, bag_info, repair_bag


def _info(args: argparse.Namespace) -> int:
    try:
        summary = bag_info(args.bag)
    except BagError as exc:
        raise ValueError(str(exc)) from exc
    print(summary.format())
    if args.config and summary.run_config:
        print("--- run configuration ---")
        print(summary.run_config, end="" if summary.run_config.endswith("\n") else "\n")
    return 0


def _repair(args: argparse.Namespace) -> int:
    try:
        report = repair_bag(args.bag, backup=not args.no_backup, force=args.force)
    except BagError as exc:
        raise ValueError(str(exc)) from exc
    if not report.rewritten:
        print(f"{report.mcap}: intact and finalized, nothing to repair (use --force to rebuild)")
        return 0
    total = sum(report.counts.values())
    print(f"{report.mcap}: rebuilt with {total} messages ({report.stop_reason or 'rebuilt'})")
    for problem in report.damaged_chunks:
        print(f"  skipped damaged {problem}")
    if report.dropped:
        print(f"  dropped {report.dropped} messages whose channel definition was lost")
    for topic, n in report.counts.items():
        print(f"  {topic}: {n}")
    if report.backup:
        print(f"  original kept as {report.backup}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `bag` subcommand with info and repair."""
    p = subparsers.add_parser("bag", help="inspect or repair recorded bags")
    sub = p.add_subparsers(dest="bag_command", required=True)
    info = sub.add_parser("info", help="verify a bag and print topics, types, counts, duration")
    info.add_argument("bag", help="bag directory")
    info.add_argument("--config", action="store_true", help="also print the stored run config")
    info.set_defaults(func=_info)
    rep = sub.add_parser("repair", help="rebuild summary/index and metadata.yaml after a crash")
    rep.add_argument("bag", help="bag directory")
    rep.add_argument("--force", action="store_true", help="rebuild even an intact bag")
    rep.add_argument("--no-backup", action="store_true", help="do not keep <name>.mcap.orig")
    rep.set_defaults(func=_repair)
