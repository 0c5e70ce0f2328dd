"""Rebuild a bag's MCAP summary/index and metadata.yaml from the chunks that are intact.

A tool the caller runs explicitly (`lubrig bag repair`, the recorder after a failed write):
BagWriter.close never repairs behind the caller's back.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
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
    typestore,
)
from lubrig_ros.bag.mcapscan import Channel, Message, ScanResult, Schema, scan

RUN_CONFIG_TOPIC_SUFFIX = "/run_config"


@dataclass
class RepairReport:
    """What repair found and did."""

    mcap: Path
    rewritten: bool
    complete: bool  # the original file was finalized and undamaged
    stop_reason: str
    damaged_chunks: list[str]
    counts: dict[str, int] = field(default_factory=dict)
    dropped: int = 0  # messages on channels whose definition was lost
    backup: Path | None = None


def metadata_dict(
    mcap_name: str,
    topics: list[tuple[str, str, str, int]],
    start: int,
    end: int,
    custom_data: dict[str, str],
) -> dict[str, object]:
    """rosbag2 (version 9) metadata; topics are (name, type, offered_qos_yaml, count)."""
    count = sum(t[3] for t in topics)
    duration = max(0, end - start) if count else 0
    start = start if count else 0
    entries = []
    for name, msgtype, qos_yaml, n in topics:
        try:
            qos = yaml.safe_load(qos_yaml) if qos_yaml else []
        except yaml.YAMLError:
            qos = []
        try:
            rihs = typestore().hash_rihs01(msgtype)
        except Exception:
            rihs = ""
        entries.append(
            {
                "message_count": n,
                "topic_metadata": {
                    "name": name,
                    "offered_qos_profiles": qos or [],
                    "serialization_format": "cdr",
                    "type": msgtype,
                    "type_description_hash": rihs,
                },
            }
        )
    return {
        "rosbag2_bagfile_information": {
            "compression_format": "",
            "compression_mode": "",
            "custom_data": custom_data or None,
            "duration": {"nanoseconds": duration},
            "files": [
                {
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                    "path": mcap_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                }
            ],
            "message_count": count,
            "relative_file_paths": [mcap_name],
            "ros_distro": "rosbags",
            "starting_time": {"nanoseconds_since_epoch": start},
            "storage_identifier": "mcap",
            "topics_with_message_count": entries,
            "version": 9,
        }
    }


def repair_bag(bag: str | Path, backup: bool = True, force: bool = False) -> RepairReport:
    """Rebuild the MCAP file and metadata.yaml of bag from its intact chunks.

    The rebuilt file replaces the original only once it is completely written; with backup the
    original is kept as ``<name>.mcap.orig``. An intact, finalized bag is left alone unless force.
    """
    bag = Path(bag)
    mcap_path = find_mcap(bag)
    bag_dir = mcap_path.parent
    meta_path = bag_dir / "metadata.yaml"
    old_custom: dict[str, str] = {}
    if meta_path.is_file():
        try:  # a damaged metadata.yaml is what repair replaces: keep what can be read of it
            old_custom = dict(bag_information(bag_dir).get("custom_data") or {})
        except (BagError, TypeError, ValueError):
            old_custom = {}

    result = ScanResult()
    tmp = mcap_path.with_name(mcap_path.name + ".repair.tmp")
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    out_schema: dict[int, int] = {}
    out_channel: dict[int, int] = {}
    counts: dict[int, int] = {}
    start, end, dropped = 2**63 - 1, 0, 0
    run_config: str | None = None
    try:
        with open(tmp, "wb") as stream:
            out = McapWriter(stream, compression=CompressionType.ZSTD)
            out.start(profile="ros2", library=f"lubrig_ros-{__version__} repair")
            for rec in scan(mcap_path, result):
                if isinstance(rec, Schema):
                    if rec.id not in schemas:
                        schemas[rec.id] = rec
                        out_schema[rec.id] = out.register_schema(rec.name, rec.encoding, rec.data)
                elif isinstance(rec, Channel):
                    if rec.id not in channels and rec.schema_id in out_schema:
                        channels[rec.id] = rec
                        out_channel[rec.id] = out.register_channel(
                            rec.topic, rec.message_encoding, out_schema[rec.schema_id], rec.metadata
                        )
                        counts[rec.id] = 0
                elif isinstance(rec, Message):
                    if rec.channel_id not in out_channel:
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
            report = RepairReport(
                mcap_path, False, result.complete, result.stop_reason, result.damaged_chunks,
                {channels[c].topic: n for c, n in counts.items()}, dropped,
            )
            if result.complete and meta_path.is_file() and not force:
                stream.close()
                tmp.unlink()
                return report
            custom = dict(old_custom)
            sidecar = bag_dir / CONFIG_SIDECAR
            if RUN_CONFIG_KEY not in custom and sidecar.is_file():
                custom[RUN_CONFIG_KEY] = sidecar.read_text(encoding="utf-8")
            if run_config is not None:
                custom.setdefault(RUN_CONFIG_KEY, run_config)
            topics = [
                (ch.topic, schemas[ch.schema_id].name, ch.metadata.get("offered_qos_profiles", ""),
                 counts[cid])
                for cid, ch in channels.items()
            ]
            meta = metadata_dict(mcap_path.name, topics, start, end, custom)
            info = meta["rosbag2_bagfile_information"]
            out.add_metadata(
                "rosbag2", {"serialized_metadata": yaml.safe_dump(info, default_flow_style=False)}
            )
            out.finish()
            stream.flush()
            os.fsync(stream.fileno())
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if backup:
        report.backup = mcap_path.with_name(mcap_path.name + ".orig")
        if not report.backup.exists():
            os.link(mcap_path, report.backup)
    tmp.replace(mcap_path)
    write_text_atomic(meta_path, yaml.safe_dump(meta, default_flow_style=False))
    report.rewritten = True
    return report
