"""Replay of the current layout (blocks and RigState as recorded) and refusal of the legacy one."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
from rclpy.serialization import serialize_message

from lubrig_interfaces.msg import RigState, RigStateBlock
from lubrig_ros.app.plant.output import BLOCK_FIELDS
from lubrig_ros.bag import BagWriter
from lubrig_ros.bag.writer import typestore

T0 = 3_000_000_000


def _block(k0: int, n: int) -> RigStateBlock:
    m = RigStateBlock(
        sample_period=1e-3,
        first_sample_index=k0,
        segment=0,
        **{name: [0.01 * (i + 1)] * n for i, name in enumerate(BLOCK_FIELDS)},
    )
    m.displacement = [float(k) for k in range(k0, k0 + n)]
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(T0 + k0 * 1_000_000, 1_000_000_000)
    return m


def test_blocks_and_rig_states_replayed_as_recorded(procs, probe, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    w = BagWriter(bag)
    blocks = [_block(k0, 50) for k0 in range(0, 500, 50)]
    for m in blocks:
        w.write(
            "/lubrig/state_block",
            "lubrig_interfaces/msg/RigStateBlock",
            m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
            serialize_message(m),
        )
    states = [RigState(sample_index=k, displacement=float(k)) for k in range(200)]
    for k, m in enumerate(states):
        w.write(
            "/lubrig/state", "lubrig_interfaces/msg/RigState", T0 + k * 1_000_000 + 1, serialize_message(m)
        )
    w.close()
    probe.subscribe("/lubrig/state_block", RigStateBlock)
    probe.subscribe("/lubrig/state", RigState)
    replay = procs.module("lubrig_ros.nodes.replay", str(bag), "--rate", "4", "--wait-for-subscribers", "120")
    assert replay.wait(timeout=300) == 0, replay.log()
    assert "published 210 messages" in replay.output()
    assert probe.wait_for_count("/lubrig/state", 200, 120)
    assert probe.wait_for_count("/lubrig/state_block", 10, 120)
    got = probe.messages["/lubrig/state_block"]
    assert [m.first_sample_index for m in got] == [m.first_sample_index for m in blocks]
    for a, b in zip(got, blocks, strict=True):  # every field as recorded
        for name in ("sample_period", "segment", "header"):
            assert getattr(a, name) == getattr(b, name), name
        for name in BLOCK_FIELDS:
            assert list(getattr(a, name)) == list(getattr(b, name)), name
    assert [m.sample_index for m in probe.messages["/lubrig/state"]] == list(range(200))


def test_legacy_bag_is_refused_with_one_line_saying_what_to_do(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    ts = typestore()
    js, hdr, stamp = (
        ts.types[t]
        for t in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    w = BagWriter(bag)
    for k in range(5):
        msg = js(hdr(stamp(1, k), ""), ["mass"], np.array([float(k)]), np.zeros(1), np.zeros(1))
        w.write(
            "/lubrig/state",
            "sensor_msgs/msg/JointState",
            10**9 + k,
            bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/JointState")),
        )
        w.write("/lubrig/displacement", "std_msgs/msg/Float64", 10**9 + k, b"\x00\x01\x00\x00" + bytes(8))
    w.close()
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.nodes.replay", str(bag)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 2
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith("replay: error: bag ") and "legacy layout" in line, line
    assert "sensor_msgs/msg/JointState on /lubrig/state" in line
    assert f"`lubrig report {bag}` still reads the bag" in line
    assert "replay its other topics with --topics /lubrig/displacement" in line
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "lubrig_ros.nodes.replay",
            str(bag),
            "--topics",
            "displacement",
            "--rate",
            "100",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert "published 5 messages" in res.stdout
