"""Driving a replay: its services and parameters, --until, and a lossless replay to a slow subscriber.

The replay runs in its own process; what it does is asserted on what a subscriber in another
process (the probe) receives: which messages, in which order, each once. Pacing is asserted only
where it decides which messages arrive at all (a 1000 s gap that a rate change makes short),
never as a wall-clock rate.
"""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rcl_interfaces.srv import GetParameters
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from lubrig_interfaces.msg import RigStateBlock
from lubrig_interfaces.srv import Seek, SetRate
from lubrig_ros.app.plant.output import BLOCK_FIELDS
from lubrig_ros.bag import BagWriter, check_bag, read_arrays

T0 = 4_000_000_000
BLOCKS = "/lubrig/state_block"
TOPIC = "/lubrig/displacement"
NODE = "lubrig_replay"


def _block(k0: int, n: int, t_ns: int) -> bytes:
    m = RigStateBlock(sample_period=1e-3, first_sample_index=k0, segment=0)
    for name in BLOCK_FIELDS:  # every sample field (a block as the plant writes it)
        setattr(m, name, [float(k) for k in range(k0, k0 + n)])
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    return serialize_message(m)


def block_bag(path: Path, count: int, size: int, step_ns: int) -> Path:
    """count RigStateBlocks of size samples, block k at T0 + k step_ns (first sample k size)."""
    w = BagWriter(path)
    for k in range(count):
        t = T0 + k * step_ns
        w.write(BLOCKS, "lubrig_interfaces/msg/RigStateBlock", t, _block(k * size, size, t))
    w.close()
    return path


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def float_bag(path: Path, times_ns: list[int]) -> Path:
    """/lubrig/displacement with value k at times_ns[k]."""
    w = BagWriter(path)
    for k, t in enumerate(times_ns):
        w.write("/lubrig/displacement", "std_msgs/msg/Float64", t, _f64(k))
    w.close()
    return path


def trigger(probe: Any, service: str) -> Any:
    """Call an idempotent Trigger service of the replay (resent while unanswered)."""
    return probe.call(Trigger, f"/{NODE}/{service}", Trigger.Request(), timeout=60, resend=5.0)


def play_next(probe: Any, client: Any) -> Any:
    """One play_next: its answer, once the stepped message has arrived.

    Not idempotent, so it is sent again only when neither an answer nor a message came in 30 s
    (a request sent before the service matched this client is lost).
    """
    before = len(probe.messages[BLOCKS])
    for _ in range(3):
        future = client.call_async(Trigger.Request())
        if probe.wait_for(lambda: future.done() or len(probe.messages[BLOCKS]) > before, 30):  # noqa: B023
            break
    assert probe.wait_for_count(BLOCKS, before + 1, 60)
    probe.wait_for(future.done, 10)
    return future.result() if future.done() else None


def firsts(probe: Any) -> list[int]:
    return [m.first_sample_index for m in probe.messages[BLOCKS]]


def test_paused_replay_steps_seeks_and_resumes_as_told(procs, probe, tmp_path: Path) -> None:
    bag = block_bag(tmp_path / "bag", 40, 10, 10_000_000)  # 40 blocks 10 ms apart: 0.39 s
    probe.subscribe(BLOCKS, RigStateBlock)
    replay = procs.module("lubrig_ros.nodes.replay", str(bag), "--paused", "--wait-for-subscribers", "60")
    answer = trigger(probe, "is_paused")
    assert answer.success and answer.message == "paused at 0 s", answer.message
    assert firsts(probe) == []  # paused: nothing published
    client = probe.node.create_client(Trigger, f"/{NODE}/play_next")
    assert client.wait_for_service(timeout_sec=60)
    answer = play_next(probe, client)
    assert answer is None or answer.message == f"published {BLOCKS} at 0 s", answer
    play_next(probe, client)
    assert firsts(probe) == [0, 10]  # one block per step
    # ~/seek (as rosbag2's player): the next message is the first at or after 0.195 s, block 20
    sought = probe.call(Seek, f"/{NODE}/seek", Seek.Request(time=0.195), timeout=60, resend=5.0)
    assert sought.success, sought.message
    answer = play_next(probe, client)
    assert answer is None or answer.message == f"published {BLOCKS} at 0.2 s", answer
    refused = probe.call(Seek, f"/{NODE}/seek", Seek.Request(time=5.0), timeout=60, resend=5.0)
    assert not refused.success and "seek" in refused.message, refused.message  # beyond the bag
    refused = probe.set_parameter(NODE, "seek", 5.0)  # the same check as a parameter
    assert not refused.successful and "seek" in refused.reason, refused.reason
    refused = probe.set_parameter(NODE, "rate", 0.0)
    assert not refused.successful
    assert refused.reason == "rate 0.0 is invalid: expected a time scale in (0, 1000]"
    refused = probe.set_parameter(NODE, "seek", "abc")
    assert not refused.successful
    assert refused.reason == "seek abc is invalid: expected seconds of bag time in [0, 0.39]"
    assert probe.set_parameter(NODE, "rate", 10).successful  # an integer is a time scale too
    assert firsts(probe) == [0, 10, 200]
    answer = trigger(probe, "resume")
    assert answer.success or answer.message.startswith("not paused"), answer.message
    assert replay.wait(timeout=120) == 0, replay.log()
    assert "published 22 messages" in replay.output()
    assert probe.wait_for_count(BLOCKS, 22, 60)
    # every message once, in order: the two steps, the seek's step, then the rest from block 21
    assert firsts(probe) == [0, 10, *range(200, 400, 10)]


