"""Sim mode over real DDS: block-streamed, lossless, every sample equal to core.run.simulate.

The in-test probe takes the plant's state blocks as a REQUIRED CONSUMER of the flow control
(belt_drive's `required_consumers`): it reports on flow_progress as it takes blocks, so however
busy the machine, belt_drive never sends more than flow_window samples beyond what the probe has
taken and no block can be lost on the way to it.
"""

from __future__ import annotations

import numpy as np
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, String

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress
from lubrig_ros.app.interface import contract
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

DURATION = 2.0
BLOCK_QOS = qos_profile(contract.BLOCK_QOS)


def block_columns(blocks: list, fields: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Concatenated arrays of consecutive blocks; AssertionError on a gap, a duplicate or a mix."""
    expected = 0
    for b in blocks:
        assert b.first_sample_index == expected, (b.first_sample_index, expected)
        expected += len(getattr(b, fields[0]))
    return {f: np.concatenate([np.asarray(getattr(b, f)) for b in blocks]) for f in fields}


STATE_FIELDS = (
    "displacement",
    "velocity",
    "friction_coefficient",
    "friction_force",
    "band_velocity",
    "relative_velocity",
    "belt_travel",
)


def test_sim_case1_equals_core_simulate(procs, probe):
    ns = "/lubrig"
    probe.subscribe(f"{ns}/band_velocity_block", BandVelocityBlock, BLOCK_QOS)
    probe.subscribe(f"{ns}/flow_progress", FlowProgress, BLOCK_QOS)
    probe.subscribe("/clock", Clock)
    probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
    probe.subscribe(f"{ns}/run_config", String, common.LATCHED_QOS)
    me = probe.consume_blocks(ns)
    assert me == "/probe"
    # a block length that does not divide the run: the last block is shorter
    procs.node("plant", case=1, duration=DURATION, publish_clock=True, wait_for_subscriber="probe")
    procs.node(
        "belt_drive",
        case=1,
        duration=DURATION,
        block_length=37,
        flow_window=74,
        required_consumers=f"['{me}']",
        wait_for_subscriber="probe",
    )
    procs.node("analysis", case=1)
    done = probe.wait_for(lambda: any(m.data for m in probe.messages[f"{ns}/run_complete"]), timeout=120)
    assert done, procs.logs()
    n = round(DURATION * 1000)
    blocks = probe.messages[f"{ns}/state_block"]
    assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks) >= n + 1, 60)
    expected = {
        f"{ns}/band_velocity_block": "lubrig_interfaces/msg/BandVelocityBlock",
        f"{ns}/state_block": "lubrig_interfaces/msg/RigStateBlock",
        f"{ns}/flow_progress": "lubrig_interfaces/msg/FlowProgress",
        "/clock": "rosgraph_msgs/msg/Clock",
        f"{ns}/run_config": "std_msgs/msg/String",
        f"{ns}/run_complete": "std_msgs/msg/Bool",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        f"{ns}/dominant_frequency": "std_msgs/msg/Float64",
        f"{ns}/wavelet_power": "std_msgs/msg/Float64MultiArray",
        f"{ns}/wavelet_frame": "lubrig_interfaces/msg/WaveletFrame",
        f"{ns}/stability": "lubrig_interfaces/msg/StabilityFlags",
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
    # sim publishes no per-sample topic unless asked (scalar_topics)
    for name in ("displacement", "velocity", "friction_coefficient", "state"):
        assert not probe.node.get_publishers_info_by_topic(f"{ns}/{name}"), name
    # the streams the probe does not pace reach it before the writers stop: a reliable sample
    # lost on the way comes again only when the reader answers the writer's next heartbeat
    band_name = f"{ns}/band_velocity_block"
    assert probe.wait_for(lambda: probe.samples(band_name, "band_velocity") >= n, 20), probe.samples(
        band_name, "band_velocity"
    )
    plant_done = lambda: any(  # noqa: E731
        m.participant == "/lubrig/plant" and m.samples == n + 1 for m in probe.messages[f"{ns}/flow_progress"]
    )
    assert probe.wait_for(plant_done, 20)
    assert probe.wait_for(
        lambda: any(m.clock.sec + 1e-9 * m.clock.nanosec == DURATION for m in probe.messages["/clock"]), 20
    )
    codes = procs.stop_all()

    ref = simulate(load_case(1).with_overrides(duration=DURATION))
    got = block_columns(blocks, STATE_FIELDS)
    assert got["displacement"].size == ref.displacement.size == n + 1  # every sample, once
    for name in ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity"):
        assert np.array_equal(got[name], getattr(ref, name)), name  # bit-identical
    normal_force = load_case(1).rig.friction.normal_force
    assert np.array_equal(got["friction_force"], ref.friction_coefficient * normal_force)
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (ref.band_velocity[1:] + ref.band_velocity[:-1]) * 1e-3)])
    assert np.allclose(got["belt_travel"], travel, rtol=1e-9, atol=1e-18)
    # one state block per band block (the first with the initial state), stamps = rig time
    assert [len(b.displacement) for b in blocks] == [38] + [37] * 53 + [2]
    assert all(b.segment == 0 and b.sample_period == 1e-3 for b in blocks)
    starts = np.array([b.header.stamp.sec + 1e-9 * b.header.stamp.nanosec for b in blocks])
    assert np.allclose(starts, ref.time[[b.first_sample_index for b in blocks]], atol=1e-9)
    band_blocks = probe.messages[f"{ns}/band_velocity_block"]
    band = block_columns(band_blocks, ("band_velocity",))["band_velocity"]
    assert np.array_equal(band, ref.band_velocity[1:])
    assert max(len(b.band_velocity) for b in band_blocks) == 37
    # flow progress: the plant's own reports end at every sample; the probe's too
    progress = probe.messages[f"{ns}/flow_progress"]
    plant = [m.samples for m in progress if m.participant == "/lubrig/plant"]
    assert plant and plant[-1] == n + 1 and plant == sorted(plant)
    assert max(m.samples for m in progress if m.participant == me) == n + 1
    # /clock (publish_clock true): rig time, the end of the run last
    clock = [m.clock.sec + 1e-9 * m.clock.nanosec for m in probe.messages["/clock"]]
    assert clock and max(clock) == DURATION
    assert "case01" in probe.messages[f"{ns}/run_config"][0].data
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
