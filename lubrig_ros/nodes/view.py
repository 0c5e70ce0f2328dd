"""`view` node: serve the rig's topics to Foxglove over the Foxglove WebSocket protocol.

A real rclpy node (``view`` in the rig namespace) that finds the topics of its namespace (and the
ROS-wide /clock and /diagnostics) on the ROS graph, subscribes to each with the type the graph
reports, RAW (serialized CDR, no decoding), and hands the bytes to a Foxglove WebSocket server of
Foxglove's own SDK (foxglove-sdk), one channel per topic: message encoding ``cdr``, schema the
message definition in ``ros2msg`` text (the type's .msg file with its dependencies, as in MCAP
files), so Foxglove decodes them itself and a new message type needs no code here.

Decimation for display (app/view/display.py): at most `rate` messages per second of rig time per topic
(header stamp; receive time for unstamped types), at most twice that per wall second. Blocks
(``state_block``) are shown sample by sample as ``<ns>/state`` (RigState) on the same rule, so one
layout serves sim and realtime rigs; where a plant publishes both (the wall-clock modes), the
per-sample ``state`` topic is not subscribed (the blocks carry every sample, 50 messages a second
instead of 1,000). Log times are rig time (header stamps; the newest rig time
seen for unstamped messages), and the server broadcasts that time, so Foxglove's clock follows the
rig (also for `lubrig replay`, whose messages carry their recorded stamps).

Loopback (127.0.0.1) by default: binding another address (``--host``) is an explicit choice.
Read-only by default: ``--allow-services``, ``--allow-parameters`` and ``--allow-publish`` each
open one way back from a client to the rig (app/view/access.py, view_control.py,
view_parameters.py); without them the server advertises none of those capabilities.
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, validate_namespace
from lubrig_ros.app.view import access as view_access
from lubrig_ros.app.view import display, layouts
from lubrig_ros.app.view.access import Access
from lubrig_ros.core.params import ParameterError

from .view_topics import DISCOVERY_PERIOD_S, View

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765  # Foxglove's default for the WebSocket protocol
#: The TCP ports a server can bind (and a client reach); 0 asks the system for a free one.
HIGHEST_PORT = 65535


def tcp_port(text: str, lowest: int = 0) -> int:
    """A TCP port `lowest`..HIGHEST_PORT from the command line (0: a free one, where allowed)."""
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not lowest <= port <= HIGHEST_PORT:
        free = " (0: a free one)" if lowest == 0 else ""
        raise argparse.ArgumentTypeError(
            f"{text!r} is not valid; expected a TCP port {lowest}..{HIGHEST_PORT}{free}"
        )
    return port


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options of the view (the `view` console script and `lubrig view`)."""
    p.add_argument(
        "--namespace",
        default=DEFAULT_NAMESPACE,
        metavar="NS",
        help=f"the rig's namespace (default {DEFAULT_NAMESPACE})",
    )
    p.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help=f"address to bind (default {DEFAULT_HOST}: this machine only; e.g. 0.0.0.0 "
        "serves every network the machine is on)",
    )
    p.add_argument(
        "--port",
        type=tcp_port,
        default=DEFAULT_PORT,
        help=f"TCP port (default {DEFAULT_PORT}; 0 picks a free one)",
    )
    p.add_argument(
        "--rate",
        action="append",
        default=[],
        metavar="TOPIC=HZ",
        help="display rate of a topic, messages per second of rig time (0: every message); "
        f"repeatable; default {display.DEFAULT_DISPLAY_RATE:g} Hz for sample streams, "
        "10 Hz for analysis outputs, every message for latched topics and /diagnostics",
    )
    p.add_argument(
        "--default-rate",
        type=float,
        default=display.DEFAULT_DISPLAY_RATE,
        metavar="HZ",
        help="display rate of topics without a --rate or a built-in one",
    )
    p.add_argument(
        "--allow-services",
        action="store_true",
        help="let Foxglove clients call the rig's services (plant reset and pause); any client that "
        "reaches the port can then stop or restart the rig",
    )
    p.add_argument(
        "--allow-parameters",
        action="store_true",
        help="let Foxglove clients read and set the rig nodes' parameters (each node accepts or "
        "refuses a value itself)",
    )
    p.add_argument(
        "--allow-publish",
        action="store_true",
        help="let Foxglove clients publish band velocity (std_msgs/Float64 on <ns>/band_velocity, "
        "what a rig_in_loop plant integrates); every other topic is refused",
    )
    p.add_argument(
        "--layout",
        choices=sorted(layouts.LAYOUTS),
        help="print the viewer layout for --namespace (as shipped in config/ for /lubrig) and exit",
    )


def build_parser(prog: str = "view") -> argparse.ArgumentParser:
    """Arguments of the view node."""
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_arguments(p)
    return p


def settings(args: argparse.Namespace) -> display.DisplayRates:
    """The display rates of the command line (ParameterError naming a bad value)."""
    validate_namespace(args.namespace, "--namespace")
    if not 0 <= args.port <= 65535:
        raise ParameterError(f"--port {args.port} is not valid; expected 0..65535 (0: a free port)")
    default = display.check_rate(args.default_rate, "--default-rate")
    return display.DisplayRates(args.namespace, display.parse_rates(args.rate, args.namespace), default)


