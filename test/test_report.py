"""`lubrig report` on a real bag (BagWriter, the recorder's writer) holding a core run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.legacy import write_legacy_bag
from matplotlib.image import imread

from lubrig_ros.core.run import summarize
from lubrig_ros.figures.timeseries import friction_velocity_figure, phase_figure
from lubrig_ros.report import ReportError, trajectory_from_bag


def _bag(path: Path, duration: float = 3.0, namespace: str = "/lubrig") -> tuple[object, object]:
    return write_legacy_bag(path, duration, namespace)


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object, object]:
    bag = tmp_path_factory.mktemp("rep") / "bag"
    config, traj = _bag(bag)
    return bag, config, traj


def test_bag_rebuilds_trajectory_and_config(recorded: tuple) -> None:
    bag, config, traj = recorded
    cfg, rebuilt = trajectory_from_bag(bag)
    assert cfg.to_yaml() == config.to_yaml()
    for name in ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity"):
        np.testing.assert_array_equal(getattr(rebuilt, name), getattr(traj, name), err_msg=name)
    np.testing.assert_allclose(rebuilt.time, traj.time, rtol=0, atol=1e-12)


def test_report_cli_writes_page_figures_summary(recorded: tuple, tmp_path: Path) -> None:
    bag, config, traj = recorded
    out = tmp_path / "report"
    res = _cli("report", str(bag), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == f"report: {out / 'report.md'}"
    summary = json.loads((out / "summary.json").read_text())
    expected = summarize(traj, config)
    for key in ("x_peak_to_peak", "mu_min", "mu_max", "samples", "stick_fraction"):
        assert summary[key] == pytest.approx(expected[key], rel=1e-12), key
    assert summary["wavelet"]["figure"] == "wavelet.png"
    text = (out / "report.md").read_text()
    assert f"{summary['x_peak_to_peak']:.4g} m" in text
    for name in ("wavelet.png", "time_history.png", "phase.png", "friction_velocity.png"):
        assert f"]({name})" in text
        assert float(np.std(imread(out / name)[..., :3])) > 0.02, name
    # figure content: the phase plot spans x in nm; μ panel holds the study's range
    _, rebuilt = trajectory_from_bag(bag)
    fig = phase_figure(rebuilt, config.name, config.rig.convention)
    assert fig.axes[0].get_xlabel() == "displacement x (nm)"
    assert fig.axes[0].get_xlim()[1] == pytest.approx(rebuilt.displacement.max() * 1e9, rel=0.1)
    fig = friction_velocity_figure(rebuilt, config.name, config.rig.convention)
    lo, hi = fig.axes[0].get_lines()[0].get_ydata().min(), fig.axes[0].get_lines()[0].get_ydata().max()
    assert lo >= 6.48e-3 and hi <= 6.6e-3


def test_truncated_bag_one_error_line(recorded: tuple, tmp_path: Path) -> None:
    bag, _, _ = recorded
    broken = tmp_path / "broken"
    broken.mkdir()
    for f in bag.iterdir():
        data = f.read_bytes()
        (broken / f.name).write_bytes(data[: len(data) * 2 // 3] if f.suffix == ".mcap" else data)
    res = _cli("report", str(broken), "--out", str(tmp_path / "r"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "damaged" in lines[0], res.stderr
    res = _cli("report", str(tmp_path / "missing"), "--out", str(tmp_path / "r"))
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1


def test_bag_of_another_namespace(tmp_path: Path) -> None:
    """The rig namespace is taken from the bag's JointState <ns>/state topic."""
    bag = tmp_path / "bag"
    _, traj = _bag(bag, duration=0.5, namespace="/rig2")
    _, rebuilt = trajectory_from_bag(bag)
    np.testing.assert_array_equal(rebuilt.displacement, traj.displacement)
    np.testing.assert_array_equal(rebuilt.friction_coefficient, traj.friction_coefficient)
    np.testing.assert_array_equal(rebuilt.band_velocity, traj.band_velocity)
    res = _cli("report", str(bag), "--out", str(tmp_path / "report"))
    assert res.returncode == 0, res.stderr
    with pytest.raises(ReportError, match="fewer than 2 /lubrig/state"):
        trajectory_from_bag(bag, namespace="/lubrig")
