"""BagWriter (mcap package, CRCs) against the rosbags writer it replaced (issue 15).

The same input written both ways gives the same rosbag2 bag apart from the CRCs and the writer's
name: identical message payloads, log and publish times, schemas (name, encoding ros2msg, text),
channels (topic, encoding cdr, offered QoS), header profile ros2 and metadata.yaml; plus what
rosbag2 writes and rosbags does not (issue 20): each channel's `topic_type_hash` and the real
`ros_distro`. Read back with the mcap reader (CRCs validated) and rosbags.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import yaml
from mcap.reader import make_reader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

from lubrig_ros.bag import BagWriter
from lubrig_ros.bag.layout import RUN_CONFIG_KEY, VERSION_KEY, ros_distro
from lubrig_ros.bag.verify import verify_bag
from lubrig_ros.bag.writer import make_qos, serialize_string, typestore

CONFIG = "plant:\n  mass_kg: 1.0\n"


def _inputs() -> list[tuple[str, str, int, bytes]]:
    ts = typestore()
    js, hdr, stamp = (
        ts.types[n]
        for n in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    clock = ts.types["rosgraph_msgs/msg/Clock"]
    rng = np.random.default_rng(15)
    out = [("/lubrig/run_config", "std_msgs/msg/String", 0, serialize_string(CONFIG))]
    for k in range(2500):
        t = 1_000_000_000 + k * 1_000_000
        sec, nsec = divmod(t, 10**9)
        out.append(
            (
                "/clock",
                "rosgraph_msgs/msg/Clock",
                t,
                bytes(ts.serialize_cdr(clock(stamp(sec, nsec)), "rosgraph_msgs/msg/Clock")),
            )
        )
        out.append(
            (
                "/lubrig/displacement",
                "std_msgs/msg/Float64",
                t,
                b"\x00\x01\x00\x00" + struct.pack("<d", float(rng.normal())),
            )
        )
        state = js(
            hdr(stamp(sec, nsec), ""), ["mass"], rng.normal(size=1), rng.normal(size=1), rng.normal(size=1)
        )
        out.append(
            (
                "/lubrig/state",
                "sensor_msgs/msg/JointState",
                t,
                bytes(ts.serialize_cdr(state, "sensor_msgs/msg/JointState")),
            )
        )
    return out


def _write_rosbags(path: Path, inputs: list[tuple[str, str, int, bytes]]) -> None:
    """What BagWriter did before issue 15 (rosbags rosbag2 Writer, MCAP, zstd chunks)."""
    w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    w.set_custom_data(VERSION_KEY, "0.1.0")
    w.set_custom_data(RUN_CONFIG_KEY, CONFIG)
    w.open()
    conns = {}
    for topic, msgtype, t, data in inputs:
        if topic not in conns:
            latched = topic.endswith("run_config")
            conns[topic] = w.add_connection(
                topic,
                msgtype,
                typestore=typestore(),
                offered_qos_profiles=[make_qos(1 if latched else 1000, latched)],
            )
        w.write(conns[topic], t, data)
    w.close()


def _write_new(path: Path, inputs: list[tuple[str, str, int, bytes]]) -> BagWriter:
    w = BagWriter(path, run_config=CONFIG)
    w.custom_data[VERSION_KEY] = "0.1.0"
    w.add_topic("/lubrig/run_config", "std_msgs/msg/String", 1, True)
    for topic, msgtype, t, data in inputs:
        w.write(topic, msgtype, t, data)
    w.close()
    return w


def _content(bag: Path) -> dict[str, object]:
    (mcap,) = bag.glob("*.mcap")
    with open(mcap, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        header = reader.get_header()
        messages = [(c.topic, m.log_time, m.publish_time, m.data) for _s, c, m in reader.iter_messages()]
    return {
        "profile": header.profile,
        "schemas": sorted((s.name, s.encoding, s.data) for s in summary.schemas.values()),
        "channels": sorted(
            (
                c.topic,
                c.message_encoding,
                summary.schemas[c.schema_id].name,
                tuple(sorted(c.metadata.items())),
            )
            for c in summary.channels.values()
        ),
        "messages": messages,
        "metadata": yaml.safe_load((bag / "metadata.yaml").read_text().replace(mcap.name, "X.mcap")),
    }


def test_same_bag_as_the_rosbags_writer_but_with_crcs(tmp_path: Path) -> None:
    inputs = _inputs()
    _write_rosbags(tmp_path / "old", inputs)
    writer = _write_new(tmp_path / "new", inputs)
    old, new = _content(tmp_path / "old"), _content(tmp_path / "new")
    assert len(new["messages"]) == len(inputs)
    assert new["messages"] == old["messages"]  # payloads bit-identical, same times, same order
    for key in ("profile", "schemas"):
        assert new[key] == old[key], key
    # the channels carry the type hash as rosbag2's MCAP plugin writes it; the rest is unchanged
    hashes = {topic: dict(meta)["topic_type_hash"] for topic, _e, _s, meta in new["channels"]}
    unhashed = [
        (t, e, s, tuple(kv for kv in m if kv[0] != "topic_type_hash")) for t, e, s, m in new["channels"]
    ]
    assert unhashed == old["channels"]
    new_info, old_info = (
        new["metadata"]["rosbag2_bagfile_information"],
        old["metadata"]["rosbag2_bagfile_information"],
    )
    assert {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
        for t in new_info["topics_with_message_count"]
    } == hashes
    assert all(h.startswith("RIHS01_") for h in hashes.values())
    assert (old_info.pop("ros_distro"), new_info.pop("ros_distro")) == ("rosbags", ros_distro())
    assert new["metadata"] == old["metadata"]
    assert writer.chunks_flushed > 1  # the flush bound closed chunks along the way
    # every chunk and the summary carry a CRC-32 (the rosbags bag has none)
    with open(tmp_path / "new" / "new.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert verify_bag(tmp_path / "new").ok and not verify_bag(tmp_path / "new").notes
    assert any("no CRC" in note for note in verify_bag(tmp_path / "old").notes)
    assert len(summary.chunk_indexes) == writer.chunks_flushed


def test_flush_bound_rig_time_and_messages(tmp_path: Path) -> None:
    """A chunk spans less than 0.2 s of log time and at most flush_messages messages."""
    w = BagWriter(tmp_path / "a", flush_period_ns=200_000_000, flush_messages=300)
    for k in range(3000):  # 1 kHz, 2 topics: the message bound (300 = 0.15 s) comes first
        for topic in ("/x", "/y"):
            w.write(topic, "std_msgs/msg/Float64", k * 1_000_000, b"\x00\x01\x00\x00" + struct.pack("<d", k))
        assert w.pending < 300
    w.close()
    w = BagWriter(tmp_path / "b", flush_period_ns=200_000_000, flush_messages=10_000)
    for k in range(3000):  # now the rig-time bound: 0.2 s = 200 samples x 2 topics
        for topic in ("/x", "/y"):
            w.write(topic, "std_msgs/msg/Float64", k * 1_000_000, b"\x00\x01\x00\x00" + struct.pack("<d", k))
    w.close()
    for name, most in (("a", 300), ("b", 402)):
        with open(tmp_path / name / f"{name}.mcap", "rb") as f:
            chunks = make_reader(f).get_summary().chunk_indexes
        assert all(c.message_end_time - c.message_start_time <= 200_000_000 for c in chunks)
        sizes = []
        with open(tmp_path / name / f"{name}.mcap", "rb") as f:
            reader = make_reader(f)
            for c in chunks:
                sizes.append(
                    sum(
                        1
                        for _ in reader.iter_messages(
                            starting_at=c.message_start_time, ending_at=c.message_end_time
                        )
                    )
                )
        assert max(sizes) <= most, (name, max(sizes))
