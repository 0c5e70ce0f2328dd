"""Rig in the loop: an external ~1 kHz band publisher with gaps, NaN and negative spikes.

The assertions are on what the plant does with its input (rejects bad values and counts them,
holds the last good value, reports a gap as stale and recovers), and that it keeps publishing
states one per millisecond of rig time meanwhile; not on wall-clock rates (bench/bench_realtime.py).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import Float64

from lubrig_interfaces.msg import RigState
from lubrig_ros.nodes import common

NS = "/lubrig"


def _values(array: DiagnosticArray, name: str) -> dict[str, str]:
    for status in array.status:
        if status.name == name:
            return {kv.key: kv.value for kv in status.values} | {"_message": status.message}
    return {}


def _rig_times(probe, topic: str, start: int = 0) -> np.ndarray:
    """Rig time of each RigState: sample_index × 1 ms (one segment here)."""
    return np.array([m.sample_index * 1e-3 for m in list(probe.messages[topic])[start:]])


def _on_grid_in_order(times: np.ndarray) -> None:
    steps = times * 1000
    assert np.all(np.diff(np.round(steps)) >= 1), "states out of order or repeated"


def test_rig_in_loop_bad_input_and_staleness(procs, probe):
    probe.subscribe(f"{NS}/displacement", Float64)
    probe.subscribe(f"{NS}/state", RigState)
    probe.subscribe("/diagnostics", DiagnosticArray)
    started, wall_start = time.monotonic(), time.time()
    # scalar_topics: the per-quantity Float64 topics for simple tools, beside RigState
    # max_lag far beyond any stall of a loaded machine: this test is about the input (the lag
    # rule: test_plant_realtime.py, test_rig_realtime_policy.py)
    plant = procs.node("plant", mode="rig_in_loop", diagnostics_period=0.25, scalar_topics=True, max_lag=10.0)
    pub = probe.publisher(f"{NS}/band_velocity", Float64, common.STREAM_QOS)
    x, state = f"{NS}/displacement", f"{NS}/state"
    assert probe.wait_for(lambda: len(probe.messages[x]) > 200, 60), procs.logs()
    assert probe.wait_for(lambda: pub.get_subscription_count() > 0, 30)
    stop = threading.Event()
    gap = threading.Event()

    def feed() -> None:
        k = 0
        start = time.perf_counter()
        while not stop.is_set():
            k += 1
            while time.perf_counter() < start + k * 1e-3:
                time.sleep(2e-4)
            if gap.is_set():
                continue
            if k % 97 == 0:
                value = float("nan")
            elif k % 101 == 0:
                value = -5.0  # absurd negative spike
            elif k % 103 == 0:
                value = float("-inf")
            else:
                value = 1e-7 + 2e-8 * math.sin(k * 1e-3)
            pub.publish(Float64(data=value))

    diag = probe.messages["/diagnostics"]

    def band() -> dict[str, str]:
        return _values(diag[-1], "/lubrig/plant: band input") if diag else {}

    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    try:
        # bad values are rejected and counted, the input is live
        assert probe.wait_for(
            lambda: int(band().get("rejected", 0)) > 20 and band()["stale"] == "false", 60
        ), band()
        report = band()
        assert report["last_rejected_value"] in ("nan", "-5.0", "-inf")
        # states keep coming, one per 1 ms of rig time, rig time never ahead of the wall clock
        assert probe.wait_for_more(state, 1000, 30)
        _on_grid_in_order(_rig_times(probe, state))
        assert _rig_times(probe, state)[-1] <= time.monotonic() - started
        # stamped with ROS time (the wall clock here): between the start of the test and now
        stamp = probe.messages[state][-1].header.stamp
        assert wall_start - 1.0 <= stamp.sec + 1e-9 * stamp.nanosec <= time.time() + 1.0
        # a gap in the input: the plant keeps publishing, holds the last good value, reports stale
        gap.set()
        assert probe.wait_for(lambda: band()["stale"] == "true", 30), band()
        report = band()
        assert "stale" in report["_message"]
        held = float(report["held_band_velocity_m_s"])
        assert 8e-8 <= held <= 1.2e-7
        assert probe.wait_for_more(state, 500, 30)
        _on_grid_in_order(_rig_times(probe, state))
        assert band()["stale"] == "true"  # still in the gap: no input arrived
        gap.clear()
        assert probe.wait_for(lambda: band()["stale"] == "false", 30), band()
    finally:
        stop.set()
        feeder.join(timeout=5)
    assert all(math.isfinite(m.data) for m in probe.messages[x])
    assert plant.running(), plant.log()  # still alive
    timing = _values(diag[-1], "/lubrig/plant: timing")
    assert timing["integration_errors"] == "0"
    codes = procs.stop_all()
    assert codes["plant"] == 0, plant.log()
