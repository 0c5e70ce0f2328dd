"""app/recording/accounting.py (per-stream sample accounting), app/interface/cdr.sample_span; no DDS."""

from __future__ import annotations

import pytest
from rclpy.serialization import serialize_message
from rosbags.typesys import Stores, get_typestore

from lubrig_ros.app.interface.cdr import SampleSpan, sample_span
from lubrig_ros.app.recording.accounting import StreamAccount
from lubrig_ros.bag.layout import typestore

MS = 1_000_000  # 1 kHz: 1 ms of rig time per sample


def _per_sample(account: StreamAccount, indices, segment: int = 0, t0: int = 0) -> None:
    for k in indices:
        account.add(segment, k, 1, t0 + k * MS)


def test_complete_stream_per_sample_and_blocks() -> None:
    a = StreamAccount("/lubrig/state")
    _per_sample(a, range(1000))
    assert (a.samples, a.messages, a.missing, a.duplicates, a.out_of_order) == (1000, 1000, 0, 0, 0)
    assert a.complete and a.problems() == [] and a.taken(0) == 1000
    b = StreamAccount("/lubrig/state_block")
    b.add(0, 0, 1, 0, 1e6)  # the initial state alone, then blocks of 100
    for k in range(10):
        b.add(0, 1 + 100 * k, 100, (1 + 100 * k) * MS, 1e6)
    assert b.samples == 1001 and b.messages == 11 and b.complete and b.taken(0) == 1001
    assert b.summary()["segments"] == {"0": {"samples": 1001, "last_index": 1000, "announced": 0}}


def test_gap_is_counted_with_its_first_index_and_rig_time() -> None:
    a = StreamAccount("/lubrig/state")
    _per_sample(a, [*range(0, 500), *range(503, 1000)])  # 500, 501, 502 lost
    assert a.samples == 997 and a.missing == 3 and not a.complete
    (gap,) = a.gaps
    assert (gap.segment, gap.first_index, gap.count, gap.rig_time_ns) == (0, 500, 3, 500 * MS)
    (line,) = a.problems()
    assert line.startswith("/lubrig/state: 3 samples missing in 1 gap(s)")
    assert "from index 500 of segment 0 at rig time 0.500000 s" in line
    assert a.taken(0) == 500  # in order without gap: what a flow participant may report
    assert a.summary()["gaps"] == [{"segment": 0, "first_index": 500, "count": 3, "rig_time_s": 0.5}]


def test_gap_in_blocks_and_at_the_start_of_a_segment() -> None:
    b = StreamAccount("/lubrig/state_block")
    b.add(0, 0, 100, 0, 1e6)
    b.add(0, 200, 100, 200 * MS, 1e6)  # block 100..199 lost
    b.add(1, 50, 10, 7_000 * MS, 1e6)  # segment 1 starts at 50: 0..49 lost
    gaps = b.gaps
    assert [(g.segment, g.first_index, g.count) for g in gaps] == [(0, 100, 100), (1, 0, 50)]
    assert gaps[0].rig_time_ns == 100 * MS
    assert gaps[1].rig_time_ns == 7_000 * MS - 50 * MS
    assert b.missing == 150 and b.samples == 210


def test_duplicates_and_out_of_order() -> None:
    a = StreamAccount("/lubrig/state")
    _per_sample(a, [0, 1, 2, 4, 3, 5, 5, 1])
    assert a.samples == 6 and a.missing == 0  # 3 came late: no gap any more
    assert a.out_of_order == 1 and a.first_out_of_order is not None
    assert (a.first_out_of_order.index, a.first_out_of_order.rig_time_ns) == (3, 3 * MS)
    assert a.duplicates == 2 and a.first_duplicate is not None and a.first_duplicate.index == 5
    lines = a.problems()
    assert len(lines) == 2
    assert "2 duplicate samples; first: index 5 of segment 0" in lines[0]
    assert "1 samples out of order; first: index 3 of segment 0" in lines[1]


def test_block_overlapping_what_was_taken_counts_only_the_overlap_as_duplicates() -> None:
    b = StreamAccount("/lubrig/state_block")
    b.add(0, 0, 100, 0, 1e6)
    b.add(0, 90, 20, 90 * MS, 1e6)
    assert b.samples == 110 and b.duplicates == 10 and b.first_duplicate.index == 90
    assert b.taken(0) == 110


