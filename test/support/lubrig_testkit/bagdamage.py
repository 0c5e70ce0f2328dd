"""The damage matrix's bag and its damages (test/test_bag_damage_matrix.py, test/test_bag_one_reader.py,
test/test_report_one_read.py).

write_bag writes one bag of the current layout with lubrig_ros's own BagWriter (case 1 as the sim
recorder writes it); CASES damages a copy of it one way each, metadata.yaml field by field and the
MCAP file, with what `lubrig bag check` must name and what `lubrig bag repair` must do.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from mcap.reader import make_reader

from lubrig_ros.app.plant.output import BeltTravel, trajectory_columns
from lubrig_ros.bag.layout import typestore
from lubrig_ros.bag.writer import BagWriter, serialize_string
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate

NS = "/lubrig"
DURATION = 0.5
BLOCK = 50
STATE_BLOCK, BAND_BLOCK = f"{NS}/state_block", f"{NS}/band_velocity_block"
STATE_TYPE, BAND_TYPE = "lubrig_interfaces/msg/RigStateBlock", "lubrig_interfaces/msg/BandVelocityBlock"
INFO = "rosbag2_bagfile_information"


def write_bag(path: Path) -> None:
    """Case 1 as the sim recorder writes it: state and band blocks, the run configuration."""
    config = load_case(1).with_overrides(duration=DURATION)
    traj = simulate(config)
    store = typestore()
    n, period = len(traj), 1.0 / config.sample_rate
    normal = config.rig.friction.normal_force
    values = trajectory_columns(traj, BeltTravel().add_many(traj.time, traj.band_velocity), normal)
    header, stamp = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    writer = BagWriter(path, run_config=config.to_yaml(), flush_messages=5)
    writer.write(f"{NS}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    for k0 in range(0, n, BLOCK):
        ks = slice(k0, min(k0 + BLOCK, n))
        t_ns = round(k0 * period * 1e9)
        head = header(stamp(*divmod(t_ns, 1_000_000_000)), "")
        common = {"header": head, "sample_period": period, "first_sample_index": k0, "segment": 0}
        fields = {name: values[name][ks] for name in values}
        state = store.types[STATE_TYPE](**common, **fields, lateness=np.zeros(0), skipped=0)
        band = store.types[BAND_TYPE](**common, band_velocity=values["band_velocity"][ks])
        writer.write(BAND_BLOCK, BAND_TYPE, t_ns, bytes(store.serialize_cdr(band, BAND_TYPE)))
        writer.write(STATE_BLOCK, STATE_TYPE, t_ns, bytes(store.serialize_cdr(state, STATE_TYPE)))
    writer.close()


# ----------------------------------------------------------------------------- damage


Damage = Callable[[Path], None]


def _meta(change: Callable[[dict[str, Any]], None]) -> Damage:
    """Edit metadata.yaml's rosbag2_bagfile_information in place."""

    def damage(bag: Path) -> None:
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())
        change(meta[INFO])
        (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))

    return damage


