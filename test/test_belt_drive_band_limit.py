"""Cross-node check (issue 11 'Silent stall'): belt_drive refuses a profile the plant would reject.

The plant rejects |v_band| > band_velocity_limit; a profile beyond it used to be accepted by
belt_drive, and the sim run stalled without a word. Now the profile over the run is checked
against the limit at start (exit 2, the reason) and at run time (the update refused with it).
A profile field beyond the default limit (core/schema.py's band range) is refused by the profile
kind itself; a plant limit lowered below it is what belt_drive checks the whole profile against.
"""

from __future__ import annotations

import subprocess

from lubrig_testkit.harness import BIN

from lubrig_ros.core.profiles import band_range_problem, profile_from_dict


def test_band_range_problem_names_value_time_and_limit():
    ok = profile_from_dict({"kind": "constant", "velocity": 1e-6})
    assert band_range_problem(ok, 1000.0, 2.0, 1e-3) is None
    fast = profile_from_dict({"kind": "constant", "velocity": 0.005})
    reason = band_range_problem(fast, 1000.0, 2.0, 1e-3)
    assert reason is not None and "|v_band| = 0.005 m/s" in reason and "band_velocity_limit 0.001" in reason
    # a cycle whose low plateau is -5 mm/s: found where it happens, not only at t = 0
    cycle = profile_from_dict(
        {
            "kind": "cycle",
            "low_velocity": -0.005,
            "high_velocity": 1e-6,
            "plateau_time": 1.0,
            "ramp_time": 0.5,
        }
    )
    reason = band_range_problem(cycle, 1000.0, 10.0, 1e-3)
    assert reason is not None and "|v_band| = 0.005 m/s" in reason
    assert band_range_problem(cycle, 1000.0, 10.0, 1e-2) is None
    ramp = profile_from_dict({"kind": "sine", "mean_velocity": 0.0, "amplitude": 0.005, "frequency": 0.1})
    reason = band_range_problem(ramp, 1000.0, 10.0, 1e-3)  # peaks at t = 2.5 s
    assert reason is not None and "t = 2.5 s" in reason, reason


def test_belt_drive_refuses_a_profile_outside_the_plants_band_range(procs, probe, ros_env):
    res = subprocess.run(
        [
            str(BIN / "belt_drive"),
            "--ros-args",
            "-p",
            "case:=1",
            "-p",
            "band_velocity_limit:=0.001",
            "-p",
            "profile.high_velocity:=0.005",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env=ros_env,
        check=False,
    )
    assert res.returncode == 2
    out = res.stdout + res.stderr
    assert "refused" in out and "|v_band| = 0.005 m/s" in out and "band_velocity_limit 0.001 m/s" in out, out

    procs.node("belt_drive", case=1, band_velocity_limit=0.001)
    result = probe.set_parameter("lubrig/belt_drive", "profile.high_velocity", 0.005)
    assert not result.successful
    assert "|v_band| = 0.005 m/s" in result.reason and "0.001 m/s" in result.reason, result.reason
    result = probe.set_parameter("lubrig/belt_drive", "profile.high_velocity", 0.5)  # beyond the schema
    assert not result.successful and "profile.high_velocity" in result.reason, result.reason
    assert probe.set_parameter("lubrig/belt_drive", "profile.high_velocity", 5e-4).successful
    codes = procs.stop_all()
    assert codes == {"belt_drive": 0}, codes
    assert "profile update rejected" in procs.log("belt_drive")
