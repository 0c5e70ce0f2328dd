"""Rebuild a bag's MCAP summary/index and metadata.yaml from the chunks that verify.

A tool the caller runs explicitly (`lubrig bag repair`, the recorder after a failed write):
BagWriter.close never repairs behind the caller's back.

Repair first verifies the bag (lubrig_ros.bag.verify): a bag with no problem of its structure is
left alone (unless force); otherwise — a missing or damaged summary, index, footer, metadata.yaml,
a damaged chunk, a truncation — the bag is rebuilt from its data section. Every message of a
chunk that verifies is kept, in file order, with its payload, log and publish time unchanged;
what is dropped is reported (where, why, and per topic how many when its message index says).
The rebuilt bag goes to ``output`` (a new directory beside the original, what `lubrig bag repair`
does by default) or, with ``output=None``, replaces the original once completely written (the
original kept as ``<name>.mcap.orig`` with backup).

metadata.yaml is rebuilt from the MCAP: per topic the type hash its channel carries
(``topic_type_hash``; a channel of an older bag has none and gets the type's
hash, meta.type_hash), ``ros_distro`` as the bag recorded it (the old metadata.yaml, else the
file's "rosbag2" record; this process's distribution if neither names one).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from lubrig_ros import __version__
from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import (
    CONFIG_SIDECAR,
    RUN_CONFIG_KEY,
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


def _record_distro(rec: Metadata) -> str | None:
    """The ros_distro of the file's "rosbag2" metadata record (serialized_metadata, or ROS_DISTRO)."""
    if rec.name != "rosbag2":
        return None
    try:
        info = yaml.safe_load(rec.metadata.get("serialized_metadata", "") or "{}")
    except yaml.YAMLError:
        info = None
    return _recorded_distro(info) or _recorded_distro({"ros_distro": rec.metadata.get("ROS_DISTRO")})


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

    @property
    def kept(self) -> int:
        """Messages in the rebuilt bag."""
        return sum(self.counts.values())


def repaired_path(bag: str | Path) -> Path:
    """Default output of `lubrig bag repair`: ``<bag>_repaired`` beside the bag directory."""
    bag_dir = find_mcap(bag).parent
    return bag_dir.with_name(bag_dir.name + "_repaired")


