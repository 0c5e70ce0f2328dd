"""Realtime mode over real DDS: rates, run-time profile updates, reset/pause, analysis outputs."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Float64, Float64MultiArray, UInt8
from std_srvs.srv import SetBool, Trigger
from test_nodes_support import Probe, Procs, new_domain

pytestmark = pytest.mark.ros
NS = "/lubrig"


def test_realtime_rates_parameters_services_analysis(tmp_path):
    domain = new_domain()
    probe = Probe(domain)
    procs = Procs(domain, tmp_path)
    try:
        for name, msg_type in (
            ("band_velocity", Float64),
            ("state", JointState),
            ("wavelet_power", Float64MultiArray),
            ("wavelet_image", Image),
            ("linear_zone", UInt8),
        ):
            probe.subscribe(f"{NS}/{name}", msg_type)
        probe.subscribe("/diagnostics", DiagnosticArray)
        procs.start("plant", mode="realtime")
        procs.start("belt_drive", mode="realtime")
        procs.start("analysis", window=256, n_scales=16, publish_period=0.2)
        state, band = f"{NS}/state", f"{NS}/band_velocity"
        assert probe.wait_for(lambda: len(probe.messages[state]) > 500, 20), procs.log("plant")
        # rates as configured (1 kHz)
        rate, pacing = probe.stamped_rate(state, 2.0)
        assert 950 < rate < 1050, rate  # one state per 1 ms of rig time
        assert 0.85 < pacing < 1.15, pacing  # rig time follows the wall clock
        assert 850 < probe.rate(band, 2.0) < 1150
        # analysis outputs
        assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_power"], 10), procs.log("analysis")
        power = probe.messages[f"{NS}/wavelet_power"][-1]
        assert [d.label for d in power.layout.dim] == ["frequency", "time"]
        assert len(power.data) == power.layout.dim[0].size * power.layout.dim[1].size
        assert all(math.isfinite(v) for v in power.data)
        assert probe.wait_for(lambda: probe.messages[f"{NS}/wavelet_image"], 5)
        image = probe.messages[f"{NS}/wavelet_image"][-1]
        assert image.encoding == "rgb8" and len(image.data) == image.height * image.step
        assert probe.messages[f"{NS}/linear_zone"][-1].data == 2  # 1e-7 m/s is zone 2

        # a valid parameter update changes the running profile
        result = probe.set_parameter("belt_drive", "profile.velocity", 3e-7)
        assert result.successful, result.reason
        assert probe.wait_for(lambda: probe.messages[band][-1].data == 3e-7, 5)
        # invalid updates are rejected with their reason; the profile is untouched
        result = probe.set_parameter("belt_drive", "profile.kind", "sawtooth")
        assert not result.successful and "sawtooth" in result.reason and "constant" in result.reason
        result = probe.set_parameter("belt_drive", "profile.velocity", float("nan"))
        assert not result.successful and "finite" in result.reason
        time.sleep(0.3)
        assert probe.messages[band][-1].data == 3e-7
        # switch kind: a sine with its defaults
        result = probe.set_parameter("belt_drive", "profile.kind", "sine")
        assert result.successful, result.reason
        assert probe.wait_for(lambda: probe.messages[band][-1].data != 3e-7, 5)

        # pause stops the plant's outputs, resume restarts them
        reply = probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=True))
        assert reply.success
        time.sleep(0.3)
        assert probe.rate(state, 0.5) == 0
        reply = probe.call(SetBool, f"{NS}/plant/pause", SetBool.Request(data=False))
        assert reply.success
        assert probe.rate(state, 0.5) > 400
        # reset: rig time back to 0
        before = probe.messages[state][-1].header.stamp.sec
        assert before >= 1
        seen = len(probe.messages[state])
        reply = probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request())
        assert reply.success

        def stamps_after_reset() -> list[float]:
            return [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                    for m in probe.messages[state][seen:]]

        # rig time restarts at 0: a state stamped within the first 50 ms arrives (whatever the load)
        assert probe.wait_for(lambda: min(stamps_after_reset(), default=1e9) < 0.05, 5), (
            stamps_after_reset()[:5]
        )
    finally:
        codes = procs.stop()
        probe.close()
    assert all(code == 0 for code in codes.values()), codes


def test_invalid_realtime_priority_is_refused_at_start():
    env = dict(os.environ, ROS_DOMAIN_ID=str(new_domain()), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    res = subprocess.run(
        [str(Path(sys.executable).parent / "plant"), "--ros-args", "-p", "mode:=realtime",
         "-p", "realtime_priority:=150"],
        capture_output=True, text=True, timeout=60, env=env, check=False,
    )
    assert res.returncode == 2
    assert "realtime_priority=150 is not valid; expected 0..99" in res.stdout + res.stderr
