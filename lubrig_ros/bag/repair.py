"""Rebuild a bag's MCAP summary/index and metadata.yaml from the chunks that verify.

A tool the caller runs explicitly (`lubrig bag repair`, the recorder after a failed write):
BagWriter.close never repairs behind the caller's back.

Repair first verifies the bag (lubrig_ros.bag.verify): a bag with no problem of its structure is
left alone (unless force); otherwise — a missing or damaged summary, index, footer, a damaged
chunk, a truncation, a metadata.yaml that is missing, unreadable or disagrees with the file in
any field (names another file, wrong counts, types, QoS, ...) — the bag is rebuilt from its data
section. Every message of a chunk that verifies is kept, in file order, with its payload, log
and publish time unchanged; what is dropped is reported (where, why, and per topic how many when
its message index says). The rebuilt bag goes to ``output`` (a new directory beside the
original, what `lubrig bag repair` does by default) or, with ``output=None``, replaces the
original once completely written (the original kept as ``<name>.mcap.orig`` with backup).
The rebuilt bag is verified again; what still does not verify is listed (``remaining``).

metadata.yaml is rebuilt from the MCAP alone: topics, types, QoS, counts and times from its
channels and messages; per topic the type hash its channel carries (``topic_type_hash``; a
channel of an older bag has none and gets the type's hash, meta.type_hash). custom_data and
``ros_distro`` come from the file's "rosbag2" record (covered by the data-section CRC), else from
the old metadata.yaml where it is readable; the run configuration, if neither holds it, from
run_config.yaml or the recorded /run_config message. What could not be kept is listed
(``not_kept``).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import BinaryIO

import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from lubrig_ros import __version__
from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import (
    CONFIG_SIDECAR,
    RUN_CONFIG_KEY,
    MetadataUnreadableError,
    bag_information,
    cdr_string,
    find_mcap,
)
from lubrig_ros.bag.mcapscan import (
    Channel,
    Message,
    Metadata,
    ScanResult,
    Schema,
    scan,
    summary_definitions,
)
from lubrig_ros.bag.meta import PROFILE, QOS_KEY, TYPE_HASH_KEY, metadata_dict, metadata_texts, type_hash
from lubrig_ros.bag.verify import verify_bag

__all__ = ["RepairReport", "metadata_dict", "repair_bag", "repaired_path"]

RUN_CONFIG_TOPIC_SUFFIX = "/run_config"
#: A ros_distro that names no distribution: what older bags say (rosbags' name).
NO_DISTRO = {"", "rosbags"}


def _recorded_distro(info: object) -> str | None:
    """The ros_distro of a rosbag2_bagfile_information mapping, None if it names no distribution."""
    distro = info.get("ros_distro") if isinstance(info, dict) else None
    return distro.strip() if isinstance(distro, str) and distro.strip() not in NO_DISTRO else None


def _record_info(rec: Metadata) -> dict[str, object]:
    """The file's "rosbag2" record as a mapping (serialized_metadata; ROS_DISTRO of older writers)."""
    try:
        info = yaml.safe_load(rec.metadata.get("serialized_metadata", "") or "{}")
    except yaml.YAMLError:
        info = None
    out = dict(info) if isinstance(info, dict) else {}
    if "ros_distro" not in out and rec.metadata.get("ROS_DISTRO"):
        out["ros_distro"] = rec.metadata["ROS_DISTRO"]
    return out


def _strings(mapping: object) -> dict[str, str] | None:
    """A custom_data mapping as str -> str (None if it is not a mapping)."""
    if mapping is None:
        return {}
    if not isinstance(mapping, dict):
        return None
    return {str(k): str(v) for k, v in mapping.items()}


@dataclass
class RepairReport:
    """What repair found and did."""

    mcap: Path
    rewritten: bool
    complete: bool  # the original data section was complete and undamaged
    stop_reason: str
    damaged_chunks: list[str]
    counts: dict[str, int] = field(default_factory=dict)
    dropped: int = 0  # messages on channels whose definition was lost
    backup: Path | None = None
    problems: list[str] = field(default_factory=list)  # what verification found first
    damage: list[str] = field(default_factory=list)  # what was dropped, where and why
    output: Path | None = None  # the bag directory written (None: nothing written)
    not_kept: list[str] = field(default_factory=list)  # metadata that could not be kept, and why
    remaining: list[str] = field(default_factory=list)  # problems of the rebuilt bag (none: it verifies)

    @property
    def kept(self) -> int:
        """Messages in the rebuilt bag."""
        return sum(self.counts.values())


def repaired_path(bag: str | Path) -> Path:
    """Default output of `lubrig bag repair`: ``<bag>_repaired`` beside the bag directory."""
    bag_dir = find_mcap(bag).parent
    return bag_dir.with_name(bag_dir.name + "_repaired")


@dataclass
class _OldMetadata:
    """What the old metadata.yaml still gives (custom_data, ros_distro), and why not if nothing."""

    custom: dict[str, str] | None = None  # None: not readable
    distro: str | None = None
    problem: str = ""  # why it could not be read ("" if it could)


