"""What rosbag2 writes and the rosbags writer did not: type hashes per channel, ros_distro.

rosbag2's MCAP storage plugin gives every channel the metadata keys `offered_qos_profiles` and
`topic_type_hash` (the topic's RIHS01 type hash, the same string as `type_description_hash` in
metadata.yaml), and rosbag2 records the ROS 2 distribution in `ros_distro`. Bags written by
BagWriter are read back with the `mcap` package's reader (CRCs validated, nothing of ours), the
hashes compared with metadata.yaml, the in-file "rosbag2" record and what rosidl generated for the
installed packages; verify, check and repair are run on them. ROS-free (no rclpy, no DDS).
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from lubrig_testkit.cli import lubrig
from mcap.reader import make_reader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

from lubrig_ros.bag import BagWriter, check_bag, layout, repair_bag
from lubrig_ros.bag.layout import PINNED_ROS_DISTRO, install_prefixes, ros_distro, typestore
from lubrig_ros.bag.meta import computed_type_hash, type_hash
from lubrig_ros.bag.verify import verify_bag
from lubrig_ros.bag.writer import make_qos, serialize_string

RIHS01 = re.compile(r"RIHS01_[0-9a-f]{64}")
#: ROS 2 distributions (rosbag2 writes ROS_DISTRO: lower-case names)
DISTROS = {"humble", "iron", "jazzy", "kilted", "lyrical", "rolling"}
#: topic -> type: stock types, a lubrig_interfaces one, and std_msgs/Char, whose `char` field
#: rosidl hashes as uint8 (rosbags' own hash_rihs01 does not)
TOPICS = {
    "/lubrig/run_config": "std_msgs/msg/String",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/lubrig/displacement": "std_msgs/msg/Float64",
    "/lubrig/flow_progress": "lubrig_interfaces/msg/FlowProgress",
    "/lubrig/code": "std_msgs/msg/Char",
}
N = 200
CDR_LE = b"\x00\x01\x00\x00"  # CDR encapsulation header, little endian


def _messages() -> list[tuple[str, str, int, bytes]]:
    ts = typestore()
    time, header = ts.types["builtin_interfaces/msg/Time"], ts.types["std_msgs/msg/Header"]
    clock, progress = ts.types["rosgraph_msgs/msg/Clock"], ts.types["lubrig_interfaces/msg/FlowProgress"]
    out: list[tuple[str, str, int, bytes]] = []

    def add(topic: str, t: int, data: bytes) -> None:
        out.append((topic, TOPICS[topic], t, data))

    add("/lubrig/run_config", 0, serialize_string("a: 1\n"))
    for k in range(N):
        t = 1_000_000_000 + k * 1_000_000
        stamp = time(*divmod(t, 10**9))
        add("/clock", t, bytes(ts.serialize_cdr(clock(stamp), TOPICS["/clock"])))
        add("/lubrig/displacement", t, CDR_LE + struct.pack("<d", k))
        add("/lubrig/code", t, CDR_LE + bytes([65 + k % 26]))
        if k % 50 == 0:
            msg = progress(header(stamp, ""), "/lubrig/lubrig_recorder", 0, k)
            add("/lubrig/flow_progress", t, bytes(ts.serialize_cdr(msg, TOPICS["/lubrig/flow_progress"])))
    return out


def _write(path: Path, finalize: bool = True) -> BagWriter:
    w = BagWriter(path, run_config="a: 1\n", flush_messages=100)
    w.add_topic("/lubrig/run_config", TOPICS["/lubrig/run_config"], 1, True)
    for topic, msgtype, t, data in _messages():
        w.write(topic, msgtype, t, data)
    if finalize:
        w.close()
    else:
        w.flush()
    return w


def _write_rosbags(path: Path) -> None:
    """A bag as the rosbags writer made them before issue 15: no topic_type_hash, ros_distro rosbags."""
    w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    w.open()
    conns = {}
    for topic, msgtype, t, data in _messages():
        if topic not in conns:
            conns[topic] = w.add_connection(
                topic, msgtype, typestore=typestore(), offered_qos_profiles=[make_qos(1000, False)]
            )
        w.write(conns[topic], t, data)
    w.close()


def _fields(bag: Path) -> tuple[dict[str, str], str]:
    """(topic -> topic_type_hash, ros_distro) of a bag, asserting that every copy agrees.

    The channels as the mcap reader gives them (CRCs validated), metadata.yaml and the in-file
    "rosbag2" record (serialized_metadata) must name the same hash per topic and the same distro.
    """
    (mcap,) = bag.glob("*.mcap")
    with open(mcap, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None
        channels = {
            c.topic: (summary.schemas[c.schema_id].name, dict(c.metadata)) for c in summary.channels.values()
        }
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
        stats = summary.statistics
        assert stats is not None and sum(1 for _ in reader.iter_messages()) == stats.message_count
    hashes = {}
    for topic, (msgtype, meta) in channels.items():
        assert set(meta) == {"offered_qos_profiles", "topic_type_hash"}, topic
        assert RIHS01.fullmatch(meta["topic_type_hash"]), (topic, meta["topic_type_hash"])
        assert meta["topic_type_hash"] == type_hash(msgtype), topic
        hashes[topic] = meta["topic_type_hash"]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (record,) = records
    in_file = yaml.safe_load(record.metadata["serialized_metadata"])
    for copy in (info, in_file):
        listed = {
            t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
            for t in copy["topics_with_message_count"]
        }
        assert listed == hashes
    assert info["ros_distro"] == in_file["ros_distro"]
    return hashes, info["ros_distro"]


def _rosidl_hash(msgtype: str) -> str | None:
    """The hash rosidl generated for msgtype (its installed .json type description), None if absent."""
    package, kind, name = msgtype.split("/")
    for prefix in install_prefixes():
        path = prefix / "share" / package / kind / f"{name}.json"
        if path.is_file():
            entries = json.loads(path.read_text())["type_hashes"]
            return next(e["hash_string"] for e in entries if e["type_name"] == msgtype)
    return None


@pytest.fixture(autouse=True)
def _no_ros_distro(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROS_DISTRO", raising=False)


def test_channels_carry_the_type_hash_of_metadata_yaml_and_a_real_distro(tmp_path: Path) -> None:
    _write(tmp_path / "bag")
    hashes, distro = _fields(tmp_path / "bag")
    assert set(hashes) == set(TOPICS)
    assert distro in DISTROS and distro == ros_distro()
    # the wheels requirements.txt pins (unprefixed ros-*, rclpy 9.1) are the Kilted line
    assert distro == PINNED_ROS_DISTRO == "kilted"


def test_type_hashes_are_the_ones_rosidl_generated(tmp_path: Path) -> None:
    _write(tmp_path / "bag")
    hashes, _distro = _fields(tmp_path / "bag")
    checked = 0
    for topic, msgtype in TOPICS.items():
        expected = _rosidl_hash(msgtype)
        if expected is not None:
            assert hashes[topic] == expected, topic
            checked += 1
    assert checked == len(TOPICS)  # make setup installs every one of them


def test_computed_hash_is_rosidls_for_every_installed_type() -> None:
    """The fallback (no installed type description) gives rosidl's hash too, char fields included."""
    described = {}
    for path in sorted((Path(install_prefixes()[0]) / "share").glob("*/msg/*.json")):
        for entry in json.loads(path.read_text())["type_hashes"]:
            described[entry["type_name"]] = entry["hash_string"]
    if not described:
        pytest.skip("no rosidl type descriptions installed")
    known = {name: h for name, h in described.items() if name in typestore().fielddefs}
    assert len(known) > 100 and "std_msgs/msg/Char" in known and "rmw_dds_common/msg/Gid" in known
    wrong = {name for name, h in known.items() if computed_type_hash(name) != h}
    assert not wrong


