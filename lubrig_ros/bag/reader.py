"""Reading bags: integrity check, summary (`bag info`), messages, numpy arrays per topic.

:class:`Bag` reads a bag once: one walk of the file gives its check, its summary and the
messages a command reads (`lubrig report`); the functions below read the bag each time they are
called.

The one bag reader: messages come from the MCAP file's own channels and schemas
(lubrig_ros.bag.mcapscan over lubrig_ros.bag.frames), never through metadata.yaml, so a
metadata.yaml that describes a channel differently cannot make a stream disappear; the check
before reading (check_bag) names such a metadata.yaml as damage.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from lubrig_ros.app.interface.cdr import float64_value
from lubrig_ros.app.plant.output import BLOCK_FIELDS as BLOCK_FIELDS_OF_PLANT
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.findings import Verification
from lubrig_ros.bag.layout import RUN_CONFIG_KEY, find_mcap, typestore
from lubrig_ros.bag.mcapscan import Channel, Message, ScanResult, Schema, scan
from lubrig_ros.bag.meta import SCHEMA_ENCODING
from lubrig_ros.bag.verify import inspect_bag, verify_bag
from lubrig_ros.core import schema


@dataclass
class TopicSummary:
    """One topic of a bag."""

    name: str
    msgtype: str
    count: int


@dataclass
class BagSummary:
    """What `lubrig bag info` prints."""

    path: Path
    topics: list[TopicSummary]
    start_ns: int
    end_ns: int
    chunks: int
    custom_data: dict[str, str] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        """Total number of messages."""
        return sum(t.count for t in self.topics)

    @property
    def duration_s(self) -> float:
        """Time between first and last log time, seconds."""
        return max(0, self.end_ns - self.start_ns) / 1e9

    @property
    def run_config(self) -> str | None:
        """The run configuration YAML stored with the bag, if any."""
        return self.custom_data.get(RUN_CONFIG_KEY)

    def format(self) -> str:
        """Human-readable text like `ros2 bag info`."""
        lines = [
            f"Files:         {self.path}",
            f"Duration:      {self.duration_s:.3f} s",
            f"Start:         {self.start_ns / 1e9:.9f} s",
            f"End:           {self.end_ns / 1e9:.9f} s",
            f"Messages:      {self.message_count}",
            f"Chunks:        {self.chunks}",
            "Topics:",
        ]
        width = max((len(t.name) for t in self.topics), default=0)
        for t in self.topics:
            lines.append(f"  {t.name:<{width}}  {t.msgtype:<36}  {t.count:>9}")
        for key, value in sorted(self.custom_data.items()):
            shown = value if "\n" not in value else f"<{len(value.splitlines())} lines of YAML>"
            lines.append(f"Custom data:   {key}: {shown}")
        return "\n".join(lines)


def check_bag(bag: str | Path) -> BagSummary:
    """Verify the bag as `lubrig bag check` does (all but continuity); BagError names the first problem.

    Every chunk (CRC), the index, the summary and metadata.yaml against the file, every field
    (lubrig_ros.bag.verify); the summary's topics, counts and times are the file's own.
    """
    return summarize(verify_bag(bag, full=True, continuity=False), bag)


def summarize(v: Verification, bag: str | Path) -> BagSummary:
    """The summary of a verified bag; BagError naming its first structural problem."""
    problem = v.error()
    if problem is not None:
        raise problem
    assert v.mcap is not None
    topics = [TopicSummary(name, v.types.get(name, "?"), n) for name, n in v.counts.items()]
    custom = (v.metadata or {}).get("custom_data") or {}
    return BagSummary(
        v.mcap,
        topics,
        v.start_ns,
        v.end_ns,
        v.chunks,
        {str(k): str(x) for k, x in dict(custom).items()},  # type: ignore[call-overload]
    )


def bag_info(bag: str | Path) -> BagSummary:
    """Summary of a bag after a full integrity check (alias of check_bag)."""
    return check_bag(bag)


@dataclass(frozen=True)
class Stream:
    """One channel of a bag as the reader gives it: topic, type and the definition the file holds."""

    topic: str
    msgtype: str
    schema: Schema | None


def read_messages(
    bag: str | Path, topics: Iterable[str] | None = None
) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield (topic, msgtype, log_time_ns, cdr_bytes) in log-time order, every message of the file.

    Read from the MCAP file itself (its channels and schemas), not through metadata.yaml: no
    channel is left out because metadata.yaml describes it differently. BagError if the data
    section is damaged (nothing is yielded then) or a message is on an undefined channel.
    """
    for stream, t, data in stream_messages(bag, topics):
        yield stream.topic, stream.msgtype, t, data