def test_segments_restart_the_index_and_an_older_segment_late_is_out_of_order() -> None:
    a = StreamAccount("/lubrig/state")
    _per_sample(a, range(10), segment=0)
    _per_sample(a, range(5), segment=1, t0=100 * MS)
    assert a.complete and a.taken(0) == 10 and a.taken(1) == 5 and a.samples == 15
    a.add(0, 10, 1, 10 * MS)  # a late sample of segment 0 after segment 1 began
    assert a.out_of_order == 1 and a.samples == 16 and a.missing == 0


def test_announced_tail_not_taken_is_a_gap() -> None:
    b = StreamAccount("/lubrig/state_block")
    b.add(0, 0, 100, 0, 1e6)
    b.announce(0, 300)
    assert b.behind() == 200
    (gap,) = b.gaps
    assert (gap.first_index, gap.count, gap.rig_time_ns) == (100, 200, 100 * MS)
    b.add(0, 100, 200, 100 * MS, 1e6)
    assert b.behind() == 0 and b.complete


def test_bad_values_are_refused_naming_them() -> None:
    with pytest.raises(ValueError, match="segment -1, first index 0, count 1"):
        StreamAccount("s").add(-1, 0, 1, 0)


# ------------------------------------------------------------------ the CDR reads, both serializers


def _rig_state(index: int, segment: int, frame_id: str = ""):
    from lubrig_interfaces.msg import RigState

    m = RigState(sample_index=index, segment=segment, displacement=1.5)
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = 2, 500, frame_id
    return m


@pytest.mark.parametrize("frame_id", ["", "a", "abcdefg", "rig frame 12345"])
def test_sample_span_of_rclpy_and_rosbags_cdr(frame_id: str) -> None:
    from lubrig_interfaces.msg import BandVelocityBlock, RigStateBlock

    msg = _rig_state(2**40 + 3, 7, frame_id)
    span = sample_span("lubrig_interfaces/msg/RigState", serialize_message(msg))
    assert span == SampleSpan(2_000_000_500, 7, 2**40 + 3, 1, None)
    block = RigStateBlock(
        sample_period=1e-3, first_sample_index=101, segment=2, displacement=[0.0] * 37, velocity=[0.0] * 37
    )
    block.header.frame_id = frame_id
    span = sample_span("lubrig_interfaces/msg/RigStateBlock", serialize_message(block))
    assert (span.segment, span.first_index, span.count, span.period_ns) == (2, 101, 37, 1e6)
    band = BandVelocityBlock(sample_period=2e-3, first_sample_index=5, segment=1, band_velocity=[1.0] * 3)
    band.header.frame_id = frame_id
    span = sample_span("lubrig_interfaces/msg/BandVelocityBlock", serialize_message(band))
    assert (span.segment, span.first_index, span.count, span.period_ns) == (1, 5, 3, 2e6)
    # rosbags' serializer (what a bag rewritten by rosbags holds) gives the same span
    ts = typestore()
    decoded = ts.deserialize_cdr(serialize_message(msg), "lubrig_interfaces/msg/RigState")
    again = bytes(ts.serialize_cdr(decoded, "lubrig_interfaces/msg/RigState"))
    assert sample_span("lubrig_interfaces/msg/RigState", again).first_index == 2**40 + 3


def test_sample_span_refuses_other_types_and_truncated_payloads() -> None:
    with pytest.raises(ValueError, match="carries no sample index"):
        sample_span("std_msgs/msg/Float64", b"\x00\x01\x00\x00" + bytes(8))
    data = serialize_message(_rig_state(1, 0))
    with pytest.raises(ValueError, match=r"truncated|too short"):
        sample_span("lubrig_interfaces/msg/RigState", data[:20])


def test_typestore_registers_every_interface_with_rosidls_type_hash() -> None:
    import json
    import sys
    from pathlib import Path

    share = Path(sys.prefix) / "share" / "lubrig_interfaces" / "msg"
    names = sorted(p.stem for p in share.glob("*.msg"))
    assert {
        "RigState",
        "RigStateBlock",
        "BandVelocityBlock",
        "FlowProgress",
        "WaveletFrame",
        "StabilityFlags",
    } <= set(names)
    ts = typestore()
    assert "lubrig_interfaces/msg/RigState" not in get_typestore(Stores.ROS2_KILTED).fielddefs
    for name in names:
        full = f"lubrig_interfaces/msg/{name}"
        described = json.loads((share / f"{name}.json").read_text())["type_hashes"]
        expected = next(h["hash_string"] for h in described if h["type_name"] == full)
        assert ts.hash_rihs01(full) == expected, name
