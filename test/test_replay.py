"""Replay acceptance test: a recorded bag republished into a separate subscriber process.

Asserted: the same messages, in order, /clock carrying each message's log time (relative stamps
preserved exactly), and pacing that never runs ahead of the bag's timing. How closely replay
follows the wall clock is a benchmark figure (bench/bench_replay.py).
"""

from __future__ import annotations

import json
import struct
import time
from pathlib import Path

from std_msgs.msg import Float64

from lubrig_ros.bag import BagWriter

RATE_HZ, N = 200, 300  # 1.5 s per topic; log times 5 ms apart
TOPICS = ("/lubrig/displacement", "/lubrig/velocity")
T0 = 5_000_000_000


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def test_replay_same_messages_in_order_with_their_log_times(procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    w = BagWriter(bag, run_config="a: 1\n")
    log_times = []
    for k in range(N):
        for i, topic in enumerate(TOPICS):
            t = T0 + k * 5_000_000 + i
            w.write(topic, "std_msgs/msg/Float64", t, _f64(k + 1000 * i))
            log_times.append(t)
    w.close()
    out = tmp_path / "got.json"
    listener = procs.module(
        "lubrig_testkit.synthetic",
        "listen",
        "--topics",
        *TOPICS,
        "/clock",
        "--count",
        str(4 * N),
        "--timeout",
        "120",
        "--output",
        str(out),
    )
    listener.wait_for_output("listening")
    started_ns = time.time_ns()
    replay = procs.module("lubrig_ros.nodes.replay", str(bag), "--clock", "--wait-for-subscribers", "60")
    assert replay.wait(timeout=120) == 0, replay.log()
    assert f"published {2 * N} messages" in replay.output()
    assert listener.wait(timeout=120) == 0, listener.log()
    got = json.loads(out.read_text())
    for i, topic in enumerate(TOPICS):
        mine = [v for name, _t, v in got if name == topic]
        assert mine == [float(k + 1000 * i) for k in range(N)]
    # /clock: the log time of every replayed message, in log-time order (relative stamps exact)
    clock = [v for name, _t, v in got if name == "/clock"]
    assert len(clock) == 2 * N
    assert [round(c * 1e9) for c in clock] == log_times
    # paced, never ahead of the bag: the last message cannot arrive before 1.495 s have passed
    last = max(t for name, t, _v in got if name in TOPICS)
    assert (last - started_ns) / 1e9 >= (log_times[-1] - log_times[0]) / 1e9


def test_sigint_during_a_long_gap_at_low_rate_stops(procs, probe, tmp_path: Path) -> None:
    """A 100 s gap in log times at --rate 0.01 is a 10^4 s wait: SIGINT must end it.

    (stop() allows 20 s, 500 times less than the gap; the stop latency is in bench/bench_replay.py)
    """
    import signal

    bag = tmp_path / "bag"
    w = BagWriter(bag, run_config="a: 1\n")
    w.write(TOPICS[0], "std_msgs/msg/Float64", 1_000_000_000, _f64(1.0))
    w.write(TOPICS[0], "std_msgs/msg/Float64", 101_000_000_000, _f64(2.0))
    w.close()
    probe.subscribe(TOPICS[0], Float64)
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "0.01", "--wait-for-subscribers", "60"
    )
    # the first message arrived: replay is now in the gap
    assert probe.wait_for_count(TOPICS[0], 1, 90), replay.log()
    status = replay.stop(signal.SIGINT, timeout=20)
    assert status == 0, replay.errors()
    assert "published 1 messages" in replay.output()
    assert [m.data for m in probe.messages[TOPICS[0]]] == [1.0]
