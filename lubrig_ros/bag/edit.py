"""New bags from recorded ones: a log-time range, a topic selection, several bags merged.

What `lubrig bag crop|filter|merge` write (docs/data.md), as `ros2 bag convert`, `mcap filter`
and `mcap merge` do: each message is copied byte for byte (its CDR payload and log time) into a
new rosbag2 bag written by the project's BagWriter, so the output verifies as any recording does.
A merge writes a message that two bags hold alike (topic, log time, bytes) once.

A time range keeps whole messages, never splits one: a RigStateBlock / BandVelocityBlock is kept
when any of its samples (log time + i · sample_period) lies within the range, so every sample in
the range is in the crop (and a block straddling a bound brings its samples outside it along);
any other message is kept when its log time lies within the range. A latched topic
(transient_local, as the run configuration) keeps its latest message from before the range at its
own log time: it is the state a subscriber joining at the start would receive.
"""

from __future__ import annotations

import heapq
import shutil
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from lubrig_ros.app.interface.cdr import INDEXED_TYPES, sample_span
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import bag_information
from lubrig_ros.bag.reader import Stream
from lubrig_ros.bag.stream import OpenedBag
from lubrig_ros.bag.writer import BagWriter

#: Offered QoS of a topic whose bag does not state it (the writer's default).
DEFAULT_QOS = (1000, False)


@dataclass
class EditReport:
    """What a crop / filter / merge wrote."""

    out: Path
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def messages(self) -> int:
        """Messages written."""
        return sum(self.counts.values())


def _qos_of(bag: OpenedBag) -> dict[str, tuple[int, bool]]:
    """(history depth, latched) per topic as the bag's metadata.yaml offers it."""
    out: dict[str, tuple[int, bool]] = {}
    directory = bag.mcap.parent
    try:
        info = bag_information(directory)
    except BagError:
        return out
    for entry in info.get("topics_with_message_count") or []:  # type: ignore[attr-defined]
        try:
            meta = entry["topic_metadata"]
            profiles = meta["offered_qos_profiles"]
            profile = (yaml.safe_load(profiles) if isinstance(profiles, str) else profiles)[0]
            durability = str(profile.get("durability", "")).lower()
            out[str(meta["name"])] = (int(profile.get("depth", 1000)), durability in ("1", "transient_local"))
        except (KeyError, IndexError, TypeError, ValueError, yaml.YAMLError):
            continue
    return out


def in_range(stream: Stream, log_ns: int, data: bytes, start_ns: int | None, end_ns: int | None) -> bool:
    """True if the message holds a sample within [start_ns, end_ns] (see the module docstring)."""
    last = log_ns
    if stream.msgtype in INDEXED_TYPES[1:]:
        try:
            span = sample_span(stream.msgtype, data)
        except ValueError:
            span = None
        if span is not None and span.count > 1 and span.period_ns:
            last = log_ns + round((span.count - 1) * span.period_ns)
    return (start_ns is None or last >= start_ns) and (end_ns is None or log_ns <= end_ns)


def run_config_of(bags: Iterable[OpenedBag]) -> str | None:
    """The one run configuration of the bags; BagError when two of them hold different ones."""
    found: dict[str, Path] = {}
    for bag in bags:
        if bag.run_config is not None:
            found.setdefault(bag.run_config, bag.path)
    if len(found) > 1:
        a, b = list(found.values())[:2]
        raise BagError(
            f"bags {str(a)!r} and {str(b)!r} hold different run configurations: merge bags of one run"
        )
    return next(iter(found), None)


def _check_types(bags: Iterable[OpenedBag]) -> None:
    """BagError when one topic has different message types in two bags."""
    seen: dict[str, tuple[str, Path]] = {}
    for bag in bags:
        for topic, msgtype in bag.types.items():
            other = seen.setdefault(topic, (msgtype, bag.path))
            if other[0] != msgtype:
                raise BagError(
                    f"topic {topic} is {other[0]} in {str(other[1])!r} but {msgtype} in {str(bag.path)!r}: "
                    "cannot merge"
                )


def copy_bags(
    bags: list[OpenedBag],
    out: Path,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> EditReport:
    """Write the messages of `bags` (merged by log time) that pass the selection into a new bag `out`.

    topics: only these (None: all); start_ns / end_ns: absolute log-time bounds (in_range). The
    output is removed again when reading a source fails half way (BagError raised).
    """
    _check_types(bags)
    config = run_config_of(bags)
    wanted = None if topics is None else list(dict.fromkeys(topics))
    qos: dict[str, tuple[int, bool]] = {}
    for bag in reversed(bags):
        qos.update(_qos_of(bag))
    writer = BagWriter(out, run_config=config)
    report = EditReport(out)
    try:
        for topic, msgtype in (item for bag in bags for item in bag.types.items()):
            if (wanted is None or topic in wanted) and topic not in report.counts:
                writer.add_topic(topic, msgtype, *qos.get(topic, DEFAULT_QOS))
                report.counts[topic] = 0
        latched = {topic for topic, (_depth, is_latched) in qos.items() if is_latched}
        for stream, t, data in _selected(_merged(bags, wanted), latched, start_ns, end_ns):
            writer.write(stream.topic, stream.msgtype, t, data)
            report.counts[stream.topic] += 1
        writer.close()
    except BagError:
        writer.close()
        shutil.rmtree(out, ignore_errors=True)
        raise
    return report


def _selected(
    messages: Iterator[tuple[Stream, int, bytes]], latched: set[str], start_ns: int | None, end_ns: int | None
) -> Iterator[tuple[Stream, int, bytes]]:
    """The messages in range (in_range), preceded by the latest message before it of each latched topic."""
    held: dict[str, tuple[Stream, int, bytes]] = {}
    for stream, t, data in messages:
        if in_range(stream, t, data, start_ns, end_ns):
            if held:
                yield from sorted(held.values(), key=lambda item: item[1])
                held = {}
            yield stream, t, data
        elif stream.topic in latched and start_ns is not None and t < start_ns:
            held[stream.topic] = (stream, t, data)
    yield from sorted(held.values(), key=lambda item: item[1])


def _merged(bags: list[OpenedBag], topics: list[str] | None) -> Iterator[tuple[Stream, int, bytes]]:
    """The messages of every bag in one stream, by log time (ties: the earlier bag first).

    A message that an earlier bag holds already (same topic, log time and bytes: two crops of one
    recording that overlap) is written once.
    """
    if len(bags) == 1:
        yield from bags[0].messages(topics)
        return
    keyed = [_keyed(bag.messages(topics), k) for k, bag in enumerate(bags)]
    now, seen = -1, set[tuple[str, bytes]]()
    for _key, (stream, t, data) in heapq.merge(*keyed, key=lambda pair: pair[0]):
        if t != now:
            now, seen = t, set()
        if (stream.topic, data) in seen:
            continue
        seen.add((stream.topic, data))
        yield stream, t, data


def _keyed(
    messages: Iterator[tuple[Stream, int, bytes]], rank: int
) -> Iterator[tuple[tuple[int, int], tuple[Stream, int, bytes]]]:
    for stream, t, data in messages:
        yield (t, rank), (stream, t, data)