def stream_messages(
    bag: str | Path, topics: Iterable[str] | None = None
) -> Iterator[tuple[Stream, int, bytes]]:
    """(stream, log_time_ns, cdr_bytes) in log-time order (ties in file order): read_messages with the stream.

    topics: only these (a topic the bag does not hold gives nothing). The whole data section is
    scanned (every chunk's CRC checked) before the first message is yielded.
    """
    kept = [(t, stream, data) for stream, t, data in messages_in_file_order(bag, topics)]
    kept.sort(key=lambda item: item[0])  # stable: ties keep their order in the file
    for t, stream, data in kept:
        yield stream, t, data


def messages_in_file_order(
    bag: str | Path, topics: Iterable[str] | None = None, mcap: Path | None = None
) -> Iterator[tuple[Stream, int, bytes]]:
    """(stream, log_time_ns, cdr_bytes) of every message of `topics` (None: all), in file order.

    Streams: each message is yielded as the scan reaches it (every chunk's CRC checked), nothing
    is held. Read from the MCAP file itself (`mcap`, else found in `bag`), its channels and
    schemas, never through metadata.yaml. BagError for a message on an undefined channel, and at
    the end for a damaged data section (what was yielded before stays valid).
    """
    path = mcap if mcap is not None else find_mcap(bag)
    wanted = set(topics) if topics is not None else None
    result = ScanResult()
    schemas: dict[int, Schema] = {}
    streams: dict[int, Stream] = {}
    try:
        for rec in scan(path, result):
            if isinstance(rec, Schema):
                schemas.setdefault(rec.id, rec)
            elif isinstance(rec, Channel):
                schema = schemas.get(rec.schema_id)
                streams.setdefault(rec.id, Stream(rec.topic, schema.name if schema else "?", schema))
            elif isinstance(rec, Message):
                stream = streams.get(rec.channel_id)
                if stream is None:
                    raise BagError(
                        f"bag {str(bag)!r} is damaged: a message at log time {rec.log_time} ns is on "
                        f"undefined channel {rec.channel_id}; run `lubrig bag repair {bag}`"
                    )
                if wanted is None or stream.topic in wanted:
                    yield stream, rec.log_time, rec.data
    except OSError as exc:
        raise BagError(f"cannot read {str(path)!r}: {exc.strerror or exc}") from exc
    if not result.complete:
        problem = result.stop_reason or "; ".join(result.damaged_chunks)
        raise BagError(f"bag {str(bag)!r} is damaged: {problem}; run `lubrig bag repair {bag}`")


_BAG_STORES: dict[tuple[str, str], Typestore] = {}


