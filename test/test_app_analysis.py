"""app/rundir.py (one run directory) and app/analysis/policy.py (one wavelet policy), without the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lubrig_ros.app import rundir
from lubrig_ros.app.analysis.policy import (
    DEFAULT_POLICY,
    MAX_POWER_POINTS,
    AnalysisError,
    WaveletPolicy,
    analyze_displacement,
    whole_record,
)
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate, summarize
from lubrig_ros.core.trajectory import Trajectory
from lubrig_ros.core.wavelet import cwt, fourier_factor
from lubrig_ros.core.wavelet_components import dominant_components


def test_run_directory_round_trips_bit_for_bit(tmp_path: Path) -> None:
    config = load_case(2).with_overrides(duration=0.5)
    traj = simulate(config)
    out = rundir.write_run(tmp_path / "run", config, traj, summarize(traj, config))
    header = (out / "timeseries.csv").read_text().splitlines()[0]
    assert header == rundir.CSV_HEADER == ",".join(c for _, c in Trajectory.COLUMNS)
    arrays = rundir.read_timeseries(out)  # the Trajectory back from timeseries.csv
    back = Trajectory(**{name: arrays[column] for name, column in Trajectory.COLUMNS})
    for name, _ in Trajectory.COLUMNS:
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name), err_msg=name)
    assert (out / "config.yaml").read_text() == config.to_yaml()
    summary = rundir.update_summary(out, "extra", {"a": 1})
    assert json.loads((out / "summary.json").read_text()) == summary and summary["extra"] == {"a": 1}
    with pytest.raises(rundir.RunDirError, match="exists and is not a directory"):
        rundir.write_run(out / "config.yaml", config, traj, summary)
    with pytest.raises(rundir.RunDirError, match="missing"):
        rundir.read_summary(tmp_path)


def _tone(seconds: float, rate: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(seconds * rate)) / rate
    growing = np.where(t < seconds / 2, 5.0, 1.0)  # a strong first half: the window must skip it
    x = 2e-6 + 1e-7 * np.sin(2 * np.pi * 10.0 * t) + growing * 4e-8 * np.sin(2 * np.pi * 30.0 * t)
    return t, x


def test_default_window_is_the_stationary_half_and_matches_the_policy_by_hand() -> None:
    t, x = _tone(6.0)
    analysis = analyze_displacement(t, x, 1000.0, 10.0 / 3.0)
    assert analysis.start_s == t[-1] / 2 and analysis.analysed_from_s == 3.0  # summarize's window
    assert analysis.decimation == 1 and not analysis.flags["decimated"]
    # the same transform written out from the policy's words: second half, rate/4 … 3/window
    half = x[t >= t[-1] / 2]
    fmax, fmin = 250.0, 3.0 / (half.size * 1e-3)
    n_scales = int(np.floor(np.log2(fmax / fmin) / DEFAULT_POLICY.dj)) + 1
    ref = cwt(half - half.mean(), 1e-3, s0=1.0 / (fmax * fourier_factor()), n_scales=n_scales, t0=3.0)
    np.testing.assert_array_equal(analysis.wavelet.power, ref.power)
    expected = dominant_components(ref, 10.0 / 3.0, 5, min_relative_power=1e-4)
    assert analysis.components == expected
    assert [round(c.frequency_hz) for c in analysis.components[:2]] == [10, 30]
    # in the second half the 10 Hz tone is the stronger one; over the whole record the 30 Hz is
    whole = analyze_displacement(t, x, 1000.0, 10.0 / 3.0, whole_record())
    assert whole.analysed_from_s == 0.0
    assert whole.components[0].power / whole.components[1].power != pytest.approx(
        analysis.components[0].power / analysis.components[1].power, rel=0.1
    )
    section = analysis.summary_section()
    assert section["dominant_frequencies"][0]["label"] == "3rd harmonic of 3.33 Hz"
    assert section["min_relative_power"] == 1e-4 and section["flags"]["decimated"] is False
    json.dumps(section, allow_nan=False)


def test_memory_cap_decimates_and_says_so() -> None:
    t, x = _tone(60.0)
    policy = whole_record(max_power_points=3_000_000)
    analysis = analyze_displacement(t, x, 1000.0, None, policy)
    n_scales = analysis.wavelet.scales.size
    assert analysis.decimation > 1 and analysis.flags["decimated"]
    assert analysis.wavelet.time.size * n_scales <= 3_000_000 * 1.01
    assert analysis.wavelet.frequencies.max() <= 0.4 * 1000.0 / analysis.decimation * 1.0001
    assert "decimated by" in analysis.note
    assert abs(analysis.components[0].frequency_hz / 10 - 1) < 0.03
    assert DEFAULT_POLICY.max_power_points == MAX_POWER_POINTS


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"start_s": -1.0}, "start=-1.0"),
        ({"dj": 0.0}, "dj=0.0"),
        ({"fmax_hz": float("nan")}, "fmax_hz=nan"),
        ({"n_components": 0}, "n_components=0"),
        ({"min_relative_power": 1.5}, "min_relative_power=1.5"),
    ],
)
def test_bad_policy_names_the_value(kwargs: dict, needle: str) -> None:
    with pytest.raises(AnalysisError, match=needle):
        WaveletPolicy(**kwargs)


def test_bad_records_are_clear_errors() -> None:
    t, x = _tone(1.0)
    with pytest.raises(AnalysisError, match="constant"):
        analyze_displacement(t, np.full_like(t, 1e-6), 1000.0)
    with pytest.raises(AnalysisError, match="samples after --start"):
        analyze_displacement(t[:20], x[:20], 1000.0)
    with pytest.raises(AnalysisError, match="sample_rate_hz"):
        analyze_displacement(t, x, 0.0)
    with pytest.raises(AnalysisError, match="--fmin"):
        analyze_displacement(t, x, 1000.0, policy=WaveletPolicy(fmin_hz=50.0, fmax_hz=20.0))
