"""Sim mode on the ROS clock: every node with use_sim_time, every stamp rig time.

- `lubrig rig` (sim) starts belt_drive, plant and analysis with use_sim_time true (the plant
  publishing /clock): the rig starts (its heartbeats, pacing and diagnostics run on the steady
  clock, not on a ROS clock that stands until /clock moves), completes, and its bag equals
  `lubrig simulate`; in the bag every message with a header is stamped with rig time (never the
  wall clock's ~1.8e9 s) within one block of its log time, /clock included.
- A reset keeps the ROS clock monotonic: a use_sim_time node with a time-jump callback sees no
  backward jump, and the new segment's samples and band blocks are stamped on from where the old
  segment ended (its own rig time, sample_index / rate, restarts at 0; its samples equal
  core.run.simulate).
- Without /clock (`--no-clock`: a second rig on the domain), use_sim_time nodes still run, and the
  plant's and the analysis' stamps are rig time from the rig's own samples.
- The report reads a later segment on the rig's clock, as the recorder's log and gap times are
  (ROS-free).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from lubrig_testkit.crosscheck import read_rosbags
from lubrig_testkit.harness import wait_until
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool
from std_srvs.srv import Trigger

from lubrig_interfaces.msg import BandVelocityBlock, StabilityFlags, WaveletFrame
from lubrig_ros.app.interface import contract
from lubrig_ros.app.plant.output import BLOCK_FIELDS
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

NS = "/lubrig"
BLOCK_QOS = qos_profile(contract.BLOCK_QOS)
SEC = 1_000_000_000
FIELDS = ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity")


def _ns(stamp) -> int:
    return int(stamp.sec) * SEC + int(stamp.nanosec)


def _stamped_messages(bag: Path) -> dict[str, list[tuple[int, int]]]:
    """Topic -> [(log time ns, stamp ns)] of every message with a header (and /clock), log-time order."""
    (path,) = bag.glob("*.mcap")
    out: dict[str, list[tuple[int, int]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=True):
            if hasattr(msg, "header"):
                stamp = _ns(msg.header.stamp)
            elif hasattr(msg, "clock"):
                stamp = _ns(msg.clock)
            else:
                continue
            out.setdefault(channel.topic, []).append((message.log_time, stamp))
    return out


@pytest.mark.slow  # a whole `lubrig rig` run with the recorder
def test_sim_rig_on_sim_time_completes_equal_to_simulate_with_rig_time_stamps(procs, tmp_path: Path) -> None:
    duration = 3.0
    out = tmp_path / "run"
    res = procs.run_module(
        "lubrig_ros.cli.main",
        "rig",
        "--case",
        "1",
        "--duration",
        f"{duration:g}",
        "--run-dir",
        str(out),
        "--no-report",
        timeout=300,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    for node in ("plant", "belt_drive", "analysis"):  # each says so in its start line
        log = (out / "logs" / f"{node}.log").read_text()
        assert "use_sim_time true" in log, (node, log)
    # the bag equals `lubrig simulate` of the same run, sample for sample
    offline = tmp_path / "offline"
    sim = procs.run_module(
        "lubrig_ros.cli.main",
        "simulate",
        "--case",
        "1",
        "--duration",
        f"{duration:g}",
        "--out",
        str(offline),
        timeout=120,
    )
    assert sim.returncode == 0, sim.stdout + sim.stderr
    csv = np.loadtxt(offline / "timeseries.csv", delimiter=",", skiprows=1)
    values = read_rosbags(out / "bag")
    assert values["/lubrig/state_block"] == csv[:, 1].tolist()  # %.17g: bit for bit
    assert values["/lubrig/band_velocity_block"] == csv[1:, 4].tolist()
    # every header stamp is rig time (0 .. duration, not the wall clock) within one block of its
    # log time; /clock the same and never going back
    block = int(contract.parameter("belt_drive", "block_length").default) * SEC // 1000
    stamped = _stamped_messages(out / "bag")
    # (the analysis outputs and /diagnostics too when the short run left time for them: the stamps
    # of both are asserted in test_without_clock_sim_time_nodes_run_and_stamp_rig_time)
    with_header = {NS + "/state_block", NS + "/band_velocity_block", NS + "/flow_progress"}
    assert with_header | {"/clock"} <= set(stamped), sorted(stamped)
    for topic, messages in stamped.items():
        for log_time, stamp in messages:
            assert 0 <= stamp <= duration * SEC, (topic, stamp)
            assert abs(stamp - log_time) <= block, (topic, stamp, log_time)
    clock = [stamp for _log, stamp in stamped["/clock"]]
    assert clock == sorted(clock) and clock[-1] == duration * SEC


def _use_sim_time_listener(probe):
    """A use_sim_time node on the probe's executor; its clock's time jumps (delta ns) are recorded."""
    from rclpy.clock import JumpThreshold
    from rclpy.duration import Duration
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    node = Node(
        "sim_time_listener",
        context=probe.context,
        parameter_overrides=[Parameter("use_sim_time", Parameter.Type.BOOL, True)],
    )
    jumps: list[int] = []
    threshold = JumpThreshold(min_forward=Duration(nanoseconds=1), min_backward=Duration(nanoseconds=-1))
    handle = node.get_clock().create_jump_callback(
        threshold, post_callback=lambda jump: jumps.append(jump.delta.nanoseconds)
    )
    probe.executor.add_node(node)
    return node, handle, jumps


def _segment(blocks: list, segment: int) -> dict[str, np.ndarray]:
    mine = [b for b in blocks if b.segment == segment]
    expected = 0
    for b in mine:
        assert b.first_sample_index == expected, (segment, b.first_sample_index, expected)
        expected += len(b.displacement)
    return {f: np.concatenate([np.asarray(getattr(b, f)) for b in mine]) for f in FIELDS}


def test_a_reset_keeps_the_ros_clock_monotonic(procs, probe) -> None:
    duration = 1.0
    probe.subscribe("/clock", Clock)
    probe.subscribe(f"{NS}/band_velocity_block", BandVelocityBlock, BLOCK_QOS)
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    node, handle, jumps = _use_sim_time_listener(probe)
    try:
        # slow enough (5 ms per block of 20) that the reset lands in the middle of segment 0
        me = probe.consume_blocks(NS, delay=0.005)
        procs.node(
            "plant",
            case=1,
            duration=duration,
            publish_clock=True,
            use_sim_time=True,
            wait_for_subscriber="probe",
        )
        procs.node(
            "belt_drive",
            case=1,
            duration=duration,
            block_length=20,
            flow_window=200,
            required_consumers=f"['{me}']",
            use_sim_time=True,
        )
        blocks = probe.messages[f"{NS}/state_block"]
        assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks) > 300, 120), procs.logs()
        answer = probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request())
        assert answer.success and "segment 1" in answer.message, answer.message
        n = round(duration * 1000)
        done = lambda: sum(len(b.displacement) for b in blocks if b.segment == 1) >= n + 1  # noqa: E731
        assert probe.wait_for(done, 120), procs.logs()
        complete = probe.messages[f"{NS}/run_complete"]
        assert probe.wait_for(lambda: complete and complete[-1].data, 30), procs.logs()
        ros_now = node.get_clock().now().nanoseconds
    finally:
        probe.executor.remove_node(node)
        handle.unregister()
        node.destroy_node()
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
    # the use_sim_time node followed /clock forward and never back
    assert jumps and min(jumps) > 0, jumps
    clock = [_ns(m.clock) for m in probe.messages["/clock"]]
    assert clock == sorted(clock), "/clock went back"
    # segment 0 ended after m samples; segment 1's t = 0 is one sample later on the same clock
    first = _segment(blocks, 0)
    m = first["displacement"].size
    assert 300 < m < n + 1
    origin = m * SEC // 1000
    seg1 = [b for b in blocks if b.segment == 1]
    assert [_ns(b.header.stamp) for b in seg1] == [origin + b.first_sample_index * SEC // 1000 for b in seg1]
    assert origin < ros_now <= clock[-1] == origin + duration * SEC  # the end of segment 1
    band = [b for b in probe.messages[f"{NS}/band_velocity_block"] if b.segment == 1]
    assert band and [_ns(b.header.stamp) for b in band] == [
        origin + (b.first_sample_index + 1) * SEC // 1000 for b in band
    ]
    # the segment's own rig time restarts at 0: its samples are the whole run again
    ref = simulate(load_case(1).with_overrides(duration=duration))
    second = _segment(blocks, 1)
    for name in FIELDS:
        assert np.array_equal(second[name], getattr(ref, name)), name
    assert np.array_equal(first["displacement"], ref.displacement[:m])


def _plant_diagnostics(probe) -> list[int]:
    """Stamps (ns) of the plant's /diagnostics arrays received so far."""
    return [
        _ns(a.header.stamp)
        for a in list(probe.messages["/diagnostics"])
        if any(s.name.startswith(f"{NS}/plant") for s in a.status)
    ]