def test_rate_parameter_changes_the_pacing_of_a_playing_replay(procs, probe, tmp_path: Path) -> None:
    """Messages at 0, 1000 and 1000.5 s: at rate 1 the second is 1000 s away, at 1000 one second."""
    bag = float_bag(tmp_path / "bag", [T0, T0 + 1000 * 10**9, T0 + 1000_500_000_000])
    probe.subscribe(TOPIC, Float64)
    replay = procs.module("lubrig_ros.nodes.replay", str(bag), "--wait-for-subscribers", "60")
    assert probe.wait_for_count("/lubrig/displacement", 1, 60), replay.log()
    assert trigger(probe, "pause").success
    assert trigger(probe, "is_paused").success
    rated = probe.call(SetRate, f"/{NODE}/set_rate", SetRate.Request(rate=1000.0), timeout=60, resend=5.0)
    assert rated.success, rated.message
    # the service set the parameter
    request = GetParameters.Request(names=["rate"])
    got = probe.call(GetParameters, f"/{NODE}/get_parameters", request, timeout=60, resend=5.0)
    assert got.values[0].double_value == 1000.0, got
    # toggle_paused resumes (not idempotent: sent again only if neither answer nor message came)
    client = probe.node.create_client(Trigger, f"/{NODE}/toggle_paused")
    assert client.wait_for_service(timeout_sec=60)
    for _ in range(3):
        future = client.call_async(Trigger.Request())
        if probe.wait_for(lambda: future.done() or len(probe.messages[TOPIC]) > 1, 30):  # noqa: B023
            break
    assert replay.wait(timeout=120) == 0, replay.log()
    assert "published 3 messages" in replay.output()
    assert probe.wait_for_count("/lubrig/displacement", 3, 60)
    assert [m.data for m in probe.messages["/lubrig/displacement"]] == [0.0, 1.0, 2.0]


def test_until_stops_after_the_last_message_at_or_before_it(procs, probe, tmp_path: Path) -> None:
    bag = float_bag(tmp_path / "bag", [T0 + k * 100_000_000 for k in range(30)])  # 2.9 s
    probe.subscribe("/lubrig/displacement", Float64)
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--start", "0.35", "--until", "1.25", "--rate", "10",
        "--wait-for-subscribers", "60",
    )  # fmt: skip
    assert replay.wait(timeout=120) == 0, replay.log()
    assert "published 9 messages" in replay.output()  # 0.4 .. 1.2 s
    assert probe.wait_for_count("/lubrig/displacement", 9, 60)
    assert [m.data for m in probe.messages["/lubrig/displacement"]] == [float(k) for k in range(4, 13)]


