"""`lubrig fit` end to end: a CSV of `lubrig simulate` and a bag of `lubrig rig` (sim mode).

Both records are made with a damping ratio other than the start configuration's; the fit must
find it, and write a fit.json with every documented field and a config.yaml that the project's
loader reads and `lubrig simulate --config` runs to the same trajectory.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from lubrig_testkit.cli import lubrig
from lubrig_testkit.harness import Processes, ros_env

from lubrig_ros.core.presets import load_case, load_config
from lubrig_ros.core.profiles import TableBand
from lubrig_ros.fit.data import load_bag, load_csv

ZETA = 0.012  # the record's damping ratio; case 4 starts the fit from 0.01
DURATION = "2"


def _table(path: Path) -> dict[str, np.ndarray]:
    names = path.read_text().splitlines()[0].split(",")
    values = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: values[:, k] for k, name in enumerate(names)}


def test_fit_a_simulated_csv_and_run_the_fitted_config(tmp_path: Path) -> None:
    made = lubrig(
        "simulate", "--case", "4", "--zeta", str(ZETA), "--duration", DURATION, "--out", str(tmp_path / "sim")
    )
    assert made.returncode == 0, made.stderr
    record = tmp_path / "sim" / "timeseries.csv"
    out = tmp_path / "fit"
    res = lubrig("fit", str(record), "--case", "4", "--free", "damping_ratio", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""  # nothing undetermined
    document = json.loads((out / "fit.json").read_text())
    estimate = document["estimates"]["damping_ratio"]
    assert estimate["value"] == pytest.approx(ZETA, rel=1e-4)
    assert estimate["unit"] == "1" and estimate["bounds"] == [0.0, 2.0] and estimate["start"] == 0.01
    assert document["free"] == ["damping_ratio"] and document["fixed"]["natural_frequency"] == 10.0
    assert document["correlation"]["names"] == ["damping_ratio"]
    assert document["data"]["sha256"] == load_csv(record).fingerprint()
    for key in ("residual_rms", "cost", "function_evaluations", "undetermined", "initial_state", "method"):
        assert key in document
    for name in (
        "fit.md",
        "fit_time_history.png",
        "fit_residuals.png",
        "fit_friction.png",
        "fit_stability.png",
    ):
        assert (out / name).is_file(), name

    config = load_config(out / "config.yaml")
    assert config.rig.damping_ratio == pytest.approx(ZETA, rel=1e-4)
    assert config.rig.convention == "paper" and isinstance(config.band, TableBand)
    command = ["simulate", "--config", str(out / "config.yaml"), "--out", str(tmp_path / "rerun")]
    rerun = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", *command],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert rerun.returncode == 0, rerun.stderr
    original, again = _table(record), _table(tmp_path / "rerun" / "timeseries.csv")
    x, y = original["displacement_m"], again["displacement_m"]
    assert x.size == y.size
    assert np.max(np.abs(x - y)) < 1e-4 * np.ptp(x)

    refused = lubrig("fit", str(record), "--case", "4", "--free", "damping_ratio", "--out", str(out))
    assert refused.returncode == 2 and "--force" in refused.stderr

    stopped = tmp_path / "stopped"
    limit = ["--max-evaluations", "1"]
    cut = lubrig("fit", str(record), "--case", "4", "--free", "damping_ratio", *limit, "--out", str(stopped))
    assert cut.returncode == 0, cut.stderr
    warning = "lubrig fit: warning: the fit stopped after 1 evaluation(s) without converging"
    assert cut.stderr.startswith(warning), cut.stderr
    assert json.loads((stopped / "fit.json").read_text())["success"] is False
    assert "**not converged**" in (stopped / "fit.md").read_text()


def test_fit_a_sim_bag(ros_module_domain: int, tmp_path: Path) -> None:
    """The bag path: displacement and μ from state_block, band velocity from band_velocity_block."""
    config = load_case(4).to_dict()
    config["rig"]["damping_ratio"] = ZETA
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(config))
    procs = Processes(ros_env(ros_module_domain), tmp_path / "logs")
    try:
        args = ("rig", "--config", str(tmp_path / "rig.yaml"), "--duration", DURATION, "--no-report")
        made = procs.run_module("lubrig_ros.cli.main", *args, "--run-dir", str(tmp_path / "run"), timeout=240)
    finally:
        procs.stop_all(timeout=10)
    assert made.returncode == 0, made.stdout + made.stderr
    bag = tmp_path / "run" / "bag"
    data = load_bag(bag)
    assert data.time.size == 2001 and data.sample_rate == pytest.approx(1000.0)
    # the band stream's values, on the states' rig times (case 4 ramps by 9e-9 m/s per ms at first)
    assert data.band_velocity[:3] == pytest.approx([1e-7, 1.09e-7, 1.18e-7], rel=1e-9)
    assert data.friction_coefficient is not None
    res = lubrig("fit", str(bag), "--case", "4", "--free", "damping_ratio", "--out", str(tmp_path / "fit"))
    assert res.returncode == 0, res.stderr
    document = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert document["estimates"]["damping_ratio"]["value"] == pytest.approx(ZETA, rel=1e-4)
    assert document["data"]["source"].startswith("bag")
