"""Relative names (issue 11): the nodes' topics and services follow the node namespace.

Real node processes started with `--ros-args -r __ns:=/rigA` produce the run on /rigA/...,
equal to core.run.simulate; a relative remap (`-r band_velocity_block:=...`) moves a topic; a separate
process sees every topic and service of the contract under /rigA with the documented types
(graph API). `topic_namespace` (the old way) is refused with the way to do it now; `lubrig rig
--namespace` runs the rig in that namespace.
"""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
from lubrig_testkit.harness import BIN
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64

from lubrig_interfaces.msg import BandVelocityBlock
from lubrig_ros.app.interface import contract
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

NS = "/rigA"
BAND = "/rigA_band/v"  # where the relative remap moves band_velocity_block
DURATION = 1.0


def test_nodes_in_a_namespace_with_a_relative_remap(procs, probe):
    for name in ("displacement", "velocity", "friction_coefficient"):
        probe.subscribe(f"{NS}/{name}", Float64)
    probe.subscribe("/clock", Clock)
    probe.subscribe(BAND, BandVelocityBlock, qos_profile(contract.BLOCK_QOS))
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    me = probe.consume_blocks(NS)
    ros_args = ["--ros-args", "-r", f"__ns:={NS}", "-r", f"band_velocity_block:={BAND}"]
    # scalar_topics: the optional Float64 topics too (every contract topic exists under /rigA);
    # a flow window the probe's Float64 queues (depth 1000) hold
    procs.node(
        "plant",
        *ros_args,
        case=1,
        duration=DURATION,
        wait_for_subscriber="probe",
        scalar_topics=True,
        publish_clock=True,
    )
    procs.node(
        "belt_drive",
        *ros_args,
        case=1,
        duration=DURATION,
        wait_for_subscriber="probe",
        flow_window=300,
        required_consumers=f"['{me}']",
    )
    procs.node("analysis", *ros_args, case=1, per_sample_input=True)  # its state subscription too
    done = probe.wait_for(lambda: any(m.data for m in probe.messages[f"{NS}/run_complete"]), 60)
    assert done, procs.logs()
    n = round(DURATION * 1000)
    assert probe.wait_for(lambda: len(probe.messages[f"{NS}/displacement"]) >= n + 1, 60)

    # a separate process (the probe) sees every contract topic and service under /rigA (but
    # those of a rig_in_loop plant in shadow mode)
    shadow = {contract.resolve(NS, n) for n in contract.SHADOW_TOPICS}
    expected = {t.name: t.msgtype for t in contract.documented_topics(NS).values() if t.name not in shadow}
    expected[BAND] = expected.pop(f"{NS}/band_velocity_block")  # moved by the relative remap
    assert probe.wait_for(lambda: set(expected) <= set(probe.topics()), 20), sorted(probe.topics())
    topics = probe.topics()
    for name, msgtype in expected.items():
        assert topics[name] == [msgtype], (name, topics[name])
    assert f"{NS}/band_velocity_block" not in topics  # nothing left on the unremapped name
    assert not [t for t in topics if t.startswith("/lubrig")], sorted(topics)
    services = dict(probe.node.get_service_names_and_types())
    for s in contract.SERVICES:
        assert services[f"{NS}/{s.name}"] == [s.srvtype], (s.name, services)
    for node in ("plant", "belt_drive", "analysis"):  # parameter services move with the node
        assert f"{NS}/{node}/set_parameters" in services, sorted(services)

    def names() -> set[tuple[str, str]]:
        return set(probe.node.get_node_names_and_namespaces())

    # node names are discovered apart from the topics (they may come a little later)
    wanted = {("plant", NS), ("belt_drive", NS), ("analysis", NS)}
    assert probe.wait_for(lambda: wanted <= names(), 20), (names(), procs.logs())
    # a parameter is set on the namespaced node
    result = probe.set_parameter(f"{NS[1:]}/plant", "rig.damping_ratio", 0.05)
    assert result.successful, result.reason

    # every block reaches the probe before the writers stop: a reliable sample lost on the way
    # comes again only when the reader answers the writer's next heartbeat (docs/nodes.md)
    assert probe.wait_for(lambda: probe.samples(BAND, "band_velocity") >= n, 20), probe.samples(
        BAND, "band_velocity"
    )
    assert probe.wait_for(lambda: probe.samples(f"{NS}/state_block", "displacement") >= n + 1, 20)
    codes = procs.stop_all()
    ref = simulate(load_case(1).with_overrides(duration=DURATION))
    x = np.array([m.data for m in probe.messages[f"{NS}/displacement"]])
    assert np.array_equal(x, ref.displacement)  # the run, bit-identical, on /rigA
    blocks = probe.messages[f"{NS}/state_block"]
    assert np.array_equal(np.concatenate([b.displacement for b in blocks]), ref.displacement)
    band = np.concatenate([b.band_velocity for b in probe.messages[BAND]])
    assert np.array_equal(band, ref.band_velocity[1:])
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())


def test_topic_namespace_other_than_the_node_namespace_is_refused(ros_env):
    res = subprocess.run(
        [str(BIN / "plant"), "--ros-args", "-r", "__ns:=/rigB", "-p", "topic_namespace:=/rigC"],
        capture_output=True,
        text=True,
        timeout=60,
        env=ros_env,
        check=False,
    )
    assert res.returncode == 2
    out = res.stdout + res.stderr
    assert "topic_namespace='/rigC' is no longer supported" in out and "-r __ns:=/rigC" in out, out


@pytest.mark.slow  # a whole rig run with the recorder
def test_lubrig_rig_namespace(tmp_path, ros_env):
    out = tmp_path / "run"
    res = subprocess.run(
        [
            str(BIN / "lubrig"),
            "rig",
            "--case",
            "1",
            "--duration",
            "1",
            "--bag",
            str(out),
            "--namespace",
            "/rig_2",
            "--no-report",
        ],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "namespace /rig_2" in res.stdout
    from rosbags.rosbag2 import Reader

    with Reader(out / "bag") as reader:  # an independent reader: every topic under /rig_2
        recorded = {c.topic for c in reader.connections}
    # sim: no per-sample topics (state: realtime; scalar topics: off by default)
    per_sample = {
        f"/rig_2/{n}" for n in ("state", "displacement", "velocity", "friction_coefficient", "band_velocity")
    }
    assert {t.name for t in contract.documented_topics("/rig_2").values()} - {"/rig_2/run_config"} - (
        per_sample
    ) <= (
        recorded
        | {
            "/rig_2/wavelet_image",
            "/rig_2/wavelet_power",
            "/rig_2/dominant_frequency",
            "/rig_2/oscillation_growing",
            "/rig_2/wavelet_frame",
            "/rig_2/stability",
        }
    ), recorded
    assert not [t for t in recorded if t.startswith("/lubrig")], recorded
    with Reader(out / "bag") as reader:  # the state blocks of the 1 s run (default block length)
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/rig_2/state_block"] == math.ceil(1000 / contract.DEFAULT_BLOCK_LENGTH), counts
    bad = subprocess.run(
        [str(BIN / "lubrig"), "rig", "--case", "1", "--bag", str(tmp_path / "x"), "--namespace", "rig-2"],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert bad.returncode == 2 and "--namespace='rig-2' is not valid" in bad.stderr, bad.stderr
