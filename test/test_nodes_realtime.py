"""Realtime mode over real DDS: 1 ms rig-time steps, run-time profile updates, reset/pause, analysis.

Nothing here asserts a wall-clock rate: how well the plant keeps its deadlines on a loaded machine
is a benchmark figure (bench/bench_realtime.py). The tests assert what is published: states one per
millisecond of rig time, in order, rig time never ahead of the wall clock, the plant's own counts.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Float64, Float64MultiArray, UInt8
from std_srvs.srv import SetBool, Trigger

NS = "/lubrig"


def _stamp(msg: JointState) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _timing_reports(probe) -> list[dict[str, str]]:
    """Every `lubrig/plant: timing` status received so far, oldest first."""
    return [
        {kv.key: kv.value for kv in status.values}
        for array in list(probe.messages["/diagnostics"])
        for status in array.status
        if status.name == "lubrig/plant: timing"
    ]


def test_realtime_steps_parameters_services_analysis(procs, probe):
    for name, msg_type in (
        ("band_velocity", Float64),
        ("state", JointState),
        ("wavelet_power", Float64MultiArray),
        ("wavelet_image", Image),
        ("linear_zone", UInt8),
    ):
        probe.subscribe(f"{NS}/{name}", msg_type)
    probe.subscribe("/diagnostics", DiagnosticArray)
    started = time.monotonic()
    procs.node("plant", mode="realtime", diagnostics_period=0.2)
    procs.node("belt_drive", mode="realtime")
    procs.node("analysis", window=256, n_scales=16, publish_period=0.2)
    state, band = f"{NS}/state", f"{NS}/band_velocity"
    assert probe.wait_for_count(state, 1000, 180), procs.logs()
    assert probe.wait_for_count(band, 500, 60), procs.logs()
    elapsed = time.monotonic() - started
    states = list(probe.messages[state])
    # one state per 1 ms of rig time, in order: stamps on the 1 ms grid, strictly increasing
    steps = np.array([_stamp(m) for m in states]) * 1000
    assert np.allclose(steps, np.round(steps), rtol=0, atol=1e-3), steps[:10]
    assert np.all(np.diff(np.round(steps)) >= 1), "states out of order or repeated"
    assert all(math.isfinite(m.position[0]) and math.isfinite(m.velocity[0]) for m in states)
    # paced by the wall clock: rig time is never ahead of it (a lagging plant is a bench figure)
    assert steps[-1] / 1000 <= elapsed, (steps[-1], elapsed)
    assert len(probe.messages[band]) <= 1000 * elapsed + 1
    # the belt drive's default profile: a constant 1e-7 m/s, every sample
    assert {m.data for m in probe.messages[band]} == {1e-7}
    # the plant's own accounting: one sample per 1 ms of rig time
    assert probe.wait_for(lambda: _timing_reports(probe), 10), procs.log("plant")
    report = _timing_reports(probe)[-1]
    # (the report may be read between a tick's publish and its count: one tick short at most)
    assert 0 <= round(float(report["rig_time_s"]) * 1000) - int(report["samples"]) <= 1, report
    assert report["integration_errors"] == "0"
    # analysis outputs
    assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_power"], 60), procs.log("analysis")
    power = probe.messages[f"{NS}/wavelet_power"][-1]
    assert [d.label for d in power.layout.dim] == ["frequency", "time"]
    assert len(power.data) == power.layout.dim[0].size * power.layout.dim[1].size
    assert all(math.isfinite(v) for v in power.data)
    assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_image"], 60)
    image = probe.messages[f"{NS}/wavelet_image"][-1]
    assert image.encoding == "rgb8" and len(image.data) == image.height * image.step
    assert probe.wait_for(lambda: probe.messages[f"{NS}/linear_zone"], 60)
    assert probe.messages[f"{NS}/linear_zone"][-1].data == 2  # 1e-7 m/s is zone 2

    # a valid parameter update changes the running profile
    result = probe.set_parameter("lubrig/belt_drive", "profile.velocity", 3e-7)
    assert result.successful, result.reason
    assert probe.wait_for(lambda: probe.messages[band][-1].data == 3e-7, 10)
    # invalid updates are rejected with their reason; the profile is untouched
    result = probe.set_parameter("lubrig/belt_drive", "profile.kind", "sawtooth")
    assert not result.successful and "sawtooth" in result.reason and "constant" in result.reason
    result = probe.set_parameter("lubrig/belt_drive", "profile.velocity", float("nan"))
    assert not result.successful and "finite" in result.reason
    assert probe.wait_for_more(band, 200, 10)  # samples published after the rejected updates
    assert probe.messages[band][-1].data == 3e-7
    # switch kind: a sine with its defaults
    result = probe.set_parameter("lubrig/belt_drive", "profile.kind", "sine")
    assert result.successful, result.reason
    assert probe.wait_for(lambda: probe.messages[band][-1].data != 3e-7, 10)

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
    assert max(_stamp(m) for m in probe.messages[state]) <= paused_at + 1e-9
    reply = probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=False))
    assert reply.success
    # resume: states flow again, rig time going on from where it stood, in order
    assert probe.wait_for(
        lambda: sum(_stamp(m) > paused_at for m in list(probe.messages[state])) >= 400, 30
    ), (paused_at, [_stamp(m) for m in probe.messages[state][-5:]], _timing_reports(probe)[-1:])
    stamps = [_stamp(m) for m in probe.messages[state]]
    assert all(a < b for a, b in itertools.pairwise(stamps)), "states out of order"
    # reset: rig time back to 0
    before = probe.messages[state][-1].header.stamp.sec
    assert before >= 1
    seen = len(probe.messages[state])
    reply = probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request())
    assert reply.success

    def stamps_after_reset() -> list[float]:
        return [_stamp(m) for m in probe.messages[state][seen:]]

    # rig time restarts at 0: a state stamped within the first 50 ms arrives (whatever the load)
    assert probe.wait_for(lambda: min(stamps_after_reset(), default=1e9) < 0.05, 10), (
        stamps_after_reset()[:5]
    )
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())


def test_invalid_realtime_priority_is_refused_at_start(procs):
    res = procs.run_script("plant", "--ros-args", "-p", "mode:=realtime", "-p", "realtime_priority:=150",
                           timeout=60)
    assert res.returncode == 2
    assert "realtime_priority=150 is not valid; expected 0..99" in res.stdout + res.stderr
