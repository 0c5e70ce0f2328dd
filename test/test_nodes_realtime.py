"""Realtime mode over real DDS: 1 ms rig-time steps, run-time profile updates, reset/pause, analysis.

Nothing here asserts a wall-clock rate: how well the plant keeps its deadlines on a loaded machine
is a benchmark figure (bench/bench_realtime.py). The tests assert what is published: one RigState
per sample (sample_index 0, 1, 2, … = rig time / 1 ms within a segment), in order, stamped with
ROS time (within a second of the wall clock), rig time never ahead of the wall clock, the same
samples in state_block (with each one's lateness), band samples sent ahead by belt_drive with
their sample indices, the plant's own counts; a reset starts segment 1 at sample 0.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Image
from std_msgs.msg import Float64MultiArray, UInt8
from std_srvs.srv import SetBool, Trigger

from lubrig_interfaces.msg import BandVelocityBlock, RigState, StabilityFlags, WaveletFrame

NS = "/lubrig"


def _stamp(msg: RigState) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _rig_time(msg: RigState) -> float:
    """Rig time of a realtime sample: its index in the segment times the 1 ms sample period."""
    return msg.sample_index * 1e-3


def _timing_reports(probe) -> list[dict[str, str]]:
    """Every `/lubrig/plant: timing` status received so far, oldest first."""
    return [
        {kv.key: kv.value for kv in status.values}
        for array in list(probe.messages["/diagnostics"])
        for status in array.status
        if status.name == "/lubrig/plant: timing"
    ]


def test_realtime_steps_parameters_services_analysis(procs, probe):
    for name, msg_type in (
        ("band_velocity_block", BandVelocityBlock),
        ("state", RigState),
        ("wavelet_power", Float64MultiArray),
        ("wavelet_frame", WaveletFrame),
        ("stability", StabilityFlags),
        ("wavelet_image", Image),
        ("linear_zone", UInt8),
    ):
        probe.subscribe(f"{NS}/{name}", msg_type)
    probe.subscribe("/diagnostics", DiagnosticArray)
    # state_block taken as the recorder takes it: the plant's loop waits for the probe's subscription
    # and its flow_progress, so that the first block (the initial state) is not sent before the match
    probe.consume_blocks(NS)
    started, wall_start = time.monotonic(), time.time()
    # max_lag far beyond any stall of a loaded machine: the lag rule has tests of its own
    procs.node("plant", mode="realtime", diagnostics_period=0.2, max_lag=10.0, wait_for_subscriber="probe")
    procs.node("belt_drive", mode="realtime", wait_for_subscriber="probe")  # every band index from 0
    procs.node("analysis", window=256, n_scales=16, publish_period=0.2)
    state, band, blocks = f"{NS}/state", f"{NS}/band_velocity_block", f"{NS}/state_block"
    assert probe.wait_for_count(state, 1000, 180), procs.logs()
    assert probe.wait_for_count(band, 10, 60), procs.logs()
    elapsed = time.monotonic() - started
    states = list(probe.messages[state])
    # one state per 1 ms of rig time, in order: sample indices strictly increasing in segment 0
    index = np.array([m.sample_index for m in states])
    assert np.all(np.diff(index) >= 1), "states out of order or repeated"
    assert {m.segment for m in states} == {0}
    assert all(math.isfinite(m.displacement) and math.isfinite(m.velocity) for m in states)
    assert all(math.isfinite(m.relative_velocity) and m.band_velocity == 1e-7 for m in states[1:])
    # stamps are ROS time (here the wall clock, same machine): between the start of the test and
    # now (a busy probe takes them late, so not compared with their arrival), never backwards
    stamps = np.array([_stamp(m) for m in states])
    assert np.all(np.diff(stamps) >= 0)
    assert wall_start - 1.0 <= stamps[0] and stamps[-1] <= time.time() + 1.0, (wall_start, stamps[[0, -1]])
    # paced by the wall clock: rig time is never ahead of it (a lagging plant is a bench figure)
    assert index[-1] / 1000 <= elapsed, (index[-1], elapsed)
    # the belt drive's default profile, a constant 1e-7 m/s, sent ahead: every band index once, in
    # order from 0, each block within lookahead (200) samples of where the plant was
    sent = list(probe.messages[band])
    firsts = [m.first_sample_index for m in sent]
    assert firsts[0] == 0 and all(
        b.first_sample_index == a.first_sample_index + len(a.band_velocity)
        for a, b in itertools.pairwise(sent)
    ), firsts[:10]
    assert {v for m in sent for v in m.band_velocity} == {1e-7} and {m.segment for m in sent} == {0}
    # (the plant's position from its blocks, taken after `sent`: the same probe, the same rate)
    newest = probe.messages[f"{NS}/state_block"][-1]
    assert sent[-1].first_sample_index + len(sent[-1].band_velocity) <= (
        newest.first_sample_index + len(newest.displacement) + 200 + 1
    )
    # state_block: the same samples as state, in blocks of output_block_length (20), each sample
    # with its lateness (>= 0, finite), the initial state alone in the first block
    got = list(probe.messages[blocks])
    assert got[0].first_sample_index == 0 and len(got[0].displacement) == 1
    assert all(len(m.lateness) == len(m.displacement) for m in got)
    assert all(math.isfinite(v) and v >= 0 for m in got for v in m.lateness)
    assert {len(m.displacement) for m in got[1:-1]} <= {20}
    by_index = {m.sample_index: m for m in states}
    for m in got[:20]:
        for i, x in enumerate(m.displacement):
            if m.first_sample_index + i in by_index:
                assert by_index[m.first_sample_index + i].displacement == x
    # the plant's own accounting: one sample per 1 ms of rig time (skipped ones included)
    assert probe.wait_for(lambda: _timing_reports(probe), 10), procs.log("plant")
    report = _timing_reports(probe)[-1]
    # (the report may be read between a tick's publish and its count: one tick short at most)
    ticks = int(report["samples"]) + int(report["skipped_samples"])
    assert 0 <= round(float(report["rig_time_s"]) * 1000) - ticks <= 1, report
    assert report["integration_errors"] == "0"
    # analysis outputs
    assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_power"], 60), procs.log("analysis")
    power = probe.messages[f"{NS}/wavelet_power"][-1]
    assert [d.label for d in power.layout.dim] == ["frequency", "time"]
    assert len(power.data) == power.layout.dim[0].size * power.layout.dim[1].size
    assert all(math.isfinite(v) for v in power.data)
    assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_image"], 60), procs.log("analysis")
    image = probe.messages[f"{NS}/wavelet_image"][-1]
    assert image.encoding == "rgb8" and len(image.data) == image.height * image.step
    assert probe.wait_for(lambda: probe.messages[f"{NS}/linear_zone"], 60)
    assert probe.messages[f"{NS}/linear_zone"][-1].data == 2  # 1e-7 m/s is zone 2
    # the typed analysis outputs: the wavelet frame with its axes, every stability flag
    assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_frame"], 60)
    frame = probe.messages[f"{NS}/wavelet_frame"][-1]
    assert frame.rows == len(frame.frequency) == 16 and len(frame.power) == frame.rows * frame.cols
    assert list(frame.frequency) == sorted(frame.frequency, reverse=True)  # row 0: highest
    assert all(math.isfinite(v) for v in frame.power)
    end = frame.end.sec + 1e-9 * frame.end.nanosec  # the plant's stamps: ROS time
    # ROS time of this run (not rig time since 0): between the test's start and now; how far the
    # analysis lags behind is a bench figure, not asserted
    assert wall_start - 1.0 <= end <= time.time() + 1.0, (wall_start, end)
    assert probe.wait_for(lambda: probe.messages[f"{NS}/stability"], 60)
    flags = probe.messages[f"{NS}/stability"][-1]
    assert flags.linear_zone == StabilityFlags.ZONE_FALLING and flags.band_velocity == 1e-7
    assert flags.damping_ratio > 0 and flags.critical_damping_ratio > 0
    assert flags.linear_stable == (flags.damping_ratio > flags.critical_damping_ratio)

    # a valid parameter update changes the running profile
    result = probe.set_parameter("lubrig/belt_drive", "profile.velocity", 3e-7)
    assert result.successful, result.reason
    assert probe.wait_for(lambda: probe.messages[band][-1].band_velocity[-1] == 3e-7, 10)
    assert probe.wait_for(lambda: probe.messages[state][-1].band_velocity == 3e-7, 10)
    # invalid updates are rejected with their reason; the profile is untouched
    result = probe.set_parameter("lubrig/belt_drive", "profile.kind", "sawtooth")
    assert not result.successful and "sawtooth" in result.reason and "constant" in result.reason
    result = probe.set_parameter("lubrig/belt_drive", "profile.velocity", float("nan"))
    # refused by the descriptor's physical range (rclpy names the range and the value)
    assert not result.successful and "nan" in result.reason and "0.01" in result.reason
    assert probe.wait_for_more(band, 20, 10)  # samples published after the rejected updates
    assert probe.messages[band][-1].band_velocity[-1] == 3e-7
    # switch kind: a sine with its defaults
    result = probe.set_parameter("lubrig/belt_drive", "profile.kind", "sine")
    assert result.successful, result.reason
    assert probe.wait_for(lambda: probe.messages[band][-1].band_velocity[-1] != 3e-7, 10)

    # pause stops the plant: rig time stands still in its reports, no later state is published
    reply = probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=True))
    assert reply.success

    def paused_reports() -> list[dict[str, str]]:
        return [r for r in _timing_reports(probe) if r["paused"] == "true"]

    def frozen() -> bool:
        reports = paused_reports()
        return len(reports) >= 2 and reports[-1]["rig_time_s"] == reports[-2]["rig_time_s"]

    assert probe.wait_for(frozen, 10), paused_reports()[-3:]
    held = paused_reports()[-1]
    count = len(paused_reports())
    assert probe.wait_for(lambda: len(paused_reports()) > count, 10)  # one more report, paused
    assert paused_reports()[-1]["rig_time_s"] == held["rig_time_s"]
    assert paused_reports()[-1]["samples"] == held["samples"]
    paused_at = float(held["rig_time_s"])
    assert max(_rig_time(m) for m in probe.messages[state]) <= paused_at + 1e-9
    reply = probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=False))
    assert reply.success
    # resume: states flow again, rig time going on from where it stood, in order
    assert probe.wait_for(
        lambda: sum(_rig_time(m) > paused_at for m in list(probe.messages[state])) >= 400, 30
    ), (paused_at, [_rig_time(m) for m in probe.messages[state][-5:]], _timing_reports(probe)[-1:])
    index = [m.sample_index for m in probe.messages[state]]
    assert all(a < b for a, b in itertools.pairwise(index)), "states out of order"
    # reset: rig time back to 0 in a new segment
    assert probe.messages[state][-1].sample_index >= 1000
    seen = len(probe.messages[state])
    reply = probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request())
    assert reply.success and "segment 1" in reply.message

    def after_reset() -> list[RigState]:
        return list(probe.messages[state][seen:])

    # segment 1 starts again at sample 0
    assert probe.wait_for(lambda: any(m.segment == 1 for m in after_reset()), 10)
    new = [m for m in after_reset() if m.segment == 1]
    # rig time back to 0: the segment restarts its sample index (a probe outside any flow control
    # may miss the very first samples beside CPU hogs — realtime loss is the recorder's accounting)
    assert new[0].sample_index < 100, [m.sample_index for m in new[:5]]
    assert all(a < b for a, b in itertools.pairwise(m.sample_index for m in new))
    # every reset and pause is logged with its caller: the probe's node, found by its client's GID
    caller = probe.node.get_fully_qualified_name()

    def called(service: str) -> list[str]:
        return [ln for ln in procs.log("plant").splitlines() if f"{NS}/plant/{service} called by" in ln]

    assert probe.wait_for(lambda: len(called("pause")) == 2 and called("reset"), 10), procs.log("plant")
    assert all(f"called by {caller} (request " in ln for ln in called("pause") + called("reset")), (
        caller,
        called("pause"),
        called("reset"),
    )
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())


def test_invalid_realtime_priority_is_refused_at_start(procs):
    res = procs.run_script(
        "plant", "--ros-args", "-p", "mode:=realtime", "-p", "realtime_priority:=150", timeout=60
    )
    assert res.returncode == 2
    assert "realtime_priority=150 is not valid; expected 0..99" in res.stdout + res.stderr