def _set(path: str, value: object) -> Damage:
    """metadata.yaml with the field at path ("a.b.0.c") set to value."""

    def change(info: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = info
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[int(last) if isinstance(node, list) else last] = value

    return _meta(change)


def _shift(path: str, by: int) -> Damage:
    """metadata.yaml with the integer at path changed by `by`."""

    def change(info: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = info
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[last] += by

    return _meta(change)


def _topic_index(info: dict[str, Any], topic: str) -> int:
    names = [t["topic_metadata"]["name"] for t in info["topics_with_message_count"]]
    return names.index(topic)


def _topic(field: str, value: object, topic: str = STATE_BLOCK) -> Damage:
    """A field of one topic's entry (topic_metadata.<field>, or message_count) set to value."""

    def change(info: dict[str, Any]) -> None:
        entry = info["topics_with_message_count"][_topic_index(info, topic)]
        if field == "message_count":
            entry["message_count"] = value
        elif field.startswith("qos."):
            entry["topic_metadata"]["offered_qos_profiles"][0][field[4:]] = value
        else:
            entry["topic_metadata"][field] = value

    return _meta(change)


def _drop_topic(info: dict[str, Any]) -> None:
    del info["topics_with_message_count"][_topic_index(info, BAND_BLOCK)]


def _duplicate_topic(info: dict[str, Any]) -> None:
    topics = info["topics_with_message_count"]
    topics.append(copy.deepcopy(topics[_topic_index(info, BAND_BLOCK)]))


def _extra_topic(info: dict[str, Any]) -> None:
    topics = info["topics_with_message_count"]
    extra = copy.deepcopy(topics[_topic_index(info, BAND_BLOCK)])
    extra["topic_metadata"]["name"] = f"{NS}/not_recorded"
    topics.append(extra)


def _delete(key: str) -> Damage:
    return _meta(lambda info: info.pop(key))


def _custom(change: Callable[[dict[str, str]], None]) -> Damage:
    return _meta(lambda info: change(info["custom_data"]))


def _text(text: str | bytes) -> Damage:
    def damage(bag: Path) -> None:
        target = bag / "metadata.yaml"
        if isinstance(text, bytes):
            target.write_bytes(text)
        else:
            target.write_text(text)

    return damage


def _no_metadata(bag: Path) -> None:
    (bag / "metadata.yaml").unlink()


def _rename_mcap(bag: Path) -> None:
    (bag / "bag.mcap").rename(bag / "renamed.mcap")


def _no_mcap(bag: Path) -> None:
    (bag / "bag.mcap").unlink()


def _empty_mcap(bag: Path) -> None:
    (bag / "bag.mcap").write_bytes(b"")


def _truncate(fraction: float) -> Damage:
    def damage(bag: Path) -> None:
        data = (bag / "bag.mcap").read_bytes()
        (bag / "bag.mcap").write_bytes(data[: int(len(data) * fraction)])

    return damage


def _flip_chunk(bag: Path) -> None:
    mcap = bag / "bag.mcap"
    with open(mcap, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[2]
    data = bytearray(mcap.read_bytes())
    data[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0x10
    mcap.write_bytes(bytes(data))


def _both(first: Damage, second: Damage) -> Damage:
    def damage(bag: Path) -> None:
        first(bag)
        second(bag)

    return damage


def _all_fields(info: dict[str, Any]) -> None:
    """Every field metadata.yaml holds made to disagree with the file at once."""
    info["version"] = 8
    info["storage_identifier"] = "sqlite3"
    info["relative_file_paths"] = ["other.mcap"]
    info["duration"]["nanoseconds"] += 7
    info["starting_time"]["nanoseconds_since_epoch"] += 3
    info["message_count"] += 2
    info["compression_format"] = "zstd"
    info["compression_mode"] = "file"
    info["ros_distro"] = "humble"
    info["custom_data"]["lubrig_ros.version"] = "0.0.0"
    file = info["files"][0]
    file["path"] = "other.mcap"
    file["message_count"] += 2
    file["starting_time"]["nanoseconds_since_epoch"] += 3
    file["duration"]["nanoseconds"] += 7
    file["size"] = 12
    for entry in info["topics_with_message_count"]:
        tm = entry["topic_metadata"]
        tm["type"] = "std_msgs/msg/Empty"
        tm["serialization_format"] = "ros1"
        tm["offered_qos_profiles"][0]["depth"] = 7
        tm["type_description_hash"] = "RIHS01_" + "0" * 64
        entry["message_count"] += 1


#: Every field the all-at-once case changes, as `lubrig bag check` must name it.
ALL_FIELDS = (
    "version",
    "storage_identifier",
    "relative_file_paths",
    "duration",
    "starting_time",
    "message_count",
    "compression_format",
    "compression_mode",
    "ros_distro",
    "custom_data['lubrig_ros.version']",
    "files[0].path",
    "files[0].message_count",
    "files[0].starting_time",
    "files[0].duration",
    "files[0].size",
    "type is 'std_msgs/msg/Empty'",
    "serialization_format",
    "offered_qos_profiles depth",
    "type_description_hash",
    "counts",
)

# name -> (damage, text a problem line of `bag check` must hold, what repair must do)
# repair: "verifies" (every message kept, the output verifies), "not kept" (and it names what
# of the metadata it could not keep), "dropped" (the messages of the damaged part dropped and
# named), "refused" (exit 2, one line: nothing to rebuild from)
CASES: dict[str, tuple[Damage, str, str]] = {
    "version_older": (_set("version", 7), "metadata.yaml version is 7", "verifies"),
    "version_not_integer": (_set("version", "nine"), "version is 'nine', expected an integer", "verifies"),
    "storage_identifier": (
        _set("storage_identifier", "sqlite3"),
        "storage_identifier is 'sqlite3'",
        "verifies",
    ),
    "relative_file_paths_other": (
        _set("relative_file_paths", ["other.mcap"]),
        "relative_file_paths",
        "verifies",
    ),
    "relative_file_paths_empty": (_set("relative_file_paths", []), "relative_file_paths is []", "verifies"),
    "relative_file_paths_two": (
        _set("relative_file_paths", ["bag.mcap", "bag_1.mcap"]),
        "relative_file_paths",
        "verifies",
    ),
    "duration": (_shift("duration.nanoseconds", 1), "metadata.yaml duration is", "verifies"),
    "starting_time": (
        _shift("starting_time.nanoseconds_since_epoch", 5),
        "metadata.yaml starting_time is",
        "verifies",
    ),
    "message_count": (_shift("message_count", 1), "metadata.yaml message_count is", "verifies"),
    "message_count_text": (
        _set("message_count", "21"),
        "message_count is '21', expected an integer",
        "verifies",
    ),
    "compression_format": (_set("compression_format", "zstd"), "compression_format is 'zstd'", "verifies"),
    "compression_mode": (_set("compression_mode", "message"), "compression_mode is 'message'", "verifies"),
    "files_path": (_set("files.0.path", "other.mcap"), "files[0].path is 'other.mcap'", "verifies"),
    "files_message_count": (_shift("files.0.message_count", -1), "files[0].message_count", "verifies"),
    "files_starting_time": (
        _shift("files.0.starting_time.nanoseconds_since_epoch", 1),
        "files[0].starting_time",
        "verifies",
    ),
    "files_duration": (_shift("files.0.duration.nanoseconds", -1), "files[0].duration", "verifies"),
    "files_size": (_set("files.0.size", 99), "files[0].size is 99, the file has (bytes)", "verifies"),
    "files_two_entries": (
        _meta(lambda info: info["files"].append(copy.deepcopy(info["files"][0]))),
        "files lists",
        "verifies",
    ),
    "custom_data_run_config": (
        _custom(lambda c: c.update({"lubrig_ros.run_config": "name: edited\n"})),
        "custom_data['lubrig_ros.run_config'] differs",
        "not kept",
    ),
    "custom_data_key_removed": (
        _custom(lambda c: c.pop("lubrig_ros.version")),
        "custom_data has no 'lubrig_ros.version'",
        "verifies",
    ),
    "custom_data_key_added": (
        _custom(lambda c: c.update({"extra": "1"})),
        "custom_data['extra'] is not in the file's rosbag2 record",
        "not kept",
    ),
    "custom_data_not_mapping": (_set("custom_data", ["a"]), "custom_data is ['a']", "verifies"),
    "ros_distro": (_set("ros_distro", "jazzy"), "ros_distro is 'jazzy'", "not kept"),
    "ros_distro_removed": (_delete("ros_distro"), "ros_distro is nothing", "verifies"),
    "topic_name": (_topic("name", f"{NS}/state_blocks"), "does not list the file's channel", "verifies"),
    "topic_type": (
        _topic("type", "lubrig_interfaces/msg/RigState"),
        "type is 'lubrig_interfaces/msg/RigState'",
        "verifies",
    ),
    "topic_serialization_format": (
        _topic("serialization_format", "cdr2"),
        "serialization_format is 'cdr2'",
        "verifies",
    ),
    "topic_qos_depth": (_topic("qos.depth", 10), "offered_qos_profiles depth 10", "verifies"),
    "topic_qos_reliability": (
        _topic("qos.reliability", "best_effort"),
        "offered_qos_profiles reliability 'best_effort'",
        "verifies",
    ),
    "topic_qos_durability": (
        _topic("qos.durability", "transient_local", BAND_BLOCK),
        "offered_qos_profiles durability 'transient_local'",
        "verifies",
    ),
    "topic_qos_removed": (
        _topic("offered_qos_profiles", [], BAND_BLOCK),
        "offered_qos_profiles [] differ",
        "verifies",
    ),
    "topic_type_hash": (
        _topic("type_description_hash", "RIHS01_" + "1" * 64),
        "type_description_hash is",
        "verifies",
    ),
    "topic_message_count": (_topic("message_count", 3), "metadata.yaml counts 3 messages", "verifies"),
    "topic_message_count_negative": (
        _topic("message_count", -1, BAND_BLOCK),
        "counts -1 messages",
        "verifies",
    ),
    "topic_removed": (_meta(_drop_topic), "does not list the file's channel", "verifies"),
    "topic_duplicated": (_meta(_duplicate_topic), f"lists topic {BAND_BLOCK} twice", "verifies"),
    "topic_extra": (_meta(_extra_topic), "lists a topic the file has no channel for", "verifies"),
    "topics_not_list": (
        _set("topics_with_message_count", "none"),
        "topics_with_message_count is 'none'",
        "verifies",
    ),
    "topics_missing": (_delete("topics_with_message_count"), "has no topics_with_message_count", "verifies"),
    "starting_time_missing": (_delete("starting_time"), "has no starting_time", "verifies"),
    "all_fields": (_meta(_all_fields), "metadata.yaml version is 8", "not kept"),
    "yaml_syntax_error": (
        _text("rosbag2_bagfile_information: [unclosed\n"),
        "metadata.yaml is unreadable",
        "verifies",
    ),
    "yaml_empty": (_text(""), "metadata.yaml is unreadable", "verifies"),
    "yaml_not_mapping": (_text("- a\n- b\n"), "metadata.yaml is unreadable", "verifies"),
    "yaml_no_information": (_text("something_else: {}\n"), "metadata.yaml is unreadable", "verifies"),
    "yaml_binary": (_text(b"\xff\xfe\x00garbage\x81"), "metadata.yaml is unreadable", "verifies"),
    "metadata_deleted": (_no_metadata, "metadata.yaml is missing", "verifies"),
    "mcap_renamed": (
        _rename_mcap,
        "relative_file_paths is ['bag.mcap'], the bag's file is ['renamed.mcap']",
        "verifies",
    ),
    "mcap_deleted": (_no_mcap, "expected one .mcap file, found 0", "refused"),
    "mcap_empty": (_empty_mcap, "the .mcap file is empty", "refused"),
    "mcap_truncated_half": (_truncate(0.5), "runs past the end", "dropped"),
    "mcap_chunk_flipped": (_flip_chunk, "chunk", "dropped"),
    "mcap_truncated_and_yaml_garbage": (
        _both(_truncate(0.6), _text("{")),
        "metadata.yaml is unreadable",
        "dropped, not kept",
    ),
}


def messages(mcap: Path) -> dict[tuple[str, int], bytes]:
    """(topic, log time) -> payload, read by mcap with CRC validation (the independent reader)."""
    out = {}
    with open(mcap, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_summary() is not None
        for _schema, channel, message in reader.iter_messages():
            out[(channel.topic, message.log_time)] = message.data
    return out
