"""Sim flow control over real DDS (issues 11 and 12): rigs on one domain, slow consumers, resets.

- Two sim rigs in two namespaces on one ROS domain, started together, each equal to
  core.run.simulate of its own case: pacing uses only the namespaced flow_progress, never the
  global /clock (one of them owns /clock, the other publishes none).
- A required consumer that is deliberately slow (it sleeps in every block) loses nothing: the
  run slows down instead.
- A plant reset during a run starts a new segment; belt_drive follows (its profile restarts at
  t = 0) and the run completes with the new segment equal to simulate, no duplicate stamp within
  a segment, no deadlock.
"""

from __future__ import annotations

import time

import numpy as np
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool
from std_srvs.srv import Trigger

from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common

FIELDS = ("displacement", "velocity", "friction_coefficient", "band_velocity")


def _segment(blocks: list, segment: int) -> dict[str, np.ndarray]:
    """The samples of one segment, checked consecutive from index 0 (no gap, no duplicate)."""
    mine = [b for b in blocks if b.segment == segment]
    expected = 0
    for b in mine:
        assert b.first_sample_index == expected, (segment, b.first_sample_index, expected)
        expected += len(b.displacement)
    out = {f: np.concatenate([np.asarray(getattr(b, f)) for b in mine]) for f in FIELDS}
    starts = [b.header.stamp.sec * 10**9 + b.header.stamp.nanosec for b in mine]
    assert starts == sorted(set(starts)), "duplicate or backward block stamps within a segment"
    return out


def _complete(probe, ns: str) -> bool:
    return any(m.data for m in probe.messages[f"{ns}/run_complete"])


def test_two_sim_rigs_on_one_domain_stay_apart(procs, probe):
    rigs = {"/rigA": (1, 1.5), "/rigB": (7, 1.0)}
    probe.subscribe("/clock", Clock)
    for ns in rigs:
        probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
        me = probe.consume_blocks(ns)
    for k, (ns, (case, duration)) in enumerate(rigs.items()):
        ros = ["--ros-args", "-r", f"__ns:={ns}"]
        procs.node(
            "plant", *ros, case=case, duration=duration, publish_clock=(k == 0), wait_for_subscriber="probe"
        )
        procs.node("belt_drive", *ros, case=case, duration=duration, required_consumers=f"['{me}']")
    assert probe.wait_for(lambda: all(_complete(probe, ns) for ns in rigs), 120), procs.logs()
    for ns, (_case, duration) in rigs.items():
        blocks = probe.messages[f"{ns}/state_block"]
        n = round(duration * 1000)
        assert probe.wait_for(lambda b=blocks, n=n: sum(len(x.displacement) for x in b) >= n + 1, 30)
    codes = procs.stop_all()
    for ns, (case, duration) in rigs.items():
        got = _segment(probe.messages[f"{ns}/state_block"], 0)
        ref = simulate(load_case(case).with_overrides(duration=duration))
        for name in FIELDS:
            assert np.array_equal(got[name], getattr(ref, name)), (ns, name)
    # /clock has one owner (rig A): its rig time, never beyond rig A's end
    clock = [m.clock.sec + 1e-9 * m.clock.nanosec for m in probe.messages["/clock"]]
    assert clock and max(clock) == rigs["/rigA"][1]
    owners = {i.node_namespace for i in probe.node.get_publishers_info_by_topic("/clock")}
    assert owners <= {"/rigA"}, owners
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())


def test_a_slow_required_consumer_loses_nothing(procs, probe):
    ns, duration = "/lubrig", 1.0
    probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
    # 20 ms per block of 10 samples: at most 500 samples per second, far below the plant's pace;
    # flow_window 500 with block_length 10: 50 blocks may be in flight, far more than DDS would
    # hold for a slow reader without the flow control (the history would overwrite them)
    me = probe.consume_blocks(ns, delay=0.02)
    procs.node("plant", case=1, duration=duration, wait_for_subscriber="probe")
    procs.node(
        "belt_drive",
        case=1,
        duration=duration,
        block_length=10,
        flow_window=500,
        required_consumers=f"['{me}']",
    )
    assert probe.wait_for(lambda: _complete(probe, ns), 120), procs.logs()
    blocks = probe.messages[f"{ns}/state_block"]
    n = round(duration * 1000)
    assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks) >= n + 1, 60)
    time.sleep(0.5)  # nothing more may arrive (no duplicate)
    codes = procs.stop_all()
    got = _segment(blocks, 0)
    ref = simulate(load_case(1).with_overrides(duration=duration))
    assert got["displacement"].size == n + 1
    for name in FIELDS:
        assert np.array_equal(got[name], getattr(ref, name)), name
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())


def test_a_reset_starts_a_new_segment_that_completes(procs, probe):
    ns, duration = "/lubrig", 2.0
    probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
    # slow enough (5 ms per block of 20) that the reset lands in the middle of segment 0
    me = probe.consume_blocks(ns, delay=0.005)
    procs.node("plant", case=1, duration=duration, wait_for_subscriber="probe")
    procs.node(
        "belt_drive",
        case=1,
        duration=duration,
        block_length=20,
        flow_window=200,
        required_consumers=f"['{me}']",
    )
    blocks = probe.messages[f"{ns}/state_block"]
    assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks) > 300, 120), procs.logs()
    answer = probe.call(Trigger, f"{ns}/plant/reset", Trigger.Request())
    assert answer.success and "segment 1" in answer.message, answer.message
    assert probe.wait_for(lambda: _complete(probe, ns) and blocks[-1].segment == 1, 120), procs.logs()
    n = round(duration * 1000)
    assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks if b.segment == 1) >= n + 1, 60)
    codes = procs.stop_all()
    assert {b.segment for b in blocks} == {0, 1}
    first = _segment(blocks, 0)  # a consecutive prefix of the run, cut by the reset
    ref = simulate(load_case(1).with_overrides(duration=duration))
    m = first["displacement"].size
    assert 300 < m < n + 1
    assert np.array_equal(first["displacement"], ref.displacement[:m])
    second = _segment(blocks, 1)  # the whole run again from t = 0
    for name in FIELDS:
        assert np.array_equal(second[name], getattr(ref, name)), name
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
