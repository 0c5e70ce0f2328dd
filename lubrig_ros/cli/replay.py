"""`lubrig replay BAG`: republish a recorded bag (see lubrig_ros.nodes.replay)."""

from __future__ import annotations

import argparse

from lubrig_ros.bag.reader import Bag
from lubrig_ros.core.errors import InputError
from lubrig_ros.nodes import replay


def _run(args: argparse.Namespace) -> int:
    try:
        bag = Bag(args.bag)  # read once: its check (not continuity) first, then what is published
        bag.refuse_damaged("lubrig replay")
        return replay.run(args, bag)
    except replay.BagError as exc:
        raise InputError(str(exc)) from exc


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `replay` subcommand."""
    p = subparsers.add_parser(
        "replay",
        help="republish a bag with its original timing; pause, step, seek, rate; lossless",
        description=(replay.__doc__ or "").splitlines()[0],
        epilog=replay.CONTROLS,
    )
    replay.add_arguments(p)
    p.set_defaults(func=_run)
