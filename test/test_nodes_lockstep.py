"""Lockstep rig in the loop over real DDS, beside two CPU hogs: lossless and deterministic.

An external band source (the probe process) answers every state it receives with the band sample
for the next one, as rig software in lockstep would; the plant (mode lockstep) advances one sample
per answer. Asserted: the recorded bag, read by an independent reader (mcap + mcap_ros2), equals
`core.run.simulate` of the same band sequence sample for sample; every sample recorded once; the
plant reports the round trip. Not asserted: how long a round trip takes (a bench figure).
"""

from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from lubrig_testkit.crosscheck import read_mcap
from std_msgs.msg import Bool

from lubrig_interfaces.msg import BandVelocityBlock, RigState
from lubrig_ros.app.interface import contract
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import band_samples, simulate
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

NS = "/lubrig"


def test_lockstep_with_an_answering_band_source_equals_simulate(procs, probe, tmp_path: Path, cpu_hogs):
    cpu_hogs(2)
    config = load_case(1).with_overrides(duration=0.6)  # 600 round trips
    run = tmp_path / "run.yaml"
    run.write_text(config.to_yaml())
    band = band_samples(config, 0, config.samples)
    bag = tmp_path / "bag"
    rec = procs.module(
        "lubrig_ros.nodes.recorder",
        "-o",
        str(bag),
        "--use-sim-time",
        "--topics",
        "state_block",
        "band_velocity_block",
        "run_complete",
    )
    rec.wait_for_output("recorder: recording", 120)
    answer = probe.publisher(f"{NS}/band_velocity_block", BandVelocityBlock, qos_profile(contract.BLOCK_QOS))
    answered: set[int] = set()

    def on_state(msg: RigState) -> None:  # rig software: the band sample for the next state
        k = int(msg.sample_index)
        if k < band.size and k not in answered:  # a state repeated by the plant's heartbeat: once
            answered.add(k)
            answer.publish(
                BandVelocityBlock(
                    sample_period=1e-3,
                    first_sample_index=k,
                    segment=int(msg.segment),
                    band_velocity=[float(band[k])],
                )
            )

    probe.node.create_subscription(RigState, f"{NS}/state", on_state, common.STREAM_QOS)
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    probe.subscribe("/diagnostics", DiagnosticArray)
    plant = procs.node(
        "plant",
        mode="lockstep",
        config_file=str(run),
        wait_for_subscriber="lubrig_recorder",
        diagnostics_period=0.5,
    )
    done = f"{NS}/run_complete"
    assert probe.wait_for(lambda: any(m.data for m in probe.messages[done]), 240), procs.logs()

    def timing() -> dict[str, str]:
        for array in reversed(list(probe.messages["/diagnostics"])):
            for status in array.status:
                if status.name == f"{NS}/plant: timing":
                    return {kv.key: kv.value for kv in status.values}
        return {}

    assert probe.wait_for(lambda: timing().get("run_complete") == "true", 30), procs.log("plant")
    values = timing()
    assert int(values["round_trips"]) >= config.samples - 1, values  # a repeated state may add none
    assert float(values["round_trip_p99_s"]) > 0
    assert plant.stop() == 0, procs.log("plant")
    assert rec.stop(signal.SIGINT, timeout=60) == 0, rec.log()
    recorded = read_mcap(bag)
    ref = simulate(config)
    x = np.array(recorded[f"{NS}/state_block"])
    assert x.size == ref.displacement.size  # the initial state and one sample per answer, once each
    assert np.array_equal(x, ref.displacement)
    assert np.array_equal(recorded[f"{NS}/band_velocity_block"], band)  # every answer once
    assert "0 missing, 0 duplicates, 0 out of order" in rec.output()