def stream_typestore(stream: Stream) -> Typestore:
    """The type store that decodes the messages of one stream.

    The project's (layout.typestore) when the bag defines the stream's type as the project does;
    otherwise one built from the definition stored in the bag, so a bag recorded before a field
    was appended to a message (RigStateBlock's lateness and skipped) still decodes, with that
    field absent from its messages.
    """
    store = typestore()
    schema = stream.schema
    if schema is None or schema.encoding != SCHEMA_ENCODING or not schema.data:
        return store
    try:
        text = schema.data.decode()
    except UnicodeDecodeError:
        return store
    key = (stream.msgtype, text)
    if key not in _BAG_STORES:
        try:
            types = get_types_from_msg(text, stream.msgtype)
        except Exception:  # an unparsable stored definition: decode with the project's types
            types = {}
        if stream.msgtype not in types or types[stream.msgtype] == store.fielddefs.get(stream.msgtype):
            _BAG_STORES[key] = store
        else:
            own = get_typestore(Stores.EMPTY)  # the stored definition holds its dependencies
            own.register(types)
            _BAG_STORES[key] = own
    return _BAG_STORES[key]


@dataclass
class TopicArrays:
    """Messages of one topic as arrays: log time t (s) and one array per field."""

    msgtype: str
    t: np.ndarray
    fields: dict[str, np.ndarray]

    def __getitem__(self, key: str) -> np.ndarray:
        """Field array by name (``"t"`` gives the log times)."""
        return self.t if key == "t" else self.fields[key]


#: Per-sample fields of lubrig_interfaces RigState (and the arrays of RigStateBlock), in order.
RIG_STATE_FIELDS: tuple[str, ...] = BLOCK_FIELDS_OF_PLANT
RIG_STATE = "lubrig_interfaces/msg/RigState"
RIG_STATE_BLOCK = "lubrig_interfaces/msg/RigStateBlock"
BAND_VELOCITY_BLOCK = "lubrig_interfaces/msg/BandVelocityBlock"
SHADOW_BLOCK = "lubrig_interfaces/msg/ShadowBlock"
#: ShadowBlock's per-pair arrays (each pair has its own sample_index: a block need not be consecutive).
SHADOW_FIELDS: tuple[str, ...] = tuple(schema.SHADOW_FIELDS)
BLOCK_FIELDS = {
    RIG_STATE_BLOCK: RIG_STATE_FIELDS,
    BAND_VELOCITY_BLOCK: ("band_velocity",),
    SHADOW_BLOCK: SHADOW_FIELDS,
}


def _stamp_s(stamp: Any) -> float:
    seconds: float = stamp.sec + stamp.nanosec * 1e-9
    return seconds


def _block_samples(msgtype: str, msg: object) -> dict[str, np.ndarray]:
    """Per-sample arrays of a block: its fields, stamp, sample_index, segment (n samples each)."""
    names = BLOCK_FIELDS[msgtype]
    cols = {name: np.asarray(getattr(msg, name), dtype=float) for name in names}
    n = len(cols[names[0]])
    for name, col in cols.items():
        if col.size != n:
            raise BagError(f"{msgtype}: field {name} has {col.size} samples, expected {n}")
    if msgtype == SHADOW_BLOCK:  # pairs: their own indices, stamped with the block's publication
        cols["stamp"] = np.full(n, _stamp_s(msg.header.stamp))  # type: ignore[attr-defined]
        cols["sample_index"] = np.asarray(msg.sample_index, dtype=np.int64).reshape(n)  # type: ignore[attr-defined]
        cols["segment"] = np.full(n, int(msg.segment), dtype=np.int64)  # type: ignore[attr-defined]
        return cols
    first = int(msg.first_sample_index)  # type: ignore[attr-defined]
    cols["stamp"] = _stamp_s(msg.header.stamp) + np.arange(n) * float(msg.sample_period)  # type: ignore[attr-defined]
    cols["sample_index"] = np.arange(first, first + n, dtype=np.int64)
    cols["segment"] = np.full(n, int(msg.segment), dtype=np.int64)  # type: ignore[attr-defined]
    if msgtype == RIG_STATE_BLOCK:
        cols["lateness"], cols["skipped"] = _block_timing(msg, n)
    return cols


