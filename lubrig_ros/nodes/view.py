"""`view` node: serve the rig's topics to Foxglove over the Foxglove WebSocket protocol.

A real rclpy node (``view`` in the rig namespace) that finds the topics of its namespace (and the
ROS-wide /clock and /diagnostics) on the ROS graph, subscribes to each with the type the graph
reports, RAW (serialized CDR, no decoding), and hands the bytes to a Foxglove WebSocket server of
Foxglove's own SDK (foxglove-sdk), one channel per topic: message encoding ``cdr``, schema the
message definition in ``ros2msg`` text (the type's .msg file with its dependencies, as in MCAP
files), so Foxglove decodes them itself and a new message type needs no code here.

Decimation for display (app/display.py): at most `rate` messages per second of rig time per topic
(header stamp; receive time for unstamped types), at most twice that per wall second. Blocks
(``state_block``) are shown sample by sample as ``<ns>/state`` (RigState) on the same rule, so one
layout serves sim and realtime rigs; where a plant publishes both (the wall-clock modes), the
per-sample ``state`` topic is not subscribed (the blocks carry every sample, 50 messages a second
instead of 1,000). Log times are rig time (header stamps; the newest rig time
seen for unstamped messages), and the server broadcasts that time, so Foxglove's clock follows the
rig (also for `lubrig replay`, whose messages carry their recorded stamps).

Loopback (127.0.0.1) by default: binding another address (``--host``) is an explicit choice.
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lubrig_ros.app import display, layouts
from lubrig_ros.app.cdr import leading_stamp_ns
from lubrig_ros.app.contract import DEFAULT_NAMESPACE, validate_namespace
from lubrig_ros.core.errors import InputError
from lubrig_ros.core.params import ParameterError

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765  # Foxglove's default for the WebSocket protocol
#: The TCP ports a server can bind (and a client reach); 0 asks the system for a free one.
HIGHEST_PORT = 65535
DISCOVERY_PERIOD_S = 0.5
TIME_PERIOD_S = 0.1
GLOBAL_TOPICS = ("/clock", "/diagnostics")
_UNKNOWN_TYPE = re.compile(r"Type '([^']+)' is unknown")


# ---------------------------------------------------------------------------------- schemas


class MessageSchemas:
    """ros2msg text of a message type with its dependencies (as MCAP and Foxglove expect it).

    Standard types come from rosbags' ROS 2 Kilted type store; others (lubrig_interfaces, a
    foreign rig's package) from the installed ``share/<pkg>/msg/<Name>.msg`` files found under
    AMENT_PREFIX_PATH and this interpreter's prefix.
    """

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self._store = get_typestore(Stores.ROS2_KILTED)
        self._texts: dict[str, str] = {}

    @staticmethod
    def prefixes() -> list[Path]:
        """Install prefixes searched for .msg files."""
        import os

        paths = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
        return [*paths, Path(sys.prefix)]

    def msg_file(self, msgtype: str) -> Path:
        """The installed .msg file of `msgtype`; ValueError if there is none."""
        pkg, _kind, name = msgtype.split("/")
        for prefix in self.prefixes():
            path = prefix / "share" / pkg / "msg" / f"{name}.msg"
            if path.is_file():
                return path
        raise InputError(f"message type {msgtype!r}: no {pkg}/msg/{name}.msg under {self.prefixes()}")

    def text(self, msgtype: str) -> str:
        """The ros2msg schema text of `msgtype` ("pkg/msg/Name"); ValueError if it cannot be found."""
        if msgtype in self._texts:
            return self._texts[msgtype]
        from rosbags.typesys import get_types_from_msg
        from rosbags.typesys.base import TypesysError

        for _ in range(64):  # one missing dependency registered per round
            try:
                text = self._store.generate_msgdef(msgtype, ros_version=2)[0]
                break
            except TypesysError as exc:
                match = _UNKNOWN_TYPE.search(str(exc))
                if not match:
                    raise InputError(f"message type {msgtype!r}: {exc}") from exc
                missing = match.group(1)
                self._store.register(get_types_from_msg(self.msg_file(missing).read_text(), missing))
        else:
            raise InputError(f"message type {msgtype!r}: too many nested types")
        self._texts[msgtype] = text
        return text

    def has_leading_stamp(self, msgtype: str) -> bool:
        """True if the payload starts with a Header or a Time (its stamp is read without decoding)."""
        self.text(msgtype)
        fields = self._store.fielddefs[msgtype][1]
        if not fields:
            return False
        first = fields[0][1]
        return first[0].name == "NAME" and first[1] in {"std_msgs/msg/Header", "builtin_interfaces/msg/Time"}


# ---------------------------------------------------------------------------------- the node


@dataclass
class Served:
    """One topic served: its channel, decimator, how its time is read, counters."""

    topic: str
    msgtype: str
    channel: Any
    decimator: display.Decimator
    stamped: bool
    resets: bool = False  # the plant's samples and /clock: rig time may go back (reset)
    envelope: display.Envelope | None = None  # block topics: extremes between samples shown
    newest_ns: int = -1  # block topics: stamp of the newest sample seen (time going back: reset)
    received: int = 0
    forwarded: int = 0
    malformed: int = 0


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


class View:
    """The node and the server (created by `start`, spun by the caller)."""

    def __init__(self, node: Any, server: Any, context: Any, rates: display.DisplayRates) -> None:
        self.node = node
        self.server = server
        self.context = context
        self.rates = rates
        self.schemas = MessageSchemas()
        self.namespace = node.get_namespace()
        self.served: dict[str, Served] = {}  # by topic (or block topic)
        self.channels: dict[tuple[str, str], tuple[Any, display.Decimator]] = {}
        self.ignored: set[str] = set()
        self.subscriptions: list[Any] = []
        self.rig_time_ns = 0
        node.create_timer(DISCOVERY_PERIOD_S, self.discover)
        node.create_timer(TIME_PERIOD_S, lambda: self.server.broadcast_time(self.rig_time_ns))

    # -- discovery
    def in_scope(self, topic: str) -> bool:
        """Topics of the rig's namespace and the ROS-wide /clock and /diagnostics."""
        if topic in GLOBAL_TOPICS:
            return True
        if topic.endswith(("/rosout", "/parameter_events")) or "/_" in topic:
            return False
        prefix = "/" if self.namespace == "/" else self.namespace + "/"
        return topic.startswith(prefix)

    def discover(self) -> None:
        """Subscribe to every topic of the namespace not served yet (called periodically)."""
        graph = self.node.get_topic_names_and_types()
        names = {topic for topic, _types in graph}
        # a plant that publishes both shows its samples once: from the blocks (fewer messages)
        from_blocks = {
            topic[: len(topic) - len(block)] + sample
            for topic in names
            for block, (sample, _type) in display.EXPANDED_BLOCKS.items()
            if topic.endswith("/" + block)
        }
        for topic, types in graph:
            if topic in self.served or topic in self.ignored or not self.in_scope(topic):
                continue
            if topic in from_blocks:
                continue  # shown from its block topic
            if len(types) != 1:
                self._ignore(topic, f"published with {len(types)} types {types}")
                continue
            try:
                self._serve(topic, types[0])
            except (ValueError, KeyError) as exc:
                self._ignore(topic, str(exc))

    def _ignore(self, topic: str, why: str) -> None:
        self.ignored.add(topic)
        self.node.get_logger().warning(f"view: not serving {topic}: {why}")

    def _channel(self, topic: str, msgtype: str) -> tuple[Any, display.Decimator]:
        key = (topic, msgtype)
        if key not in self.channels:
            import foxglove

            schema = foxglove.Schema(
                name=msgtype, encoding="ros2msg", data=self.schemas.text(msgtype).encode()
            )
            channel = foxglove.Channel(topic, message_encoding="cdr", schema=schema, context=self.context)
            self.channels[key] = (channel, display.Decimator(self.rates.rate(topic)))
        return self.channels[key]

    def _serve(self, topic: str, msgtype: str) -> None:
        from .interfaces import message_class

        cls = message_class(msgtype)
        relative = topic[len(self.namespace) :].lstrip("/") if self.namespace != "/" else topic[1:]
        expanded = display.EXPANDED_BLOCKS.get(relative)
        if expanded is not None:
            sample_topic = topic[: len(topic) - len(relative)] + expanded[0]
            channel, decimator = self._channel(sample_topic, expanded[1])
            served = Served(topic, msgtype, channel, decimator, stamped=True)
            callback = self._block_callback(served, cls, message_class(expanded[1]))
        else:
            channel, decimator = self._channel(topic, msgtype)
            resets = relative == "state" or topic == "/clock"
            stamped = self.schemas.has_leading_stamp(msgtype)
            served = Served(topic, msgtype, channel, decimator, stamped, resets)
            callback = self._raw_callback(served)
        self.subscriptions.append(
            self.node.create_subscription(cls, topic, callback, self._qos(topic), raw=True)
        )
        self.served[topic] = served
        rate = decimator.rate
        shown = f"as {channel.topic()} " if expanded else ""
        every = "every message" if rate == 0 else f"{rate:g} Hz"
        self.node.get_logger().info(f"view: serving {topic} ({msgtype}) {shown}at {every}")

    def _qos(self, topic: str) -> Any:
        """Reliable/latched as the publishers offer (a latched topic is received on connecting)."""
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        infos = self.node.get_publishers_info_by_topic(topic)
        reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        latched = bool(infos) and all(
            i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos
        )
        return QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=1 if latched else 100,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        )

    # -- forwarding
    def _raw_callback(self, served: Served) -> Any:
        def callback(data: bytes) -> None:
            served.received += 1
            wall = time.monotonic_ns()
            if served.stamped:
                try:
                    stamp = leading_stamp_ns(data)
                except ValueError:
                    served.malformed += 1
                    return
                self._advance(stamp, served.resets)
                log_time = stamp
            else:
                stamp, log_time = wall, self.rig_time_ns
            if served.decimator.take(stamp, wall):
                served.channel.log(data, log_time=log_time)
                served.forwarded += 1

        return callback

    def _block_callback(self, served: Served, block_cls: Any, sample_cls: Any) -> Any:
        from rclpy.serialization import deserialize_message, serialize_message

        per_block = ("header", "sample_index", "segment")
        sample_fields = [f for f in sample_cls.get_fields_and_field_types() if f not in per_block]

        def show(i: int, block: Any, arrays: dict[str, Any]) -> None:
            """Sample i of a block, as the per-sample message it stands for."""
            stamp = block.header.stamp.sec * 1_000_000_000 + block.header.stamp.nanosec
            stamp += round(i * float(block.sample_period) * 1e9)
            sample = sample_cls()
            sample.header.stamp.sec, sample.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            sample.sample_index = block.first_sample_index + i
            sample.segment = block.segment
            for name, values in arrays.items():
                setattr(sample, name, float(values[i]))
            served.channel.log(serialize_message(sample), log_time=stamp)
            served.forwarded += 1

        def callback(data: bytes) -> None:
            served.received += 1
            try:
                block = deserialize_message(data, block_cls)
                first = block.header.stamp.sec * 1_000_000_000 + block.header.stamp.nanosec
                step = float(block.sample_period) * 1e9
                arrays = {f: getattr(block, f) for f in sample_fields}
                count = min(len(a) for a in arrays.values()) if arrays else 0
            except Exception:  # a malformed block is counted, never fatal
                served.malformed += 1
                return
            taken = set(served.decimator.take_block(first, step, count, time.monotonic_ns()))
            extremes = [arrays[f] for f in display.EXTREME_FIELDS if f in arrays]
            if served.envelope is None:
                served.envelope = display.Envelope(len(extremes))
            if first < served.newest_ns:
                served.envelope.reset()  # a reset, a replay from the start
            for i in range(count):
                values = [float(a[i]) for a in extremes]
                if i not in taken:
                    served.envelope.offer(values, (i, block, arrays))
                    continue
                for held in served.envelope.shown(values):
                    show(*held)  # type: ignore[misc]
                show(i, block, arrays)
            served.newest_ns = first + round((count - 1) * step) if count else served.newest_ns
            if count:
                self._advance(first + round((count - 1) * step), True)

        return callback

    def _advance(self, stamp: int, resets: bool) -> None:
        """Newest rig time seen; only the plant's samples move it back (a reset, a replay loop)."""
        if stamp > self.rig_time_ns or resets:
            self.rig_time_ns = stamp

    def summary(self) -> str:
        """One line per served topic: received, forwarded (and malformed) messages."""
        lines = []
        for s in self.served.values():
            bad = f", {s.malformed} malformed" if s.malformed else ""
            lines.append(f"  {s.topic}: {s.received} received, {s.forwarded} shown{bad}")
        return "\n".join(lines)


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
    try:
        server = foxglove.start_server(
            name=f"lubrig view {args.namespace}",
            host=args.host,
            port=args.port,
            capabilities=[foxglove.Capability.Time],
            context=context,
        )
    except Exception as exc:  # the SDK raises its own error type for a bind failure
        raise OSError(f"cannot serve on {args.host}:{args.port}: {exc}") from exc
    rclpy.init(
        args=["--ros-args", *ros_args] if ros_args else [], signal_handler_options=SignalHandlerOptions.NO
    )
    node = rclpy.create_node("view", namespace=args.namespace)
    if node.get_namespace() != args.namespace:  # remapped (-r __ns:=, a launch file's namespace)
        args.namespace = node.get_namespace()
        rates = settings(args)
    view = View(node, server, context, rates)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    url = f"ws://{args.host}:{server.port}"
    print(f"view: serving {view.namespace} on {url} (Foxglove WebSocket protocol)", flush=True)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"view: bound to {args.host}: reachable from other machines on that network", flush=True)
    print(f"view: open it in Foxglove: Open connection -> Foxglove WebSocket -> {url}", flush=True)
    try:
        view.discover()
        while not stop[0]:
            executor.spin_once(timeout_sec=0.1)
    finally:
        server.stop()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"view: stopped; {len(view.served)} topics served", flush=True)
    if view.served:
        print(view.summary(), flush=True)
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
