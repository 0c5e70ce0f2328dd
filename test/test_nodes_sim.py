"""Sim mode over real DDS: deterministic x(t) equal to core.run.simulate, topics and types."""

from __future__ import annotations

import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String

from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common

DURATION = 2.0


def test_sim_case1_equals_core_simulate(procs, probe):
    ns = "/lubrig"
    probe.subscribe(f"{ns}/displacement", Float64)
    probe.subscribe(f"{ns}/velocity", Float64)
    probe.subscribe(f"{ns}/friction_coefficient", Float64)
    probe.subscribe(f"{ns}/band_velocity", Float64)
    probe.subscribe(f"{ns}/state", JointState)
    probe.subscribe("/clock", Clock)
    probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
    probe.subscribe(f"{ns}/run_config", String, common.LATCHED_QOS)
    # nothing flows before this probe has subscribed to every output: no missed first sample
    procs.node("plant", case=1, duration=DURATION, wait_for_subscriber="probe")
    procs.node("belt_drive", case=1, duration=DURATION, wait_for_subscriber="probe")
    procs.node("analysis", case=1)
    done = probe.wait_for(
        lambda: any(m.data for m in probe.messages[f"{ns}/run_complete"]), timeout=120
    )
    assert done, procs.logs()
    n = round(DURATION * 1000)
    assert probe.wait_for(lambda: len(probe.messages[f"{ns}/displacement"]) >= n + 1, 120)
    expected = {
        f"{ns}/band_velocity": "std_msgs/msg/Float64",
        f"{ns}/displacement": "std_msgs/msg/Float64",
        f"{ns}/velocity": "std_msgs/msg/Float64",
        f"{ns}/friction_coefficient": "std_msgs/msg/Float64",
        f"{ns}/state": "sensor_msgs/msg/JointState",
        "/clock": "rosgraph_msgs/msg/Clock",
        f"{ns}/run_config": "std_msgs/msg/String",
        f"{ns}/run_complete": "std_msgs/msg/Bool",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        f"{ns}/dominant_frequency": "std_msgs/msg/Float64",
        f"{ns}/wavelet_power": "std_msgs/msg/Float64MultiArray",
        f"{ns}/wavelet_image": "sensor_msgs/msg/Image",
        f"{ns}/linear_zone": "std_msgs/msg/UInt8",
        f"{ns}/critical_damping_ratio": "std_msgs/msg/Float64",
        f"{ns}/oscillation_growing": "std_msgs/msg/Bool",
    }
    # the analysis node may still be starting (imports, kernels) when a short run ends
    assert probe.wait_for(lambda: set(expected) <= set(probe.topics()), 60), sorted(probe.topics())
    topics = probe.topics()
    for name, type_name in expected.items():
        assert type_name in topics[name], (name, topics[name])
    codes = procs.stop_all()
    x = np.array([m.data for m in probe.messages[f"{ns}/displacement"]])
    ref = simulate(load_case(1).with_overrides(duration=DURATION))
    assert x.size == ref.displacement.size == n + 1
    assert np.array_equal(x, ref.displacement)  # bit-identical, sample for sample
    states = probe.messages[f"{ns}/state"]
    stamps = np.array([s.header.stamp.sec + 1e-9 * s.header.stamp.nanosec for s in states])
    assert np.allclose(stamps, ref.time, atol=1e-9)
    assert np.array_equal([s.position[0] for s in states], ref.displacement)
    # joint "band": the band velocity each sample was integrated with, and the belt travel
    assert all(list(s.name) == ["mass", "band"] for s in states)
    assert np.array_equal([s.velocity[1] for s in states], ref.band_velocity)
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (ref.band_velocity[1:] + ref.band_velocity[:-1]) * 1e-3)])
    assert np.allclose([s.position[1] for s in states], travel, rtol=1e-9, atol=1e-18)
    for topic, column in (
        ("velocity", ref.velocity),
        ("friction_coefficient", ref.friction_coefficient),
    ):
        assert np.array_equal([m.data for m in probe.messages[f"{ns}/{topic}"]], column), topic
    band = [m.data for m in probe.messages[f"{ns}/band_velocity"]]
    assert np.array_equal(band, ref.band_velocity[1:])
    assert "case01" in probe.messages[f"{ns}/run_config"][0].data
    assert all(code == 0 for code in codes.values()), codes