def _block_timing(msg: object, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(lateness, skipped) of a RigStateBlock's n samples.

    lateness (s): the block's own, NaN for each sample when it carries none (sim and lockstep
    blocks, and bags recorded before the field existed). skipped: the block's count of samples
    the plant skipped just before it, on its first sample, 0 on the others (so the sum over a
    stream is every declared skip and the first sample marks where its gap ends).
    """
    lateness = np.asarray(getattr(msg, "lateness", ()), dtype=float)
    if lateness.size == 0:
        lateness = np.full(n, np.nan)
    elif lateness.size != n:
        raise BagError(f"{RIG_STATE_BLOCK}: field lateness has {lateness.size} samples, expected {n}")
    skipped = np.zeros(n, dtype=np.int64)
    if n:
        skipped[0] = int(getattr(msg, "skipped", 0))
    return lateness, skipped


def _first(values: Any) -> float:
    """The first joint's value of a JointState array, NaN if it has none."""
    return float(values[0]) if len(values) else np.nan


def _decode(msgtype: str, data: bytes, store: Typestore) -> dict[str, object]:
    if msgtype == "std_msgs/msg/Float64" and len(data) >= 12 and data[1] == 1:
        return {"data": float64_value(data)}  # fast path; other encodings: rosbags below
    msg: Any = store.deserialize_cdr(data, msgtype)
    if msgtype == RIG_STATE:
        out: dict[str, object] = {
            "stamp": _stamp_s(msg.header.stamp),
            "sample_index": int(msg.sample_index),
            "segment": int(msg.segment),
        }
        out.update({name: float(getattr(msg, name)) for name in RIG_STATE_FIELDS})
        return out
    if msgtype == "sensor_msgs/msg/JointState":
        return {
            "stamp": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
            "position": _first(msg.position),
            "velocity": _first(msg.velocity),
            "effort": _first(msg.effort),
        }
    if msgtype == "rosgraph_msgs/msg/Clock":
        return {"clock": msg.clock.sec + msg.clock.nanosec * 1e-9}
    if hasattr(msg, "data") and np.isscalar(msg.data):
        return {"data": msg.data}
    return {"message": msg}


def read_arrays(bag: str | Path, topics: Iterable[str] | None = None) -> dict[str, TopicArrays]:
    """Read a bag into numpy arrays per topic.

    Float64/UInt8/Bool topics give field ``data``; RigState gives ``stamp`` (s), ``sample_index``,
    ``segment`` and its fields (RIG_STATE_FIELDS); a RigStateBlock / BandVelocityBlock topic is
    flattened into one entry per SAMPLE (``t`` = the message's log time + i · sample_period, the
    same fields as RigState / ``band_velocity``, ``stamp`` per sample; a RigStateBlock adds
    ``lateness`` (s, NaN without realtime timing) and ``skipped`` (the block's declared skip on
    its first sample, see _block_timing)); a ShadowBlock topic is flattened into one entry per
    pair (SHADOW_FIELDS, its own ``sample_index``, ``segment``, ``stamp`` = the block's); legacy
    JointState gives
    ``stamp``, ``position``, ``velocity``, ``effort`` (first joint); Clock gives ``clock`` (s);
    other types give ``message`` (an object array of rosbags messages).
    """
    return _to_arrays(bag, stream_messages(bag, topics))


