"""Replay acceptance test: a recorded bag republished into a separate subscriber process."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
from ros_harness import ros_env, start_module

from lubrig_ros.bag import BagWriter

pytestmark = pytest.mark.ros
RATE_HZ, N = 200, 300  # 1.5 s per topic; log times 5 ms apart
TOPICS = ("/lubrig/displacement", "/lubrig/velocity")


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def test_replay_same_messages_in_order_with_timing(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    w = BagWriter(bag, run_config="a: 1\n")
    t0 = 5_000_000_000
    for k in range(N):
        for i, topic in enumerate(TOPICS):
            w.write(topic, "std_msgs/msg/Float64", t0 + k * 5_000_000 + i, _f64(k + 1000 * i))
    w.close()
    env = ros_env()
    out = tmp_path / "got.json"
    listener = start_module(
        "lubrig_ros.bag.synthetic", "listen", "--topics", *TOPICS, "--count", str(2 * N),
        "--timeout", "25", "--output", str(out), env=env,
    )
    with listener:
        listener.wait_for_output("listening")
        replay = start_module(
            "lubrig_ros.nodes.replay", str(bag), "--wait-for-subscribers", "15", env=env
        )
        with replay:
            assert replay.wait(timeout=30) == 0, replay.errors()
        assert listener.wait(timeout=30) == 0, listener.errors()
    got = json.loads(out.read_text())
    for i, topic in enumerate(TOPICS):
        mine = [(t, v) for name, t, v in got if name == topic]
        assert [v for _t, v in mine] == [float(k + 1000 * i) for k in range(N)]
        times = [(t - mine[0][0]) / 1e9 for t, _v in mine]
        errors = [abs(t - k / RATE_HZ) for k, t in enumerate(times)]
        assert max(errors) < 0.05, f"{topic}: timing error up to {max(errors) * 1e3:.1f} ms"


def test_sigint_during_a_long_gap_at_low_rate_stops_promptly(tmp_path: Path) -> None:
    """A 100 s gap in log times at --rate 0.01 is a 10^4 s wait: SIGINT must end it in about 1 s."""
    import signal
    import time

    bag = tmp_path / "bag"
    w = BagWriter(bag, run_config="a: 1\n")
    w.write(TOPICS[0], "std_msgs/msg/Float64", 1_000_000_000, _f64(1.0))
    w.write(TOPICS[0], "std_msgs/msg/Float64", 101_000_000_000, _f64(2.0))
    w.close()
    replay = start_module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "0.01", "--wait-for-subscribers", "0",
        env=ros_env(),
    )
    with replay:
        replay.wait_for_output("replay:")
        time.sleep(1.0)  # now in the gap
        sent = time.monotonic()
        status = replay.stop(signal.SIGINT, timeout=10)
        took = time.monotonic() - sent
        assert status == 0, replay.errors()
        assert took < 1.5, f"replay took {took:.1f} s to stop"
        assert "published 1 messages" in replay.output()
