"""50 resets and pause toggles at random moments of a sim run leave a consistent run (issue 11).

plant + belt_drive in sim mode, the probe a required consumer (it takes every block, lossless by
the flow control). 50 control calls (reset, pause, resume) at random moments (seeded); then the
run is resumed and must complete. Every segment the probe saw is a consecutive prefix of the run
from sample 0 (no gap, no duplicate, stamps increasing) equal to core.run.simulate, and the last
segment is the whole run.
"""

from __future__ import annotations

import random
import time

import numpy as np
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common

NS = "/lubrig"
DURATION = 1.5
CALLS = 50


def _segments(blocks: list) -> dict[int, dict[str, np.ndarray]]:
    out = {}
    for segment in sorted({b.segment for b in blocks}):
        mine = [b for b in blocks if b.segment == segment]
        expected = 0
        for b in mine:
            assert b.first_sample_index == expected, (segment, b.first_sample_index, expected)
            expected += len(b.displacement)
        starts = [b.header.stamp.sec * 10**9 + b.header.stamp.nanosec for b in mine]
        assert starts == sorted(set(starts)), f"duplicate or backward stamps in segment {segment}"
        out[segment] = {"displacement": np.concatenate([np.asarray(b.displacement) for b in mine])}
    return out


def test_fifty_resets_and_pauses_leave_a_run_that_completes(procs, probe):
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    me = probe.consume_blocks(NS, delay=0.002)
    procs.node("plant", case=1, duration=DURATION, wait_for_subscriber="probe")
    procs.node(
        "belt_drive",
        case=1,
        duration=DURATION,
        block_length=20,
        flow_window=200,
        required_consumers=f"['{me}']",
    )
    blocks = probe.messages[f"{NS}/state_block"]
    assert probe.wait_for(lambda: len(blocks) > 2, 120), procs.logs()
    rng = random.Random(11)
    resets = 0
    for _ in range(CALLS):
        time.sleep(rng.uniform(0.0, 0.05))
        kind = rng.choice(("reset", "pause", "resume"))
        if kind == "reset":
            assert probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request()).success
            resets += 1
        else:
            assert probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=kind == "pause")).success
        assert all(p.running() for p in procs.started.values()), procs.logs()
    assert probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=False)).success
    n = round(DURATION * 1000) + 1

    def last_segment_complete() -> bool:
        last = max((b.segment for b in blocks), default=-1)
        return last == resets and sum(len(b.displacement) for b in blocks if b.segment == last) >= n

    assert probe.wait_for(last_segment_complete, 180), procs.logs()
    assert probe.wait_for(lambda: probe.messages[f"{NS}/run_complete"][-1].data, 30)
    codes = procs.stop_all()
    ref = simulate(load_case(1).with_overrides(duration=DURATION)).displacement
    segments = _segments(list(blocks))
    assert max(segments) == resets and resets >= 5
    for segment, cols in segments.items():
        x = cols["displacement"]
        assert np.array_equal(x, ref[: x.size]), segment  # every segment: the run from t = 0
    assert segments[resets]["displacement"].size == n
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
