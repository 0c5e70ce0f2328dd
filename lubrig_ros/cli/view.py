"""`lubrig view`: serve a running rig (or `lubrig replay`) to Foxglove (see lubrig_ros.nodes.view).

Open Foxglove, "Open connection" -> "Foxglove WebSocket" -> the printed ws:// URL, then import
config/foxglove/lubrig_layout.json (docs/viewing.md). Runs until Ctrl-C.
"""

from __future__ import annotations

import argparse

from lubrig_ros.nodes import view


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `view` subcommand."""
    p = subparsers.add_parser(
        "view",
        help="live view: serve the rig's topics to Foxglove (WebSocket, loopback by default)",
        description="Serve the topics of a rig namespace (live rig or `lubrig replay`) over the Foxglove "
        "WebSocket protocol, decimated for display. Read-only unless an --allow-... option lets "
        "clients act on the rig (the protocol has no authentication: every client that reaches "
        "the port can). Runs until Ctrl-C.",
    )
    view.add_arguments(p)
    p.set_defaults(func=view.run)