def _old_metadata(bag_dir: Path) -> _OldMetadata:
    if not (bag_dir / "metadata.yaml").is_file():
        return _OldMetadata(problem="metadata.yaml is missing")
    try:  # a damaged metadata.yaml is what repair replaces: keep what can be read of it
        info = bag_information(bag_dir)
    except MetadataUnreadableError as exc:
        return _OldMetadata(problem=exc.what)
    custom = _strings(info.get("custom_data"))
    return _OldMetadata(
        custom, _recorded_distro(info), "" if custom is not None else "custom_data unreadable"
    )


class _Rebuild:
    """The rewrite of one data section: definitions, counts, times, the run configuration seen."""

    def __init__(self, out: McapWriter, fallback: tuple[dict[int, Schema], dict[int, Channel]]) -> None:
        self.out = out
        self.fallback_schemas, self.fallback_channels = fallback
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.out_schema: dict[int, int] = {}
        self.out_channel: dict[int, int] = {}
        self.counts: dict[int, int] = {}
        self.start, self.end, self.dropped = 2**63 - 1, 0, 0
        self.run_config: str | None = None
        self.record: dict[str, object] | None = None

    def define_channel(self, rec: Channel) -> bool:
        if rec.schema_id not in self.out_schema:
            schema = self.schemas.get(rec.schema_id) or self.fallback_schemas.get(rec.schema_id)
            if schema is None:
                return False
            self.schemas[schema.id] = schema
            self.out_schema[schema.id] = self.out.register_schema(schema.name, schema.encoding, schema.data)
        if TYPE_HASH_KEY not in rec.metadata:  # an older bag: as rosbag2 writes it
            hashed = type_hash(self.schemas[rec.schema_id].name)
            rec = replace(rec, metadata={**rec.metadata, TYPE_HASH_KEY: hashed})
        self.channels[rec.id] = rec
        self.out_channel[rec.id] = self.out.register_channel(
            rec.topic, rec.message_encoding, self.out_schema[rec.schema_id], rec.metadata
        )
        self.counts[rec.id] = 0
        return True

    def add(self, rec: Schema | Channel | Message | Metadata) -> None:
        if isinstance(rec, Schema):
            if rec.id not in self.out_schema:
                self.schemas[rec.id] = rec
                self.out_schema[rec.id] = self.out.register_schema(rec.name, rec.encoding, rec.data)
        elif isinstance(rec, Channel):
            if rec.id not in self.channels:
                self.define_channel(rec)
        elif isinstance(rec, Message):
            self.message(rec)
        elif rec.name == "rosbag2" and self.record is None:
            self.record = _record_info(rec)

    def message(self, rec: Message) -> None:
        if rec.channel_id not in self.out_channel:
            fallback = self.fallback_channels.get(rec.channel_id)
            if fallback is None or not self.define_channel(fallback):
                self.dropped += 1
                return
        self.out.add_message(
            self.out_channel[rec.channel_id], rec.log_time, rec.data, rec.publish_time, rec.sequence
        )
        self.counts[rec.channel_id] += 1
        self.start, self.end = min(self.start, rec.log_time), max(self.end, rec.log_time)
        if self.run_config is None and self.channels[rec.channel_id].topic.endswith(RUN_CONFIG_TOPIC_SUFFIX):
            self.run_config = cdr_string(rec.data)

    def metadata(self, name: str, old: _OldMetadata, sidecar: Path, not_kept: list[str]) -> dict[str, object]:
        """metadata.yaml of the rebuilt file; what could not be kept appended to not_kept."""
        custom, distro = self._recorded(old, not_kept)
        if RUN_CONFIG_KEY not in custom and sidecar.is_file():
            custom[RUN_CONFIG_KEY] = sidecar.read_text(encoding="utf-8")
        if self.run_config is not None:
            custom.setdefault(RUN_CONFIG_KEY, self.run_config)
        if RUN_CONFIG_KEY not in custom:
            not_kept.append(
                "custom_data: no run configuration found (rosbag2 record, metadata.yaml, "
                f"{CONFIG_SIDECAR}, a /run_config message): `lubrig report` cannot read the bag"
            )
        topics = [
            (ch.topic, self.schemas[ch.schema_id].name, ch.metadata.get(QOS_KEY, ""), self.counts[cid])
            for cid, ch in self.channels.items()
        ]
        hashes = {ch.topic: ch.metadata[TYPE_HASH_KEY] for ch in self.channels.values()}
        return metadata_dict(name, topics, self.start, self.end, custom, hashes, distro)

    def _recorded(self, old: _OldMetadata, not_kept: list[str]) -> tuple[dict[str, str], str | None]:
        """(custom_data, ros_distro): the file's rosbag2 record first, else the old metadata.yaml."""
        stored = _strings(self.record.get("custom_data")) if self.record is not None else None
        if stored is None:
            if old.custom is None:
                not_kept.append(
                    f"custom_data and ros_distro: {old.problem} and the file holds no readable rosbag2 "
                    "record; rebuilt without them"
                )
            return dict(old.custom or {}), old.distro
        for key in sorted(set(old.custom or {}) - set(stored)):
            not_kept.append(f"custom_data[{key!r}] of metadata.yaml: not in the file's rosbag2 record")
        for key in sorted(set(old.custom or {}) & set(stored)):
            if (old.custom or {})[key] != stored[key]:
                not_kept.append(
                    f"custom_data[{key!r}] of metadata.yaml: differs from the file's rosbag2 record, "
                    "the record's kept"
                )
        distro = _recorded_distro(self.record)
        if distro and old.distro and old.distro != distro:
            not_kept.append(
                f"ros_distro {old.distro!r} of metadata.yaml: the file's rosbag2 record says {distro!r}, kept"
            )
        return stored, distro or old.distro