def _to_arrays(bag: str | Path, messages: Iterable[tuple[Stream, int, bytes]]) -> dict[str, TopicArrays]:
    """read_arrays of messages (stream, log time, payload) in log-time order; bag names the bag."""
    times: dict[str, list[int]] = {}
    values: dict[str, dict[str, list[object]]] = {}
    types: dict[str, str] = {}
    blocks: dict[str, list[tuple[int, dict[str, np.ndarray]]]] = {}
    for stream, t, data in messages:
        topic, msgtype = stream.topic, stream.msgtype
        types[topic] = msgtype
        try:
            store = stream_typestore(stream)
            if msgtype in BLOCK_FIELDS:
                samples = _block_samples(msgtype, store.deserialize_cdr(data, msgtype))
                blocks.setdefault(topic, []).append((t, samples))
                continue
            decoded = _decode(msgtype, data, store)
        except Exception as exc:  # the stream cannot be read: say which, never skip it
            raise BagError(
                f"bag {str(bag)!r}: topic {topic} ({msgtype}): the message at log time {t} ns does not "
                f"decode ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'no detail'}); "
                "the stream cannot be read"
            ) from None
        times.setdefault(topic, []).append(t)
        cols = values.setdefault(topic, {})
        for key, val in decoded.items():
            cols.setdefault(key, []).append(val)
    out: dict[str, TopicArrays] = {}
    for topic, ts in times.items():
        fields = {k: np.array(v, dtype=object if k == "message" else None) for k, v in values[topic].items()}
        out[topic] = TopicArrays(types[topic], np.array(ts, dtype=np.int64) / 1e9, fields)
    for topic, parts in blocks.items():
        names = list(parts[0][1])
        joined = {name: np.concatenate([cols[name] for _t, cols in parts]) for name in names}
        log = np.concatenate([t / 1e9 + (cols["stamp"] - cols["stamp"][:1]) for t, cols in parts])
        out[topic] = TopicArrays(types[topic], log, joined)
    return out


def _every(_topic: str) -> bool:
    return True


class Bag:
    """A bag read once: its check, its summary and the messages of the topics a command reads.

    Opening it walks the .mcap file once (lubrig_ros.bag.verify.inspect_bag: every chunk's CRC,
    the index, the summary and metadata.yaml against the file; not the samples' continuity) and
    keeps the payloads of the topics `keep` accepts (default: all). The summary, the refusal of a
    damaged bag, the messages and their arrays all come from that walk: `lubrig report` reads its
    bag once. Messages are read from the file's own channels, as read_messages does.
    """

    def __init__(self, bag: str | Path, keep: Callable[[str], bool] | None = None) -> None:
        self.path = Path(bag)
        self.keep = keep or _every
        self.verification, state = inspect_bag(bag, full=True, continuity=False, keep=self.keep)
        self._streams = {
            cid: Stream(ch.topic, state.msgtype(cid), state.schemas.get(ch.schema_id))
            for cid, ch in state.channels.items()
        }
        self._messages = state.messages
        self._arrays: dict[frozenset[str] | None, dict[str, TopicArrays]] = {}

    def refuse_damaged(self, command: str) -> None:
        """BagError in one line if the file is damaged (as verify.refuse_damaged; gaps are not damage)."""
        problem = self.verification.error(command)
        if problem is not None:
            raise problem

    def summary(self) -> BagSummary:
        """What check_bag gives: topics, counts, times, custom_data; BagError if the file is damaged."""
        return summarize(self.verification, self.path)

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[Stream, int, bytes]]:
        """(stream, log_time_ns, cdr_bytes) in log-time order (ties in file order), as stream_messages.

        BagError if the file is damaged. topics: only these; each must be one `keep` accepts.
        """
        if self.verification.structural:
            raise BagError(f"{self.verification.verdict()}; run `lubrig bag repair {self.path}`")
        wanted = set(topics) if topics is not None else None
        dropped = sorted(t for t in wanted or () if not self.keep(t))
        if dropped:
            raise ValueError(f"topics {dropped} were not kept when the bag was opened")
        kept = [
            (t, self._streams[cid], data)
            for t, cid, data in self._messages
            if wanted is None or self._streams[cid].topic in wanted
        ]
        kept.sort(key=lambda item: item[0])  # stable: ties keep their order in the file
        for t, stream, data in kept:
            yield stream, t, data

    def arrays(self, topics: Iterable[str] | None = None) -> dict[str, TopicArrays]:
        """read_arrays of the topics (default: every kept one), decoded once per set of topics."""
        key = frozenset(topics) if topics is not None else None
        if key not in self._arrays:
            self._arrays[key] = _to_arrays(self.path, self.messages(key))
        return self._arrays[key]