def test_until_outside_the_bag_or_before_start_is_one_line_and_status_2(tmp_path: Path) -> None:
    bag = float_bag(tmp_path / "bag", [T0 + k * 100_000_000 for k in range(30)])  # 2.9 s
    err = "replay: error: "
    cases = {
        ("--until", "5"): f"{err}--until 5 is invalid: the bag spans 2.9 s; expected seconds in (0, 2.9]",
        ("--start", "1", "--until", "0.5"): f"{err}--until 0.5 is invalid: expected seconds after --start 1",
        ("--until", "nan"): f"{err}--until nan is invalid: expected seconds after --start 0",
        ("--lossless", "probe"): f"{err}--lossless paces the state blocks (/lubrig/state_block, "
        "lubrig_interfaces/msg/RigStateBlock), which are not replayed; replayed: /lubrig/displacement",
    }
    for args, line in cases.items():
        res = subprocess.run(
            [sys.executable, "-m", "lubrig_ros.nodes.replay", str(bag), *args],
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        assert res.returncode == 2, (args, res.stdout, res.stderr)
        assert res.stderr.strip().splitlines() == [line], args


def test_lossless_replay_at_20x_gives_a_slow_subscriber_every_block_once_in_order(
    procs, probe, tmp_path: Path
) -> None:
    """150 blocks (more than the block topics' QoS depth of 100) at 20x, to a subscriber that
    sleeps 50 ms per block: unpaced, 0.15 s of publishing for 7.5 s of taking."""
    bag = block_bag(tmp_path / "bag", 150, 20, 20_000_000)  # 3 s of bag time
    subscriber = probe.consume_blocks("/lubrig", delay=0.05)
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "20", "--lossless", subscriber,
        "--wait-for-subscribers", "60",
    )  # fmt: skip
    assert replay.wait(timeout=300) == 0, replay.log()
    assert "published 150 messages" in replay.output()
    assert f"lossless to {subscriber}" in replay.output()
    assert probe.wait_for_count(BLOCKS, 150, 60)
    assert firsts(probe) == list(range(0, 3000, 20))


def test_lossless_replay_into_the_recorder_records_every_sample_once(procs, tmp_path: Path) -> None:
    """The recorder as the lossless subscriber (its flow_progress as in a sim run): 100 blocks
    of 50 samples from sample 0, replayed at 50x, are recorded without a gap or a duplicate."""
    import signal

    bag = block_bag(tmp_path / "bag", 100, 50, 50_000_000)  # 4.95 s of bag time
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(tmp_path / "again"), "--use-sim-time")
    rec.wait_for_output("recording", timeout=180)
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "50", "--lossless", "lubrig_recorder",
        "--wait-for-subscribers", "120",
    )  # fmt: skip
    assert replay.wait(timeout=300) == 0, replay.log()
    assert "published 100 messages" in replay.output()
    assert "lossless to /lubrig/lubrig_recorder" in replay.output()
    assert rec.stop(signal.SIGINT, timeout=120) == 0, rec.log()
    assert "/lubrig/state_block: 5000 in 100 messages, 0 missing, 0 duplicates" in rec.output()


@pytest.mark.slow  # a 10 s `lubrig rig` run, then its lossless replay
def test_rig_run_replayed_losslessly_at_20x_is_recorded_again_whole(procs, tmp_path: Path) -> None:
    """Every message of a recorded sim run (all its topics), replayed at 20x losslessly into a
    recorder, is in the new bag: the same counts per topic, the same samples in the same order."""
    import signal

    res = procs.run_module(
        "lubrig_ros.cli.main", "rig", "--case", "1", "--duration", "10", "--bag", str(tmp_path / "run"),
        "--no-report", timeout=600,
    )  # fmt: skip
    assert res.returncode == 0, res.stdout + res.stderr
    bag, again = tmp_path / "run" / "bag", tmp_path / "again"
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(again), "--use-sim-time")
    rec.wait_for_output("recording", timeout=180)
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "20", "--lossless", "lubrig_recorder",
        "--wait-for-subscribers", "120",
    )  # fmt: skip
    assert replay.wait(timeout=600) == 0, replay.log()
    assert rec.stop(signal.SIGINT, timeout=120) == 0, rec.log()
    progress = "/lubrig/flow_progress"  # not replayed with --lossless; the new bag has the recorder's
    before = {t.name: t.count for t in check_bag(bag).topics if t.count and t.name != progress}
    after = {t.name: t.count for t in check_bag(again).topics if t.count and t.name != progress}
    assert after == before
    assert f"published {sum(before.values())} messages" in replay.output()
    old, new = read_arrays(bag, [BLOCKS]), read_arrays(again, [BLOCKS])
    for field in ("sample_index", "displacement", "velocity", "friction_coefficient"):
        assert np.array_equal(old[BLOCKS][field], new[BLOCKS][field]), field


def test_lossless_replay_held_by_a_silent_subscriber_says_who_and_stops_on_sigint(
    procs, tmp_path: Path
) -> None:
    """A named subscriber that never reports holds every block: the replay says whom it waits
    for, publishes nothing, and a Ctrl-C ends it with status 0."""
    import signal

    bag = block_bag(tmp_path / "bag", 5, 10, 10_000_000)
    replay = procs.module("lubrig_ros.nodes.replay", str(bag), "--lossless", "nobody", "--flow-window", "100")
    replay.wait_for_output(
        "replay: held by flow control: waiting for the first flow_progress of /lubrig/nobody", timeout=120
    )
    assert replay.stop(signal.SIGINT, timeout=60) == 0, replay.log()
    assert "published 0 messages" in replay.output()