def test_without_clock_sim_time_nodes_run_and_stamp_rig_time(procs, probe) -> None:
    duration = 3.0
    for topic, msg_type in (
        (f"{NS}/stability", StabilityFlags),
        (f"{NS}/wavelet_frame", WaveletFrame),
        ("/diagnostics", DiagnosticArray),
    ):
        probe.subscribe(topic, msg_type, common.ANALYSIS_QOS)
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    probe.subscribe("/clock", Clock)
    # the analysis first, so that it takes every sample of the (short) run
    analysis = procs.node("analysis", case=1, use_sim_time=True)
    wait_until(
        lambda: "use_sim_time true" in analysis.output() + analysis.errors(),
        90,
        "the analysis started",
        alive=(analysis,),
    )
    me = probe.consume_blocks(NS, delay=0.01)  # 10 ms per block of 100: about 10 x real time
    procs.node(
        "plant",
        case=1,
        duration=duration,
        publish_clock=False,
        use_sim_time=True,
        diagnostics_period=0.1,
        wait_for_subscriber="probe",
    )
    procs.node(
        "belt_drive",
        case=1,
        duration=duration,
        block_length=100,
        required_consumers=f"['{me}']",
        use_sim_time=True,
    )
    complete = probe.messages[f"{NS}/run_complete"]
    assert probe.wait_for(lambda: complete and complete[-1].data, 120), procs.logs()
    frames = probe.messages[f"{NS}/wavelet_frame"]
    # the analysis' next update takes the run's last samples: stamped with the end of the run
    assert probe.wait_for(lambda: frames and _ns(frames[-1].header.stamp) == duration * SEC, 30), (
        [_ns(f.header.stamp) for f in frames],
        procs.logs(),
    )
    # the plant's diagnostics come every diagnostics_period of wall time, so the run (under a
    # second of wall time) can end between two of them: the next one after the end carries it
    assert probe.wait_for(lambda: _plant_diagnostics(probe)[-1:] == [duration * SEC], 30), (
        _plant_diagnostics(probe)[-5:],
        procs.logs(),
    )
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
    assert not probe.messages["/clock"]  # nobody published /clock: the node clocks stood at 0
    blocks = probe.messages[f"{NS}/state_block"]
    assert sum(len(b.displacement) for b in blocks) == round(duration * 1000) + 1
    assert [_ns(b.header.stamp) for b in blocks] == [b.first_sample_index * SEC // 1000 for b in blocks]
    for f in frames:  # the stamp is the last column's rig time, on the 1 ms grid
        assert _ns(f.header.stamp) == _ns(f.end) and _ns(f.end) % (SEC // 1000) == 0, f.end
    stability = [_ns(m.header.stamp) for m in probe.messages[f"{NS}/stability"]]
    assert stability == sorted(stability) and 0 < stability[-1] <= duration * SEC, stability
    plant = _plant_diagnostics(probe)
    assert plant == sorted(plant) and plant[-1] == duration * SEC, plant[-5:]


def test_the_report_reads_a_later_segment_on_the_rigs_clock(tmp_path: Path) -> None:
    from rclpy.serialization import serialize_message

    from lubrig_interfaces.msg import RigStateBlock
    from lubrig_ros.bag import BagWriter
    from lubrig_ros.bag.writer import serialize_string
    from lubrig_ros.report import trajectory_from_bag

    config = load_case(1).with_overrides(duration=0.5)
    traj = simulate(config)
    n = len(traj)
    bag = tmp_path / "bag"
    w = BagWriter(bag, run_config=config.to_yaml())
    w.write(f"{NS}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    origin = 0
    for segment, cut in ((0, 200), (1, n)):  # segment 0 reset after 200 samples
        for k0 in range(0, cut, 50):
            k1 = min(k0 + 50, cut)
            m = RigStateBlock(sample_period=1e-3, first_sample_index=k0, segment=segment)
            for name in BLOCK_FIELDS:  # every array set, as the plant does
                setattr(m, name, [0.0] * (k1 - k0))
            for name in FIELDS:
                setattr(m, name, getattr(traj, name)[k0:k1].tolist())
            t = origin + k0 * SEC // 1000
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(t, SEC)
            w.write(f"{NS}/state_block", "lubrig_interfaces/msg/RigStateBlock", t, serialize_message(m))
        origin += cut * SEC // 1000  # the plant's clock goes on across the reset
    w.close()
    _cfg, second = trajectory_from_bag(bag, segment=1)  # the run again, from 0.2 s on the clock
    assert len(second) == n
    np.testing.assert_allclose(second.time, 0.2 + traj.time, rtol=0, atol=1e-12)
    assert np.array_equal(second.displacement, traj.displacement)
    _cfg, first = trajectory_from_bag(bag, segment=0)
    np.testing.assert_allclose(first.time, traj.time[:200], rtol=0, atol=1e-12)