def test_verify_check_and_cli_accept_the_fields(tmp_path: Path) -> None:
    _write(tmp_path / "bag")
    v = verify_bag(tmp_path / "bag")
    assert v.ok, v.verdict()
    assert {t.name: t.count for t in check_bag(tmp_path / "bag").topics}["/lubrig/code"] == N
    res = lubrig("bag", "check", str(tmp_path / "bag"))
    assert res.returncode == 0, res.stderr


def test_repair_reproduces_hashes_and_distro(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_DISTRO", "jazzy")  # a bag recorded elsewhere, repaired here
    _write(tmp_path / "bag")
    monkeypatch.delenv("ROS_DISTRO")
    hashes, distro = _fields(tmp_path / "bag")
    assert distro == "jazzy"
    report = repair_bag(tmp_path / "bag", force=True, output=tmp_path / "forced")
    assert report.rewritten and verify_bag(tmp_path / "forced").ok
    assert _fields(tmp_path / "forced") == (hashes, "jazzy")  # from the old metadata.yaml
    (tmp_path / "bag" / "metadata.yaml").unlink()
    repair_bag(tmp_path / "bag", output=tmp_path / "no_yaml")
    assert verify_bag(tmp_path / "no_yaml").ok
    assert _fields(tmp_path / "no_yaml") == (hashes, "jazzy")  # from the file's "rosbag2" record


def test_repair_of_an_unfinalized_bag_writes_the_fields(tmp_path: Path) -> None:
    _write(tmp_path / "crashed", finalize=False)
    assert not (tmp_path / "crashed" / "metadata.yaml").exists()
    repair_bag(tmp_path / "crashed", output=tmp_path / "repaired")
    assert verify_bag(tmp_path / "repaired").ok
    hashes, distro = _fields(tmp_path / "repaired")
    assert set(hashes) == set(TOPICS) and distro == ros_distro()  # no record survived: this one's


def test_repair_gives_an_old_bag_the_type_hash(tmp_path: Path) -> None:
    _write_rosbags(tmp_path / "old")
    with open(tmp_path / "old" / "old.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        assert all("topic_type_hash" not in c.metadata for c in summary.channels.values())
    assert verify_bag(tmp_path / "old").structural == []  # an old bag still verifies
    repair_bag(tmp_path / "old", force=True, output=tmp_path / "new")
    hashes, distro = _fields(tmp_path / "new")
    assert hashes == {topic: _rosidl_hash(msgtype) for topic, msgtype in TOPICS.items()}
    assert distro == ros_distro() != "rosbags"


@pytest.mark.parametrize(
    ("installed", "expected"),
    [
        ({"ros-rclpy": "9.1.2"}, "kilted"),  # the unprefixed wheels: the line of their rclpy
        ({"ros_jazzy_rclpy": "7.1.5"}, "jazzy"),  # a prefixed wheel set names it
        ({"rclpy": "4.1.7"}, "iron"),  # a ROS install's or colcon build's rclpy
        ({"ros-rclpy": "99.0.0"}, None),  # a line not known here
        ({}, None),
    ],
)
def test_installed_ros_distro_from_package_metadata(
    monkeypatch: pytest.MonkeyPatch, installed: dict[str, str], expected: str | None
) -> None:
    from importlib import metadata

    def version(name: str) -> str:
        if name not in installed:
            raise metadata.PackageNotFoundError(name)
        return installed[name]

    fake = SimpleNamespace(
        version=version,
        distributions=lambda: [SimpleNamespace(metadata={"Name": n}) for n in installed],
        PackageNotFoundError=metadata.PackageNotFoundError,
    )
    monkeypatch.setattr(layout, "metadata", fake)
    layout.installed_ros_distro.cache_clear()
    try:
        assert layout.installed_ros_distro() == expected
        assert ros_distro() == (expected or PINNED_ROS_DISTRO)
        monkeypatch.setenv("ROS_DISTRO", "rolling")  # a sourced ROS environment says so: as rosbag2
        assert ros_distro() == "rolling"
    finally:
        layout.installed_ros_distro.cache_clear()
