"""`lubrig simulate`: files, summary, figures, errors.

The case-1 run and one bad value go through the real script (`python -m lubrig_ros.cli.main`);
the other runs call the same main() in-process (lubrig_testkit.cli), which is cheaper.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.cli import lubrig
from lubrig_testkit.figures import plotted_range
from matplotlib.image import imread

from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.figures.timeseries import FIGURES

LUBRIG = [sys.executable, "-m", "lubrig_ros.cli.main"]
HEADER = "time_s,displacement_m,velocity_m_s,friction_coefficient,band_velocity_m_s,relative_velocity_m_s"


def lubrig_process(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*LUBRIG, *args], capture_output=True, text=True, timeout=120, check=False)


@pytest.fixture(scope="module")
def case1_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sim") / "case1"
    res = lubrig_process("simulate", "--case", "1", "--duration", "4", "--out", str(out))
    assert res.returncode == 0, res.stderr
    return out


def test_writes_csv_equal_to_core_run(case1_dir):
    text = (case1_dir / "timeseries.csv").read_text().splitlines()
    assert text[0] == HEADER
    data = np.loadtxt(case1_dir / "timeseries.csv", delimiter=",", skiprows=1)
    ref = simulate(load_case(1).with_overrides(duration=4.0))
    assert data.shape == (4001, 6)
    assert np.array_equal(data[:, 1], ref.displacement)
    assert np.array_equal(data[:, 3], ref.friction_coefficient)


def test_summary_has_contract_keys(case1_dir):
    summary = json.loads((case1_dir / "summary.json").read_text())
    for key in (
        "convention",
        "duration",
        "x_peak_to_peak",
        "mu_min",
        "mu_max",
        "stick_fraction",
        "dominant_frequencies_hz",
    ):
        assert key in summary
    assert summary["convention"] == "paper"
    assert summary["duration"] == 4.0
    assert 6.48e-3 < summary["mu_min"] < summary["mu_max"] < 6.6e-3
    assert abs(summary["band_fundamental_hz"] - 1 / 0.21) < 1e-12


def test_config_file_repeats_the_run(case1_dir, tmp_path):
    res = lubrig("simulate", "--config", str(case1_dir / "config.yaml"), "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "timeseries.csv").read_bytes() == (case1_dir / "timeseries.csv").read_bytes()


def test_figures_have_content(case1_dir):
    for name in FIGURES:
        image = imread(case1_dir / name)
        assert image.shape[0] > 300 and image.shape[1] > 400
        assert float(np.std(image[..., :3])) > 0.05, name  # not blank


def test_figure_axes_and_data():
    config = load_case(1).with_overrides(duration=2.0)
    traj = simulate(config)
    fig = FIGURES["time_history.png"](traj, "case01", "paper")
    assert fig.axes[0].get_ylabel() == "displacement x (nm)"
    assert fig.axes[1].get_xlabel() == "time t (s)"
    lo, hi = plotted_range(fig, 0)
    assert lo == pytest.approx(traj.displacement.min() * 1e9)
    assert hi == pytest.approx(traj.displacement.max() * 1e9)
    assert "paper convention" in fig.axes[0].get_title()
    phase = FIGURES["phase.png"](traj, "case01", "paper")
    assert phase.axes[0].get_xlabel() == "displacement x (nm)"
    assert phase.axes[0].get_ylabel() == "velocity ẋ (m/s)"
    mu = FIGURES["friction_velocity.png"](traj, "case01", "paper")
    assert plotted_range(mu, 0) == pytest.approx(
        (traj.friction_coefficient.min(), traj.friction_coefficient.max())
    )


def test_profile_csv_and_overrides(tmp_path):
    csv = tmp_path / "band.csv"
    csv.write_text("time_s,band_velocity_m_s\n0,1e-7\n0.5,2e-7\n1,1e-7\n")
    out = tmp_path / "out"
    res = lubrig(
        "simulate",
        "--profile",
        str(csv),
        "--convention",
        "paper",
        "--zeta",
        "0.05",
        "--duration",
        "1",
        "--out",
        str(out),
    )
    assert res.returncode == 0, res.stderr
    data = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)
    assert data[500, 4] == pytest.approx(2e-7)
    assert "damping_ratio: 0.05" in (out / "config.yaml").read_text()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--mass", "-0.1"], "mass=-0.1"),
        (["--duration", "0"], "duration=0.0"),
        (["--cycle", "2e-7", "1e-7", "0.1", "0.2"], "V2 > V1"),
        (["--case", "11"], "case='11'"),
        (["--profile", "/nonexistent/band.csv"], "/nonexistent/band.csv"),
        (["--band-velocity", "nan"], "'nan'"),
        (["--zeta", "-0.5"], "damping_ratio=-0.5"),
        (["--convention", "sideways"], "sideways"),
    ],
)
def test_bad_values_one_line(args, needle, tmp_path):
    res = lubrig("simulate", *args, "--out", str(tmp_path / "x"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], res.stderr
    assert not (tmp_path / "x").exists()


def test_bad_value_one_line_from_the_real_script(tmp_path):
    res = lubrig_process("simulate", "--mass", "-0.1", "--out", str(tmp_path / "x"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "mass=-0.1" in lines[0], res.stderr
    assert not (tmp_path / "x").exists()
