"""Per-stream sample continuity in `lubrig bag info` / `lubrig bag check` (issue 15).

Float64 streams (the old layout) are checked by log-time steps against the sample period; the
RigState / RigStateBlock streams of issue 12 by sample_index / first_sample_index + n and segment.
The RigState bags are serialized by rclpy (lubrig_interfaces, built by `make setup`) and written
with the mcap writer directly, as the recorder of issue 12 writes them.
"""

from __future__ import annotations

import struct
from pathlib import Path

from lubrig_testkit.cli import lubrig
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from lubrig_ros.app.plant.output import BLOCK_FIELDS
from lubrig_ros.bag import BagWriter
from lubrig_ros.bag.meta import metadata_dict, metadata_texts
from lubrig_ros.bag.verify import verify_bag

CONFIG = "simulation:\n  sample_rate: 1000\n"
MSG_DIR = Path(__file__).resolve().parents[1] / "lubrig_interfaces" / "msg"


def _float_bag(path: Path, skip: set[int], repeat: set[int]) -> None:
    w = BagWriter(path, run_config=CONFIG)
    for k in range(2000):
        if k in skip:
            continue
        for _ in range(2 if k in repeat else 1):
            w.write(
                "/lubrig/displacement",
                "std_msgs/msg/Float64",
                1_000_000_000 + k * 1_000_000,
                b"\x00\x01\x00\x00" + struct.pack("<d", float(k)),
            )
    w.close()


def _msg_bag(path: Path, msgtype: str, messages: list[tuple[int, object]]) -> None:
    """A rosbag2 bag of one custom-type topic written with the mcap writer."""
    from rclpy.serialization import serialize_message

    path.mkdir()
    name = msgtype.rsplit("/", 1)[1]
    topic = "/lubrig/state_block" if name.endswith("Block") else "/lubrig/state"
    with open(path / f"{path.name}.mcap", "wb") as f:
        w = McapWriter(f, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="test")
        sid = w.register_schema(msgtype, "ros2msg", (MSG_DIR / f"{name}.msg").read_bytes())
        cid = w.register_channel(topic, "cdr", sid, {"offered_qos_profiles": ""})
        for t, msg in messages:
            w.add_message(cid, t, serialize_message(msg), t)
        meta = metadata_dict(
            f"{path.name}.mcap",
            [(topic, msgtype, "", len(messages))],
            messages[0][0],
            messages[-1][0],
            {"lubrig_ros.run_config": CONFIG},
        )
        yaml_text, record = metadata_texts(meta)
        w.add_metadata("rosbag2", {"serialized_metadata": record})
        w.finish()
    (path / "metadata.yaml").write_text(yaml_text)


def _stamp(msg: object, ns: int) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)


def _blocks(spec: list[tuple[int, int, int]]) -> list[tuple[int, object]]:
    """RigStateBlock messages (segment, first index, n) at 1 kHz."""
    from lubrig_interfaces.msg import RigStateBlock

    out = []
    for segment, first, n in spec:
        msg = RigStateBlock(sample_period=1e-3, first_sample_index=first, segment=segment)
        t = 1_000_000_000 + segment * 100_000_000_000 + first * 1_000_000
        _stamp(msg, t)
        for name in BLOCK_FIELDS:
            setattr(msg, name, [float(k) for k in range(first, first + n)])
        out.append((t, msg))
    return out


def test_float64_gap_and_duplicate_named_by_info_and_check(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    _float_bag(bag, skip={500, 501, 502}, repeat={800})
    info = lubrig("bag", "info", str(bag))
    assert info.returncode == 0, info.stderr  # info shows gaps, it does not fail on them
    line = next(
        x for x in info.stdout.splitlines() if x.strip().startswith("/lubrig/displacement") and "gaps" in x
    )
    assert "gaps 1 (3 samples missing, first at 1.503000 s), duplicates 1 (first at 1.800000 s)" in line
    check = lubrig("bag", "check", str(bag))
    assert check.returncode == 1
    assert "topic /lubrig/displacement: gap: 3 samples missing before log time 1.503000 s" in check.stderr
    assert lubrig("bag", "info", "--verify", str(bag)).returncode == 1


def test_clean_float64_stream(tmp_path: Path) -> None:
    _float_bag(tmp_path / "bag", set(), set())
    v = verify_bag(tmp_path / "bag")
    assert v.ok and v.streams["/lubrig/displacement"].format() == "gaps 0, duplicates 0"


def test_rig_state_block_gaps_duplicates_segments(tmp_path: Path) -> None:
    spec = [
        (0, 0, 100),
        (0, 100, 100),
        (0, 300, 100),  # block 200..299 missing
        (0, 300, 100),  # the same block again
        (1, 0, 100),
        (1, 100, 50),
    ]  # a reset: segment 1 from sample 0
    _msg_bag(tmp_path / "bag", "lubrig_interfaces/msg/RigStateBlock", _blocks(spec))
    v = verify_bag(tmp_path / "bag")
    assert not v.structural, [p.line() for p in v.problems]
    rep = v.streams["/lubrig/state_block"]
    assert rep.method == "by first_sample_index"
    assert (rep.gaps, rep.missing, rep.duplicates, rep.segments) == (1, 100, 1, 2)
    assert rep.first_gap_s == 1.3 and rep.first_duplicate_s == 1.3
    assert rep.samples == 550  # duplicates included: what the bag holds
    first = v.problems[0]
    assert first.topic == "/lubrig/state_block"
    assert "100 samples missing before rig time 1.300000 s" in first.text
    res = lubrig("bag", "check", str(tmp_path / "bag"))
    assert res.returncode == 1 and "gap" in res.stderr and "/lubrig/state_block" in res.stderr


def test_rig_state_segment_restart_without_zero_is_a_gap(tmp_path: Path) -> None:
    from lubrig_interfaces.msg import RigState

    messages = []
    for segment, indices in ((0, range(0, 300)), (1, range(5, 100))):
        for k in indices:
            msg = RigState(sample_index=k, segment=segment, displacement=float(k))
            t = 1_000_000_000 + segment * 10_000_000_000 + k * 1_000_000
            _stamp(msg, t)
            messages.append((t, msg))
    _msg_bag(tmp_path / "bag", "lubrig_interfaces/msg/RigState", messages)
    rep = verify_bag(tmp_path / "bag").streams["/lubrig/state"]
    assert rep.method == "by sample_index"
    assert (rep.gaps, rep.missing, rep.duplicates, rep.segments, rep.samples) == (1, 5, 0, 2, 395)
    assert rep.first_gap_s == 11.005