def access(args: argparse.Namespace) -> Access:
    """The ways back from a client to the rig that the command line opened."""
    return Access(services=args.allow_services, parameters=args.allow_parameters, publish=args.allow_publish)


@dataclass
class Opened:
    """What the server is started with for the opened ways back (nothing when read-only)."""

    capabilities: list[Any]
    services: list[Any]
    listener: Any  # view_control.Listener, or None when read-only
    encodings: list[str] | None
    bridges: list[Any] = field(default_factory=list)  # those with a summary() of client actions

    def summary(self) -> str:
        """What clients did through the opened ways (empty when read-only)."""
        return "\n".join(b.summary() for b in self.bridges)


def open_access(node: Any, view: View, opened: Access) -> Opened:
    """Services, parameter and band-input bridges for what `opened` allows."""
    import foxglove

    from .view_control import BandInput, Listener, ServiceBridge
    from .view_parameters import ParameterBridge

    capabilities = [foxglove.Capability.Time]
    services: list[Any] = []
    bridges: list[Any] = []
    if opened.services:
        capabilities.append(foxglove.Capability.Services)
        bridge = ServiceBridge(node, view.namespace, view.schemas)
        services = bridge.services()
        bridges.append(bridge)
    parameters = None
    if opened.parameters:
        capabilities.append(foxglove.Capability.Parameters)
        parameters = ParameterBridge(node, view.namespace)
        bridges.append(parameters)
        parameters.discover()
        node.create_timer(DISCOVERY_PERIOD_S, parameters.discover)
    band = None
    if opened.publish:
        capabilities.append(foxglove.Capability.ClientPublish)
        band = BandInput(node, view.namespace)
        bridges.append(band)
    if not (opened.parameters or opened.publish):
        return Opened(capabilities, services, None, None, bridges)
    listener = Listener(node, opened, parameters, band)
    encodings = list(view_access.BAND_ENCODINGS) if band else None
    return Opened(capabilities, services, listener, encodings, bridges)


def _announce(args: argparse.Namespace, view: View, port: int, opened: Access) -> None:
    url = f"ws://{args.host}:{port}"
    print(f"view: serving {view.namespace} on {url} (Foxglove WebSocket protocol)", flush=True)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"view: bound to {args.host}: reachable from other machines on that network", flush=True)
    if opened.opened():
        print(
            f"view: clients may act on the rig: {', '.join(opened.opened())} "
            "(anyone who reaches the port, without authentication)",
            flush=True,
        )
    print(f"view: open it in Foxglove: Open connection -> Foxglove WebSocket -> {url}", flush=True)


def run(args: argparse.Namespace, ros_args: Sequence[str] = ()) -> int:
    """Start node and server, spin until SIGINT/SIGTERM; returns the exit status."""
    rates = settings(args)
    if args.layout:
        print(layouts.LAYOUTS[args.layout](args.namespace), end="")
        return 0
    import foxglove
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = [False]

    def on_signal(_s: int, _f: object) -> None:
        stop[0] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    context = foxglove.Context()
    rclpy.init(
        args=["--ros-args", *ros_args] if ros_args else [], signal_handler_options=SignalHandlerOptions.NO
    )
    node = rclpy.create_node("view", namespace=args.namespace)
    server = None
    try:
        if node.get_namespace() != args.namespace:  # remapped (-r __ns:=, a launch file's namespace)
            args.namespace = node.get_namespace()
            rates = settings(args)
        view = View(node, None, context, rates)
        opened = open_access(node, view, access(args))
        try:
            server = foxglove.start_server(
                name=f"lubrig view {args.namespace}",
                host=args.host,
                port=args.port,
                capabilities=opened.capabilities,
                server_listener=opened.listener,
                supported_encodings=opened.encodings,
                services=opened.services or None,
                context=context,
            )
        except Exception as exc:  # the SDK raises its own error type for a bind failure
            raise OSError(f"cannot serve on {args.host}:{args.port}: {exc}") from exc
        view.server = server
        if opened.listener is not None:
            opened.listener.server = server
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        _announce(args, view, server.port, access(args))
        view.discover()
        while not stop[0]:
            executor.spin_once(timeout_sec=0.1)
    finally:
        if server is not None:
            server.stop()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"view: stopped; {len(view.served)} topics served", flush=True)
    if view.served:
        print(view.summary(), flush=True)
    if opened.summary():
        print(opened.summary(), flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Console script `view` (ROS arguments after --ros-args go to rclpy: remaps, __ns)."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    ros_args: list[str] = []
    if "--ros-args" in args_list:
        at = args_list.index("--ros-args")
        args_list, ros_args = args_list[:at], args_list[at + 1 :]
    args = build_parser().parse_args(args_list)
    try:
        return run(args, ros_args)
    except (ValueError, OSError) as exc:
        print(f"view: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
