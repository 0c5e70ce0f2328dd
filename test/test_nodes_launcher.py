"""`lubrig rig` launcher: starts the nodes, waits for the sim run, stops them cleanly."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from test_nodes_support import new_domain, ros_env

pytestmark = pytest.mark.ros
LUBRIG = str(Path(sys.executable).parent / "lubrig")


def test_lubrig_rig_sim_case(tmp_path):
    out = tmp_path / "run"
    result = subprocess.run(
        [LUBRIG, "rig", "--case", "1", "--duration", "1.5", "--bag", str(out), "--no-recorder"],
        env=ros_env(new_domain()),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"results in {out}" in result.stdout
    saved = yaml.safe_load((out / "run_config.yaml").read_text())
    assert saved["name"] == "case01" and saved["simulation"]["duration"] == 1.5
    plant_log = (out / "logs" / "plant.log").read_text()
    assert "run complete" in plant_log


def test_lubrig_rig_rejects_bad_case(tmp_path):
    result = subprocess.run(
        [LUBRIG, "rig", "--case", "11", "--bag", str(tmp_path / "x")],
        env=ros_env(new_domain()),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 2
    assert "case=11" in result.stderr and "1..10" in result.stderr
