"""metadata.yaml against the MCAP file it describes: every field it holds, one problem per disagreement.

A reader driven by metadata.yaml (rosbags, `ros2 bag play`) matches each listed topic to the
file's channels by name, type, serialization format, offered QoS and type hash, and skips a
channel that matches none — so a metadata.yaml that disagrees with the file is damage, even
when the MCAP file itself is intact. What is compared (rosbag2 metadata version 9):

- with the data section: ``relative_file_paths`` and ``files`` (path, starting time, duration,
  message count, a size where one is recorded), ``starting_time``, ``duration``,
  ``message_count``, and per topic of ``topics_with_message_count`` its name, ``type`` (the
  channel's schema), ``serialization_format`` (the channel's message encoding),
  ``offered_qos_profiles`` (the channel's QoS text), ``type_description_hash`` (the channel's
  ``topic_type_hash``) and ``message_count``; every channel must be listed once;
- with what the file is: ``storage_identifier`` mcap, ``compression_format`` and
  ``compression_mode`` empty (the file is a plain MCAP; its chunks compress themselves);
- with the file's "rosbag2" metadata record (the copy the writer puts into the data section,
  covered by its CRC), where it has one: ``version``, ``custom_data``, ``ros_distro``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

from lubrig_ros.bag.findings import Verification
from lubrig_ros.bag.frames import Channel
from lubrig_ros.bag.meta import QOS_KEY, TYPE_HASH_KEY
from lubrig_ros.bag.verify_data import ScanState

#: The newest rosbag2 metadata version (what the writer writes; rosbags reads up to it).
METADATA_VERSION = 9
#: Keys a files entry (or the top level) may hold the size of the file under, in bytes.
SIZE_KEYS = ("size", "file_size", "bag_size")
_MISSING = object()


@dataclass(frozen=True)
class FileFacts:
    """What the MCAP file says about itself (from one walk)."""

    name: str
    size: int
    counts: dict[str, int]  # topic -> messages
    channels: dict[str, Channel]  # topic -> its (first) channel
    types: dict[str, str]  # topic -> schema name
    start: int  # first log time, ns (0 without messages)
    duration: int  # last - first log time, ns
    times_known: bool  # the data section was decompressed (log times of every message seen)
    record: dict[str, object] | None  # the "rosbag2" record's metadata mapping

    @property
    def total(self) -> int:
        """Messages in the file."""
        return sum(self.counts.values())


def file_facts(st: ScanState, mcap: Path, counts: dict[str, int], full: bool) -> FileFacts:
    """The facts of a walked file; counts: per topic (what the verifier counted)."""
    channels: dict[str, Channel] = {}
    types: dict[str, str] = {}
    for cid, ch in sorted(st.channels.items()):
        channels.setdefault(ch.topic, ch)
        types.setdefault(ch.topic, st.msgtype(cid))
    total = sum(counts.values())
    start = st.start if total else 0
    duration = max(0, st.end - st.start) if total else 0
    return FileFacts(
        mcap.name,
        mcap.stat().st_size,
        counts,
        channels,
        types,
        start,
        duration,
        full,
        _record_mapping(st.rosbag2_record),
    )


def _record_mapping(record: dict[str, str] | None) -> dict[str, object] | None:
    if record is None:
        return None
    try:
        info = yaml.safe_load(record.get("serialized_metadata", "") or "")
    except yaml.YAMLError:
        return None
    if isinstance(info, dict) and "rosbag2_bagfile_information" in info:
        info = info["rosbag2_bagfile_information"]
    return info if isinstance(info, dict) else None


def _get(mapping: object, path: str) -> object:
    """mapping[a][b]... for path "a.b" (_MISSING where a key or a mapping is absent)."""
    node = mapping
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            return _MISSING
        node = node[key]
    return node


class _Checker:
    """Adds `metadata.yaml <field> ...` problems to a Verification."""

    def __init__(self, v: Verification, meta: dict[str, object], facts: FileFacts) -> None:
        self.v, self.meta, self.facts = v, meta, facts

    def add(self, text: str, topic: str | None = None) -> None:
        self.v.add(f"metadata.yaml {text}", topic=topic)

    def integer(
        self, where: object, path: str, label: str, topic: str | None = None, required: bool = True
    ) -> int | None:
        """The integer at path of where (None, with a problem, if it is missing or not an integer)."""
        value = _get(where, path)
        if value is _MISSING:
            if required:
                self.add(f"has no {label}", topic)
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            self.add(f"{label} is {value!r}, expected an integer", topic)
            return None
        return value

    def equal(self, label: str, listed: object, actual: object, what: str, topic: str | None = None) -> None:
        if listed is not None and listed != actual:
            self.add(f"{label} is {listed!r}, {what} {actual!r}", topic)

    # ------------------------------------------------------------------ top level
    def top_level(self) -> None:
        f = self.facts
        self.version()
        self.equal("storage_identifier", self.text("storage_identifier"), "mcap", "the file is storage")
        files = _get(self.meta, "relative_file_paths")
        if files is _MISSING:
            self.add("has no relative_file_paths")
        elif files != [f.name]:
            self.add(f"relative_file_paths is {files!r}, the bag's file is [{f.name!r}]")
        for key in ("compression_format", "compression_mode"):
            value = _get(self.meta, key)
            if value not in (_MISSING, None, "") and not (key == "compression_mode" and value == "none"):
                self.add(f"{key} is {value!r}, the file is a plain MCAP (expected '')")
        total = self.integer(self.meta, "message_count", "message_count")
        self.equal("message_count", total, f.total, "the file holds")
        if f.times_known:
            start = self.integer(
                self.meta, "starting_time.nanoseconds_since_epoch", "starting_time.nanoseconds_since_epoch"
            )
            self.equal("starting_time", start, f.start, "the file's first log time is")
            duration = self.integer(self.meta, "duration.nanoseconds", "duration.nanoseconds")
            self.equal("duration", duration, f.duration, "the file's log times span")
        self.size(self.meta, "")
        self.files()
        self.recorded_fields()

    def text(self, key: str) -> str | None:
        value = _get(self.meta, key)
        if value is _MISSING:
            self.add(f"has no {key}")
            return None
        return value if isinstance(value, str) else repr(value)

    def version(self) -> None:
        version = self.integer(self.meta, "version", "version")
        if version is None:
            return
        recorded = _get(self.facts.record, "version")
        if isinstance(recorded, int) and not isinstance(recorded, bool):
            self.equal("version", version, recorded, "the file's rosbag2 record says")
        elif not 1 <= version <= METADATA_VERSION:
            self.add(f"version is {version}, expected a rosbag2 metadata version 1..{METADATA_VERSION}")

    def size(self, where: object, label: str) -> None:
        for key in SIZE_KEYS:
            value = _get(where, key)
            if value is not _MISSING:
                self.equal(f"{label}{key}", value, self.facts.size, "the file has (bytes)")

    def files(self) -> None:
        f = self.facts
        entries = _get(self.meta, "files")
        if entries is _MISSING:
            return  # before metadata version 5
        if not isinstance(entries, list) or len(entries) != 1 or not isinstance(entries[0], dict):
            self.add(f"files lists {entries!r}, expected one entry for {f.name!r}")
            return
        entry = entries[0]
        if "path" not in entry:
            self.add("files[0] has no path")
        else:
            self.equal("files[0].path", entry["path"], f.name, "the bag's file is")
        count = self.integer(entry, "message_count", "files[0].message_count")
        self.equal("files[0].message_count", count, f.total, "the file holds")
        if f.times_known:
            start = self.integer(entry, "starting_time.nanoseconds_since_epoch", "files[0].starting_time")
            self.equal("files[0].starting_time", start, f.start, "the file's first log time is")
            duration = self.integer(entry, "duration.nanoseconds", "files[0].duration")
            self.equal("files[0].duration", duration, f.duration, "the file's log times span")
        self.size(entry, "files[0].")

    def recorded_fields(self) -> None:
        """custom_data and ros_distro: their shape, and against the file's rosbag2 record."""
        record = self.facts.record
        custom = _get(self.meta, "custom_data")
        if custom not in (_MISSING, None) and not (
            isinstance(custom, dict) and all(isinstance(x, str) for kv in custom.items() for x in kv)
        ):
            self.add(f"custom_data is {custom!r}, expected a mapping of strings")
            return
        if record is not None:
            listed = custom if isinstance(custom, dict) else {}
            stored = _get(record, "custom_data")
            stored = stored if isinstance(stored, dict) else {}
            for key in sorted(set(listed) | set(stored), key=str):
                if key not in stored:
                    self.add(f"custom_data[{key!r}] is not in the file's rosbag2 record")
                elif key not in listed:
                    self.add(f"custom_data has no {key!r}, the file's rosbag2 record has it")
                elif listed[key] != stored[key]:
                    self.add(f"custom_data[{key!r}] differs from the file's rosbag2 record")
            distro = _get(self.meta, "ros_distro")
            stored_distro = _get(record, "ros_distro")
            if stored_distro is not _MISSING and distro != stored_distro:
                shown = "nothing" if distro is _MISSING else repr(distro)
                self.add(f"ros_distro is {shown}, the file's rosbag2 record says {stored_distro!r}")

    # ------------------------------------------------------------------ topics
    def topics(self) -> None:
        f = self.facts
        entries = _get(self.meta, "topics_with_message_count")
        if entries is _MISSING:
            self.add("has no topics_with_message_count")
            return
        if not isinstance(entries, list):
            self.add(f"topics_with_message_count is {entries!r}, expected a list")
            return
        seen: set[str] = set()
        for k, entry in enumerate(entries):
            name = _get(entry, "topic_metadata.name")
            if not isinstance(name, str):
                self.add(f"topics_with_message_count[{k}] names no topic ({entry!r})")
                continue
            if name in seen:
                self.add(f"lists topic {name} twice", name)
                continue
            seen.add(name)
            if name not in f.channels:
                self.add("lists a topic the file has no channel for", name)
                continue
            self.topic(entry, name)
        for name in sorted(set(f.channels) - seen):
            self.add(
                f"does not list the file's channel ({f.types[name]}, {f.counts.get(name, 0)} messages): "
                "a reader driven by metadata.yaml skips it",
                name,
            )

    def topic(self, entry: dict[str, object], name: str) -> None:
        f, ch = self.facts, self.facts.channels[name]
        tm = _get(entry, "topic_metadata")
        self.field_equal(tm, "type", f.types[name], "the file's schema is", name)
        self.field_equal(
            tm, "serialization_format", ch.message_encoding, "the file's channel encoding is", name
        )
        self.qos(tm, ch, name)
        if TYPE_HASH_KEY in ch.metadata:
            self.field_equal(
                tm,
                "type_description_hash",
                ch.metadata[TYPE_HASH_KEY],
                "the file's channel topic_type_hash is",
                name,
                required=False,
            )
        count = self.integer(entry, "message_count", "message_count", name)
        if count is not None and count != f.counts.get(name, 0):
            self.add(f"counts {count} messages, the file holds {f.counts.get(name, 0)}", name)

    def field_equal(
        self, where: object, key: str, actual: str, what: str, topic: str, required: bool = True
    ) -> None:
        value = _get(where, key)
        if value is _MISSING:
            if required:
                self.add(f"has no {key}", topic)
            return
        self.equal(key, value, actual, what, topic)

    def qos(self, tm: object, ch: Channel, name: str) -> None:
        listed = _get(tm, "offered_qos_profiles")
        text = ch.metadata.get(QOS_KEY)
        if listed is _MISSING or text is None:
            if (listed is _MISSING) != (text is None):
                where = "metadata.yaml" if listed is _MISSING else "the file's channel"
                self.add(f"offered_qos_profiles: {where} has none, the other has", name)
            return
        try:
            actual = yaml.safe_load(text) or []
            if isinstance(listed, str):  # metadata versions before 9 hold the text
                listed = yaml.safe_load(listed) or []
        except yaml.YAMLError as exc:
            self.add(f"offered_qos_profiles do not parse ({str(exc).splitlines()[0]})", name)
            return
        if listed != actual:
            self.add(f"offered_qos_profiles {_qos_difference(listed, actual)} (the file's channel QoS)", name)


def _qos_difference(listed: object, actual: object) -> str:
    """The first QoS value that differs, as `depth 10 differs from 1000`."""
    if isinstance(listed, list) and isinstance(actual, list) and len(listed) == len(actual):
        for a, b in zip(listed, actual, strict=True):
            if isinstance(a, dict) and isinstance(b, dict):
                for key in sorted(set(a) | set(b)):
                    if a.get(key, _MISSING) != b.get(key, _MISSING):
                        shown = "missing" if key not in a else repr(a[key])
                        return f"{key} {shown} differs from {b.get(key, 'nothing')!r}"
    return f"{listed!r} differ from {actual!r}"


def check_metadata(
    v: Verification, meta: dict[str, object], facts: FileFacts, counts_comparable: bool
) -> None:
    """Every disagreement of metadata.yaml (meta: its rosbag2_bagfile_information) with the file.

    counts_comparable False (a quick check of a file whose structure is broken): only the fields
    that do not depend on what the data section holds.
    """
    check = _Checker(v, meta, facts)
    if not counts_comparable:
        files = _get(meta, "relative_file_paths")
        if files != [facts.name]:
            check.add(f"relative_file_paths is {files!r}, the bag's file is [{facts.name!r}]")
        return
    check.top_level()
    check.topics()
