"""`lubrig rig` launcher: starts the nodes, waits for the sim run, stops them cleanly."""

from __future__ import annotations

import yaml


def test_lubrig_rig_sim_case(procs, tmp_path):
    out = tmp_path / "run"
    result = procs.run_script(
        "lubrig",
        "rig",
        "--case",
        "1",
        "--duration",
        "1.5",
        "--bag",
        str(out),
        "--no-recorder",
        timeout=180,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"results in {out}" in result.stdout
    saved = yaml.safe_load((out / "run_config.yaml").read_text())
    assert saved["name"] == "case01" and saved["simulation"]["duration"] == 1.5
    plant_log = (out / "logs" / "plant.log").read_text()
    assert "run complete" in plant_log


def test_lubrig_rig_rejects_bad_case(procs, tmp_path):
    result = procs.run_script("lubrig", "rig", "--case", "11", "--bag", str(tmp_path / "x"), timeout=60)
    assert result.returncode == 2
    assert "case=11" in result.stderr and "1..10" in result.stderr