def repair_bag(
    bag: str | Path, backup: bool = True, force: bool = False, *, output: str | Path | None = None
) -> RepairReport:
    """Rebuild the bag from its data section when its structure does not verify (or force).

    output: new bag directory to write (must not exist); None rebuilds in place (the original
    replaced only once the new file is complete; kept as ``<name>.mcap.orig`` with backup).
    BagError if there is no .mcap file to rebuild from or the output cannot be written.
    """
    bag = Path(bag)
    mcap_path = find_mcap(bag)
    bag_dir = mcap_path.parent
    verification = verify_bag(bag, full=True)
    problems = [p.line() for p in verification.structural]
    result = ScanResult()
    if not problems and not force:
        return RepairReport(mcap_path, False, True, "", [], dict(verification.counts), problems=[])
    meta_path = bag_dir / "metadata.yaml"
    old_custom: dict[str, str] = {}
    distro: str | None = None
    if meta_path.is_file():
        try:  # a damaged metadata.yaml is what repair replaces: keep what can be read of it
            info = bag_information(bag_dir)
            distro = _recorded_distro(info)
            stored = dict(info.get("custom_data") or {})  # type: ignore[call-overload]
            old_custom = {str(k): str(v) for k, v in stored.items()}
        except (BagError, TypeError, ValueError, AttributeError):
            old_custom = {}

    if output is not None:
        out_dir = Path(output)
        if out_dir.exists():
            raise BagError(f"output {str(out_dir)!r} already exists: give a new directory (--output)")
        out_mcap = out_dir / f"{out_dir.name}.mcap"
        tmp = out_mcap
        try:
            out_dir.mkdir(parents=False)
        except OSError as exc:
            raise BagError(f"cannot create {str(out_dir)!r}: {exc.strerror or exc}") from exc
    else:
        out_dir, out_mcap = bag_dir, mcap_path
        tmp = mcap_path.with_name(mcap_path.name + ".repair.tmp")

    fallback_schemas, fallback_channels = summary_definitions(mcap_path)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    out_schema: dict[int, int] = {}
    out_channel: dict[int, int] = {}
    counts: dict[int, int] = {}
    start, end, dropped = 2**63 - 1, 0, 0
    run_config: str | None = None

    def define_channel(rec: Channel, out: McapWriter) -> bool:
        if rec.schema_id not in out_schema:
            schema = schemas.get(rec.schema_id) or fallback_schemas.get(rec.schema_id)
            if schema is None:
                return False
            schemas[schema.id] = schema
            out_schema[schema.id] = out.register_schema(schema.name, schema.encoding, schema.data)
        if TYPE_HASH_KEY not in rec.metadata:  # an older bag: as rosbag2 writes it
            rec = replace(
                rec, metadata={**rec.metadata, TYPE_HASH_KEY: type_hash(schemas[rec.schema_id].name)}
            )
        channels[rec.id] = rec
        out_channel[rec.id] = out.register_channel(
            rec.topic, rec.message_encoding, out_schema[rec.schema_id], rec.metadata
        )
        counts[rec.id] = 0
        return True

    try:
        with open(tmp, "xb") as stream:
            out = McapWriter(
                stream, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True
            )
            out.start(profile=PROFILE, library=f"lubrig_ros-{__version__} repair")
            for rec in scan(mcap_path, result):
                if isinstance(rec, Schema):
                    if rec.id not in out_schema:
                        schemas[rec.id] = rec
                        out_schema[rec.id] = out.register_schema(rec.name, rec.encoding, rec.data)
                elif isinstance(rec, Channel):
                    if rec.id not in channels:
                        define_channel(rec, out)
                elif isinstance(rec, Message):
                    if rec.channel_id not in out_channel:
                        fallback = fallback_channels.get(rec.channel_id)
                        if fallback is None or not define_channel(fallback, out):
                            dropped += 1
                            continue
                    out.add_message(
                        out_channel[rec.channel_id], rec.log_time, rec.data, rec.publish_time, rec.sequence
                    )
                    counts[rec.channel_id] += 1
                    start, end = min(start, rec.log_time), max(end, rec.log_time)
                    ch = channels[rec.channel_id]
                    if run_config is None and ch.topic.endswith(RUN_CONFIG_TOPIC_SUFFIX):
                        run_config = cdr_string(rec.data)
                elif isinstance(rec, Metadata) and distro is None:
                    distro = _record_distro(rec)
            if not channels:
                raise BagError(
                    f"bag {str(bag)!r}: nothing to rebuild from, no intact chunk in its data section "
                    f"({result.stop_reason or 'no channel definition found'})"
                )
            custom = dict(old_custom)
            sidecar = bag_dir / CONFIG_SIDECAR
            if RUN_CONFIG_KEY not in custom and sidecar.is_file():
                custom[RUN_CONFIG_KEY] = sidecar.read_text(encoding="utf-8")
            if run_config is not None:
                custom.setdefault(RUN_CONFIG_KEY, run_config)
            topics = [
                (ch.topic, schemas[ch.schema_id].name, ch.metadata.get(QOS_KEY, ""), counts[cid])
                for cid, ch in channels.items()
            ]
            hashes = {ch.topic: ch.metadata[TYPE_HASH_KEY] for ch in channels.values()}
            meta = metadata_dict(out_mcap.name, topics, start, end, custom, hashes, distro)
            yaml_text, record_text = metadata_texts(meta)
            out.add_metadata("rosbag2", {"serialized_metadata": record_text})
            out.finish()
            stream.flush()
            os.fsync(stream.fileno())
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if output is not None:
            shutil.rmtree(out_dir, ignore_errors=True)
        if isinstance(exc, OSError):
            raise BagError(f"repair of {str(bag)!r} failed: {exc.strerror or exc}") from exc
        raise
    topic_of = {cid: ch.topic for cid, ch in {**fallback_channels, **channels}.items()}
    report = RepairReport(
        mcap_path,
        True,
        result.complete,
        result.stop_reason,
        result.damaged_chunks,
        {channels[c].topic: n for c, n in counts.items()},
        dropped,
        problems=problems,
        damage=[d.line(topic_of) for d in result.damage],
        output=out_dir,
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
    return report
