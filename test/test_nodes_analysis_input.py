"""The analysis node under odd input: band at rest, a mass that does not move, malformed states.

Input both ways the plant sends it: RigState per sample (realtime) and RigStateBlock (sim),
with blocks whose arrays disagree in length and samples that are NaN.
"""

from __future__ import annotations

import math
import time

from std_msgs.msg import Float64, Float64MultiArray, UInt8

from lubrig_interfaces.msg import RigState, RigStateBlock, StabilityFlags, WaveletFrame
from lubrig_ros.app.interface import contract
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

NS = "/lubrig"


def _state(x: float, v: float, band: float) -> RigState:
    return RigState(displacement=x, velocity=v, band_velocity=band, relative_velocity=band - v)


def test_analysis_survives_band_at_rest_constant_and_malformed_states(procs, probe):
    for name, kind in (
        ("linear_zone", UInt8),
        ("critical_damping_ratio", Float64),
        ("dominant_frequency", Float64),
        ("wavelet_power", Float64MultiArray),
        ("wavelet_frame", WaveletFrame),
        ("stability", StabilityFlags),
    ):
        probe.subscribe(f"{NS}/{name}", kind, common.ANALYSIS_QOS)
    proc = procs.node("analysis", window=256, n_scales=16, publish_period=0.1, per_sample_input=True)
    state = probe.publisher(f"{NS}/state", RigState, common.STREAM_QOS)
    block = probe.publisher(f"{NS}/state_block", RigStateBlock, qos_profile(contract.BLOCK_QOS))
    assert probe.wait_for(
        lambda: state.get_subscription_count() > 0 and block.get_subscription_count() > 0, 60
    ), procs.log("analysis")
    for k in range(600):
        band = 0.0 if k < 300 else 1e-7  # the band at rest, then moving
        if k % 50 == 11:
            state.publish(_state(math.nan, 0.0, band))
        state.publish(_state(1.6e-8, 0.0, band))  # a mass that does not move
        if k % 100 == 7:  # arrays of unequal length, and a block with NaN samples
            block.publish(RigStateBlock(displacement=[1.0, 2.0], velocity=[0.0]))
            block.publish(
                RigStateBlock(
                    sample_period=1e-3,
                    displacement=[math.nan, 1.6e-8],
                    velocity=[0.0, math.inf],
                    band_velocity=[band, band],
                    relative_velocity=[band, band],
                )
            )
        time.sleep(0.001)
    # it keeps running and publishes the zone once the band moves
    zone = probe.messages[f"{NS}/linear_zone"]
    assert probe.wait_for(lambda: zone, 60), procs.log("analysis")
    # and still analyses good input after all of that, given as blocks this time
    seen = len(zone)
    for k in range(30):
        block.publish(
            RigStateBlock(
                sample_period=1e-3,
                first_sample_index=10 * k,
                displacement=[1.6e-8] * 10,
                velocity=[0.0] * 10,
                band_velocity=[1e-7] * 10,
                relative_velocity=[1e-7] * 10,
            )
        )
        time.sleep(0.01)
    assert probe.wait_for(lambda: len(zone) > seen, 60), procs.log("analysis")
    assert proc.running(), procs.log("analysis")
    for name in ("critical_damping_ratio", "dominant_frequency"):
        assert all(math.isfinite(m.data) for m in probe.messages[f"{NS}/{name}"]), name
    for m in probe.messages[f"{NS}/wavelet_power"]:
        assert all(math.isfinite(v) for v in m.data)
    for m in probe.messages[f"{NS}/wavelet_frame"]:
        assert all(math.isfinite(v) for v in m.power) and len(m.power) == m.rows * m.cols
    flags = probe.messages[f"{NS}/stability"]
    assert flags and flags[-1].linear_zone == StabilityFlags.ZONE_FALLING
    numbers = (
        "band_velocity",
        "damping_ratio",
        "critical_damping_ratio",
        "effective_damping",
        "growth_rate",
        "growth_fit_r2",
        "stick_threshold",
        "stick_share",
        "longest_stick",
    )
    for m in flags:
        assert all(math.isfinite(getattr(m, f)) for f in numbers)
    # at rest: zone unknown, and the group's numbers are 0
    assert any(m.linear_zone == StabilityFlags.ZONE_UNKNOWN and m.band_velocity == 0.0 for m in flags)
