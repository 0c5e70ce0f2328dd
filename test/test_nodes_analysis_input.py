"""The analysis node under odd input: band at rest, a mass that does not move, malformed states."""

from __future__ import annotations

import math
import time

from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, UInt8

from lubrig_ros.nodes import common

NS = "/lubrig"


def test_analysis_survives_band_at_rest_constant_and_malformed_states(procs, probe):
    for name, kind in (("linear_zone", UInt8), ("critical_damping_ratio", Float64),
                       ("dominant_frequency", Float64), ("wavelet_power", Float64MultiArray)):
        probe.subscribe(f"{NS}/{name}", kind, common.ANALYSIS_QOS)
    proc = procs.node("analysis", window=256, n_scales=16, publish_period=0.1)
    band = probe.publisher(f"{NS}/band_velocity", Float64, common.STREAM_QOS)
    state = probe.publisher(f"{NS}/state", JointState, common.STREAM_QOS)
    assert probe.wait_for(
        lambda: band.get_subscription_count() > 0 and state.get_subscription_count() > 0, 60
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
    zone = probe.messages[f"{NS}/linear_zone"]
    assert probe.wait_for(lambda: zone, 60), procs.log("analysis")
    # and still analyses good input after all of that
    seen = len(zone)
    for _ in range(300):
        band.publish(Float64(data=1e-7))
        state.publish(msg)
        time.sleep(0.001)
    assert probe.wait_for(lambda: len(zone) > seen, 60), procs.log("analysis")
    assert proc.running(), procs.log("analysis")
    for name in ("critical_damping_ratio", "dominant_frequency"):
        assert all(math.isfinite(m.data) for m in probe.messages[f"{NS}/{name}"]), name
    for m in probe.messages[f"{NS}/wavelet_power"]:
        assert all(math.isfinite(v) for v in m.data)
