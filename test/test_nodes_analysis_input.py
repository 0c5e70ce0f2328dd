"""The analysis node under odd input: band at rest, a mass that does not move, malformed states."""

from __future__ import annotations

import math
import time

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, UInt8
from test_nodes_support import Probe, Procs, new_domain

from lubrig_ros.nodes import common

pytestmark = pytest.mark.ros
NS = "/lubrig"


def test_analysis_survives_band_at_rest_constant_and_malformed_states(tmp_path):
    domain = new_domain()
    probe = Probe(domain)
    procs = Procs(domain, tmp_path)
    try:
        for name, kind in (("linear_zone", UInt8), ("critical_damping_ratio", Float64),
                           ("dominant_frequency", Float64), ("wavelet_power", Float64MultiArray)):
            probe.subscribe(f"{NS}/{name}", kind, common.ANALYSIS_QOS)
        proc = procs.start("analysis", window=256, n_scales=16, publish_period=0.1)
        band = probe.node.create_publisher(Float64, f"{NS}/band_velocity", common.STREAM_QOS)
        state = probe.node.create_publisher(JointState, f"{NS}/state", common.STREAM_QOS)
        assert probe.wait_for(
            lambda: band.get_subscription_count() > 0 and state.get_subscription_count() > 0, 30
        ), procs.log("analysis")
        msg = JointState()
        msg.name = ["mass"]
        for k in range(600):
            band.publish(Float64(data=0.0 if k < 300 else 1e-7))  # the band at rest, then moving
            if k % 50 == 7:
                state.publish(JointState())  # no position / velocity at all
            if k % 50 == 11:
                msg.position, msg.velocity = [math.nan], [0.0]
                state.publish(msg)
            msg.position, msg.velocity = [1.6e-8], [0.0]  # a mass that does not move
            state.publish(msg)
            time.sleep(0.001)
        # it keeps running and publishes the zone once the band moves
        assert probe.wait_for(lambda: probe.messages[f"{NS}/linear_zone"], 10), procs.log("analysis")
        time.sleep(0.5)
        assert proc.poll() is None, procs.log("analysis")
        for name in ("critical_damping_ratio", "dominant_frequency"):
            assert all(math.isfinite(m.data) for m in probe.messages[f"{NS}/{name}"]), name
        for m in probe.messages[f"{NS}/wavelet_power"]:
            assert all(math.isfinite(v) for v in m.data)
    finally:
        procs.stop()
        probe.close()
