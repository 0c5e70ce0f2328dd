"""Rig in the loop: an external 1 kHz band publisher with gaps, NaN and negative spikes."""

from __future__ import annotations

import math
import threading
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from test_nodes_support import Probe, Procs, new_domain

from lubrig_ros.nodes import common

pytestmark = pytest.mark.ros
NS = "/lubrig"


def _values(array: DiagnosticArray, name: str) -> dict[str, str]:
    for status in array.status:
        if status.name == name:
            return {kv.key: kv.value for kv in status.values} | {"_message": status.message}
    return {}


def test_rig_in_loop_bad_input_and_staleness(tmp_path):
    domain = new_domain()
    probe = Probe(domain)
    procs = Procs(domain, tmp_path)
    try:
        probe.subscribe(f"{NS}/displacement", Float64)
        probe.subscribe(f"{NS}/state", JointState)
        probe.subscribe("/diagnostics", DiagnosticArray)
        procs.start("plant", mode="rig_in_loop", diagnostics_period=0.25)
        pub = probe.node.create_publisher(Float64, f"{NS}/band_velocity", common.STREAM_QOS)
        x = f"{NS}/displacement"
        assert probe.wait_for(lambda: len(probe.messages[x]) > 200, 20), procs.log("plant")
        assert probe.wait_for(lambda: pub.get_subscription_count() > 0, 10)
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

        feeder = threading.Thread(target=feed, daemon=True)
        feeder.start()
        rate, pacing = probe.stamped_rate(f"{NS}/state", 2.0)
        assert 950 < rate < 1050 and 0.85 < pacing < 1.15, (rate, pacing)
        diag = probe.messages["/diagnostics"]
        band = _values(diag[-1], "lubrig/plant: band input")
        assert int(band["rejected"]) > 20
        assert band["last_rejected_value"] in ("nan", "-5.0", "-inf")
        assert band["stale"] == "false"
        # a gap in the input: the plant keeps its rate, holds the last good value, reports stale
        gap.set()
        rate, pacing = probe.stamped_rate(f"{NS}/state", 1.5)
        assert 950 < rate < 1050 and 0.85 < pacing < 1.15, (rate, pacing)
        band = _values(diag[-1], "lubrig/plant: band input")
        assert band["stale"] == "true" and "stale" in band["_message"]
        held = float(band["held_band_velocity_m_s"])
        assert 8e-8 <= held <= 1.2e-7
        gap.clear()
        time.sleep(0.6)
        assert _values(diag[-1], "lubrig/plant: band input")["stale"] == "false"
        stop.set()
        feeder.join(timeout=2)
        assert all(math.isfinite(m.data) for m in probe.messages[x])
        assert procs.procs["plant"].poll() is None  # still alive
        timing = _values(diag[-1], "lubrig/plant: timing")
        assert timing["integration_errors"] == "0"
    finally:
        codes = procs.stop()
        probe.close()
    assert codes["plant"] == 0