def _open_output(bag_dir: Path, mcap_path: Path, output: str | Path | None) -> tuple[Path, Path, Path]:
    """(output directory, its .mcap, the file written first) of a repair."""
    if output is None:
        return bag_dir, mcap_path, mcap_path.with_name(mcap_path.name + ".repair.tmp")
    out_dir = Path(output)
    if out_dir.exists():
        raise BagError(f"output {str(out_dir)!r} already exists: give a new directory (--output)")
    try:
        out_dir.mkdir(parents=False)
    except OSError as exc:
        raise BagError(f"cannot create {str(out_dir)!r}: {exc.strerror or exc}") from exc
    out_mcap = out_dir / f"{out_dir.name}.mcap"
    return out_dir, out_mcap, out_mcap


def _rewrite(stream: BinaryIO, mcap_path: Path, result: ScanResult) -> _Rebuild:
    """Write every message of the data section that verifies to stream; the summary is left open."""
    out = McapWriter(stream, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True)
    out.start(profile=PROFILE, library=f"lubrig_ros-{__version__} repair")
    rebuild = _Rebuild(out, summary_definitions(mcap_path))
    for rec in scan(mcap_path, result):
        rebuild.add(rec)
    return rebuild


def repair_bag(
    bag: str | Path, backup: bool = True, force: bool = False, *, output: str | Path | None = None
) -> RepairReport:
    """Rebuild the bag from its data section when its structure or metadata.yaml does not verify (or force).

    output: new bag directory to write (must not exist); None rebuilds in place (the original
    replaced only once the new file is complete; kept as ``<name>.mcap.orig`` with backup).
    BagError if there is no .mcap file to rebuild from or the output cannot be written.
    """
    bag = Path(bag)
    mcap_path = find_mcap(bag)
    bag_dir = mcap_path.parent
    verification = verify_bag(bag, full=True, continuity=False)
    problems = [p.line() for p in verification.structural]
    result = ScanResult()
    if not problems and not force:
        return RepairReport(mcap_path, False, True, "", [], dict(verification.counts), problems=[])
    old = _old_metadata(bag_dir)
    out_dir, out_mcap, tmp = _open_output(bag_dir, mcap_path, output)
    sidecar = bag_dir / CONFIG_SIDECAR
    not_kept: list[str] = []
    try:
        with open(tmp, "xb") as stream:
            rebuild = _rewrite(stream, mcap_path, result)
            if not rebuild.channels:
                raise BagError(
                    f"bag {str(bag)!r}: nothing to rebuild from, no intact chunk in its data section "
                    f"({result.stop_reason or 'no channel definition found'})"
                )
            meta = rebuild.metadata(out_mcap.name, old, sidecar, not_kept)
            yaml_text, record_text = metadata_texts(meta)
            rebuild.out.add_metadata("rosbag2", {"serialized_metadata": record_text})
            rebuild.out.finish()
            stream.flush()
            os.fsync(stream.fileno())
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if output is not None:
            shutil.rmtree(out_dir, ignore_errors=True)
        if isinstance(exc, OSError):
            raise BagError(f"repair of {str(bag)!r} failed: {exc.strerror or exc}") from exc
        raise
    channels = rebuild.channels
    topic_of = {cid: ch.topic for cid, ch in {**rebuild.fallback_channels, **channels}.items()}
    report = RepairReport(
        mcap_path,
        True,
        result.complete,
        result.stop_reason,
        result.damaged_chunks,
        {channels[c].topic: n for c, n in rebuild.counts.items()},
        rebuild.dropped,
        problems=problems,
        damage=[d.line(topic_of) for d in result.damage],
        output=out_dir,
        not_kept=not_kept,
    )
    try:
        if output is None:
            if backup:
                report.backup = mcap_path.with_name(mcap_path.name + ".orig")
                if not report.backup.exists():
                    os.link(mcap_path, report.backup)
            tmp.replace(mcap_path)
        elif sidecar.is_file():
            shutil.copyfile(sidecar, out_dir / CONFIG_SIDECAR)
        write_text_atomic(out_dir / "metadata.yaml", yaml_text)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise BagError(f"repair of {str(bag)!r} failed: {exc.strerror or exc}") from exc
    report.remaining = [p.line() for p in verify_bag(out_dir, full=True, continuity=False).structural]
    return report
