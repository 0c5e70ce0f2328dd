"""Bags of the current layout (lubrig_interfaces types) and of the legacy layout, without DDS.

Messages are serialized by rclpy (the generated types the nodes publish) and written with
BagWriter (the recorder's writer); they are read back by two independent readers that use only
what is stored in the file (mcap + mcap_ros2 from the MCAP schemas, rosbags' AnyReader from the
bag's message definitions), and by report/frombag (current and legacy layout, gaps).
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from lubrig_interfaces.msg import (
    BandVelocityBlock,
    FlowProgress,
    RigState,
    RigStateBlock,
    StabilityFlags,
    WaveletFrame,
)
from lubrig_ros.app.plant.output import BLOCK_FIELDS, BeltTravel, trajectory_columns
from lubrig_ros.bag import BagWriter, read_arrays
from lubrig_ros.bag.writer import serialize_string
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.report import trajectory_from_bag
from lubrig_ros.report.frombag import recording_summary

NS = "/lubrig"
FIELDS = BLOCK_FIELDS


def _stamp(msg, ns: int) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)


def _values(traj, config, k0: int, k1: int) -> dict[str, np.ndarray]:
    travel = BeltTravel().add_many(traj.time, traj.band_velocity)
    columns = trajectory_columns(traj, travel, config.rig.friction.normal_force)
    return {name: column[k0:k1] for name, column in columns.items()}


def _write_run(
    path: Path,
    duration: float = 1.0,
    block: int = 100,
    per_sample: bool = False,
    drop_blocks: tuple[int, ...] = (),
):
    """A core run written in the current layout: state_block (sim) or RigState per sample."""
    config = load_case(1).with_overrides(duration=duration)
    traj = simulate(config)
    w = BagWriter(path, run_config=config.to_yaml())
    w.write(f"{NS}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    n = len(traj)
    ns_of = lambda k: round(float(traj.time[k]) * 1e9)  # noqa: E731
    if per_sample:
        for k in range(n):
            m = RigState(sample_index=k, segment=0)
            _stamp(m, ns_of(k))
            for name, col in _values(traj, config, k, k + 1).items():
                setattr(m, name, float(col[0]))
            w.write(f"{NS}/state", "lubrig_interfaces/msg/RigState", ns_of(k), serialize_message(m))
    else:
        starts = [0, *range(1, n, block)]  # the initial state alone, then blocks (as the plant)
        for b, k0 in enumerate(starts):
            k1 = 1 if b == 0 else min(k0 + block, n)
            if b in drop_blocks:
                continue
            m = RigStateBlock(sample_period=1.0 / config.sample_rate, first_sample_index=k0, segment=0)
            _stamp(m, ns_of(k0))
            for name, col in _values(traj, config, k0, k1).items():
                setattr(m, name, col.tolist())
            w.write(
                f"{NS}/state_block", "lubrig_interfaces/msg/RigStateBlock", ns_of(k0), serialize_message(m)
            )
    w.close()
    return config, traj


def test_state_blocks_rebuild_the_core_run_bit_for_bit(tmp_path: Path) -> None:
    config, traj = _write_run(tmp_path / "bag", duration=1.0, block=100)
    cfg, rebuilt = trajectory_from_bag(tmp_path / "bag")
    assert cfg.to_yaml() == config.to_yaml() and len(rebuilt) == len(traj) == 1001
    for name in ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity"):
        np.testing.assert_array_equal(getattr(rebuilt, name), getattr(traj, name), err_msg=name)
    np.testing.assert_allclose(rebuilt.time, traj.time, rtol=0, atol=1e-12)  # k / rate vs k * dt
    arrays = read_arrays(tmp_path / "bag")[f"{NS}/state_block"]  # one entry per sample
    assert arrays["sample_index"].tolist() == list(range(1001))
    assert recording_summary(tmp_path / "bag")["problems"] == []


def test_rig_state_per_sample_rebuilds_the_core_run(tmp_path: Path) -> None:
    _config, traj = _write_run(tmp_path / "bag", duration=0.5, per_sample=True)
    _, rebuilt = trajectory_from_bag(tmp_path / "bag")
    np.testing.assert_array_equal(rebuilt.displacement, traj.displacement)
    np.testing.assert_allclose(rebuilt.time, traj.time, rtol=0, atol=1e-12)
    summary = recording_summary(tmp_path / "bag")
    assert summary["streams"][f"{NS}/state"]["samples"] == 501 and summary["problems"] == []


def test_gap_is_named_and_marked_in_the_report(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    _config, _traj = _write_run(bag, duration=1.0, block=100, drop_blocks=(3,))  # samples 201..300
    summary = recording_summary(bag)
    (gap,) = summary["streams"][f"{NS}/state_block"]["gaps"]
    assert (gap["segment"], gap["first_index"], gap["count"]) == (0, 201, 100)
    assert gap["rig_time_s"] == pytest.approx(0.201, abs=1e-9)
    assert "100 samples missing in 1 gap(s)" in summary["problems"][0]
    _, rebuilt = trajectory_from_bag(bag)  # the samples that are there, without the gap
    assert len(rebuilt) == 901
    out = tmp_path / "report"
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", "report", str(bag), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    page = (out / "report.md").read_text()
    assert "**INCOMPLETE**" in page
    assert "**gap**: 100 samples from index 201 of segment 0 at rig time 0.201000 s" in page
    recorded = json.loads((out / "summary.json").read_text())["recording"]
    assert recorded["streams"][f"{NS}/state_block"]["missing"] == 100


def _every_custom_type() -> list[tuple[str, str, object]]:
    """(topic, type, message) with non-trivial values for each lubrig_interfaces message."""
    state = RigState(
        sample_index=7,
        segment=2,
        **{name: 1e-3 * (i + 1) for i, name in enumerate(BLOCK_FIELDS)},
    )
    block = RigStateBlock(
        sample_period=1e-3,
        first_sample_index=11,
        segment=1,
        **{name: [2.0 * i + 1.0, 2.0 * i + 2.0] for i, name in enumerate(BLOCK_FIELDS)},
    )
    band = BandVelocityBlock(sample_period=1e-3, first_sample_index=3, segment=1, band_velocity=[0.5, 0.25])
    progress = FlowProgress(participant="/lubrig/lubrig_recorder", segment=1, samples=1234)
    frame = WaveletFrame(frequency=[100.0, 50.0, 25.0], rows=3, cols=2, power=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    frame.start.sec, frame.end.sec, frame.end.nanosec = 1, 1, 1_000_000
    flags = StabilityFlags(
        linear_zone=StabilityFlags.ZONE_FALLING,
        band_velocity=1e-4,
        damping_ratio=0.01,
        critical_damping_ratio=0.05,
        effective_damping=-0.08,
        linear_stable=False,
        oscillation=StabilityFlags.OSCILLATION_GROWING,
        oscillation_growing=True,
        growth_rate=1.5,
        growth_fit_r2=0.9,
        sticking=True,
        stick_threshold=1e-5,
        stick_share=0.25,
        stick_episodes=4,
        longest_stick=0.02,
        resonance=True,
        resonance_harmonic=2,
    )
    msgs = [
        ("state", state),
        ("state_block", block),
        ("band_velocity_block", band),
        ("flow_progress", progress),
        ("wavelet_frame", frame),
        ("stability", flags),
    ]
    out = []
    for i, (topic, msg) in enumerate(msgs):
        _stamp(msg, 2_000_000_000 + i)
        out.append((f"{NS}/{topic}", f"lubrig_interfaces/msg/{type(msg).__name__}", msg))
    return out


def _plain(value: object) -> object:
    """Field values comparable across readers (sequences as lists, messages as dicts of fields)."""
    if hasattr(value, "get_fields_and_field_types"):  # rclpy message
        return {n: _plain(getattr(value, n)) for n in value.get_fields_and_field_types()}
    if dataclasses.is_dataclass(value):  # rosbags message; ROS constants are UPPER_CASE
        return {
            f.name: _plain(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if f.name != "__msgtype__" and f.name.lower() == f.name
        }
    if hasattr(value, "__slots__") and not isinstance(value, (list, tuple, np.ndarray)):  # mcap_ros2
        return {n: _plain(getattr(value, n)) for n in value.__slots__ if n.lower() == n}
    if isinstance(value, (list, tuple, np.ndarray)) or type(value).__name__ == "array":
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


def test_every_custom_type_is_decoded_by_two_independent_readers(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    msgs = _every_custom_type()
    w = BagWriter(bag)
    for i, (topic, msgtype, msg) in enumerate(msgs):
        w.write(topic, msgtype, 2_000_000_000 + i, serialize_message(msg))
    w.close()
    expected = {topic: _plain(msg) for topic, _t, msg in msgs}
    # mcap + mcap_ros2: decoded from the schemas stored in the MCAP file only
    (path,) = bag.glob("*.mcap")
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        schemas = {s.name: s for s in reader.get_summary().schemas.values()}
        got = {ch.topic: _plain(m) for _s, ch, _m, m in reader.iter_decoded_messages()}
    for _topic, msgtype, _msg in msgs:
        schema = schemas[msgtype]
        assert schema.encoding == "ros2msg" and b"MSG: std_msgs/Header" in schema.data, msgtype
    assert got == expected
    # rosbags: the stock Kilted type store knows none of them; AnyReader takes the bag's definitions
    stock = get_typestore(Stores.ROS2_KILTED)
    assert not any(msgtype in stock.fielddefs for _t, msgtype, _m in msgs)
    with AnyReader([bag], default_typestore=stock) as reader:
        got = {c.topic: _plain(reader.deserialize(d, c.msgtype)) for c, _t, d in reader.messages()}
    assert got == expected
