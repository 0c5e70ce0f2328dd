"""Topic forwarding of the `view` node: ROS topics of a rig namespace -> Foxglove channels.

Each topic of the namespace (and the ROS-wide /clock and /diagnostics) found on the ROS graph is
subscribed RAW (serialized CDR, no decoding) with the type the graph reports and logged on a
Foxglove channel: message encoding ``cdr``, schema the message definition in ``ros2msg`` text (the
type's .msg file with its dependencies, as in MCAP files), so Foxglove decodes it itself and a new
message type needs no code here. Decimation for display (app/view/display.py); blocks (``state_block``)
shown sample by sample as ``<ns>/state`` with their extremes kept.
"""

from __future__ import annotations

import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lubrig_ros.app.interface.cdr import leading_stamp_ns
from lubrig_ros.app.view import display
from lubrig_ros.core.errors import InputError

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

    def service_texts(self, srvtype: str) -> tuple[str, str]:
        """ros2msg texts of the request and the response of `srvtype` ("pkg/srv/Name").

        From the installed .srv file; a part that uses other message types gets their
        definitions appended as in a message schema.
        """
        from rosbags.typesys import get_types_from_msg

        pkg, _kind, name = srvtype.split("/")
        for prefix in self.prefixes():
            path = prefix / "share" / pkg / "srv" / f"{name}.srv"
            if path.is_file():
                break
        else:
            raise InputError(f"service type {srvtype!r}: no {pkg}/srv/{name}.srv under {self.prefixes()}")
        parts = re.split(r"^---[ \t]*$", path.read_text(), maxsplit=1, flags=re.MULTILINE)
        texts = []
        for part, suffix in zip(parts, ("_Request", "_Response"), strict=False):
            fields = [ln for ln in part.splitlines() if ln.split("#", 1)[0].strip()]
            if not fields:
                texts.append("")
                continue
            typename = f"{pkg}/msg/{name}{suffix}"  # the store keeps messages only
            self._store.register(get_types_from_msg(part, typename))
            texts.append(self.text(typename))
        return texts[0], texts[1] if len(texts) > 1 else ""

    def has_leading_stamp(self, msgtype: str) -> bool:
        """True if the payload starts with a Header or a Time (its stamp is read without decoding)."""
        self.text(msgtype)
        fields = self._store.fielddefs[msgtype][1]
        if not fields:
            return False
        first = fields[0][1]
        return first[0].name == "NAME" and first[1] in {"std_msgs/msg/Header", "builtin_interfaces/msg/Time"}


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


class View:
    """Topics of the namespace forwarded to the server's channels (the node is spun by the caller)."""

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
        node.create_timer(TIME_PERIOD_S, self._broadcast_time)

    def _broadcast_time(self) -> None:
        if self.server is not None:  # None until the server runs
            self.server.broadcast_time(self.rig_time_ns)

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
