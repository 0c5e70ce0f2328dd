"""Output folders: an existing non-empty one is refused with one clear line unless --force."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from lubrig_ros.cli.main import build_parser, main

LUBRIG = [sys.executable, "-m", "lubrig_ros.cli.main"]


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*LUBRIG, *args], capture_output=True, text=True, timeout=300, check=False)


def _occupied(tmp_path: Path) -> Path:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    return out


def _refused(res: subprocess.CompletedProcess, command: str, option: str, out: Path) -> None:
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0] == (
        f"lubrig {command}: error: {option} {str(out)!r} exists and is not empty (1 entries: notes.txt); "
        "pass --force to replace its contents, or choose a new folder"
    )


def test_simulate_refuses_then_force_replaces_the_run(tmp_path: Path) -> None:
    out = _occupied(tmp_path)
    res = _cli("simulate", "--case", "7", "--duration", "2", "--out", str(out))
    _refused(res, "simulate", "--out", out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # nothing written
    # an earlier run's figure that the new run does not draw (simulate draws no wavelet.png)
    (out / "wavelet.png").write_bytes(b"stale case 7 figure")
    res = _cli("simulate", "--case", "1", "--duration", "2", "--out", str(out), "--force")
    assert res.returncode == 0, res.stderr
    names = sorted(p.name for p in out.iterdir())
    assert "wavelet.png" not in names  # no stale figure beside the new run
    assert {"timeseries.csv", "config.yaml", "summary.json", "mu_velocity.png", "notes.txt"} <= set(names)
    assert "case01" in (out / "summary.json").read_text()
    assert (out / "notes.txt").read_text() == "mine\n"  # not the command's: kept


def test_simulate_into_an_empty_folder_needs_no_force(tmp_path: Path) -> None:
    assert main(["simulate", "--case", "1", "--duration", "1", "--out", str(tmp_path)]) == 0


def test_report_paper_and_rig_refuse(tmp_path: Path) -> None:
    out = _occupied(tmp_path)
    _refused(_cli("report", str(tmp_path / "bag"), "--out", str(out)), "report", "--out", out)
    _refused(_cli("paper", "--out", str(out), "--duration", "4"), "paper", "--out", out)
    _refused(_cli("rig", "--case", "1", "--run-dir", str(out)), "rig", "--run-dir", out)
    _refused(_cli("rig", "--case", "1", "--bag", str(out)), "rig", "--run-dir", out)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_paper_bad_duration_before_the_folder_check(tmp_path: Path) -> None:
    out = _occupied(tmp_path)
    res = _cli("paper", "--out", str(out), "--duration", "1")
    assert res.returncode == 2 and "--duration" in res.stderr and "not empty" not in res.stderr


@pytest.mark.parametrize("option", ["--run-dir", "--bag"])
def test_rig_run_dir_and_its_alias(option: str) -> None:
    args = build_parser().parse_args(["rig", "--case", "1", option, "runs/x"])
    assert args.run_dir == "runs/x" and args.force is False
    assert build_parser().parse_args(["rig", option, "x", "--force"]).force is True


def test_help_names_the_run_folder() -> None:
    res = _cli("rig", "--help")
    text = " ".join(res.stdout.split())
    assert "--run-dir DIR, --bag DIR" in text and "run folder" in text and "--force" in text
