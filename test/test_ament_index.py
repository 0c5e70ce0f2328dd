"""make setup registers lubrig_ros in the venv prefix's ament index as a colcon ament_python build does.

ROS-free: ament_index_python (in the venv) finds the package with the venv on AMENT_PREFIX_PATH,
which is what `ros2 run lubrig_ros <node>` and `ros2 launch lubrig_ros rig.launch.py` look up on a
machine with ROS 2 (ros2pkg: PREFIX/lib/<package>/<executable>, the share directory for launch
files). The registration itself (lubrig_ros/app/processes/ament_install.py) is checked in a scratch prefix.
"""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory

from lubrig_ros.app.processes import ament_install

ROOT = Path(__file__).resolve().parents[1]
PREFIX = Path(sys.prefix)
PACKAGE = "lubrig_ros"


def _scripts() -> list[str]:
    eps = importlib.metadata.distribution(PACKAGE).entry_points
    return sorted(ep.name for ep in eps if ep.group == "console_scripts")


@pytest.fixture
def venv_index(monkeypatch):
    """The venv prefix on AMENT_PREFIX_PATH (as a sourced ROS 2 setup plus `export AMENT_PREFIX_PATH`)."""
    found = ament_install.problems(ROOT, PREFIX)
    assert not found, f"lubrig_ros is not registered in {PREFIX} (run make setup): {found[:3]}"
    rest = os.environ.get("AMENT_PREFIX_PATH", "")
    monkeypatch.setenv("AMENT_PREFIX_PATH", os.pathsep.join(p for p in (str(PREFIX), rest) if p))
    return PREFIX


def test_the_index_finds_the_package_in_the_venv_prefix(venv_index):
    assert Path(get_package_prefix(PACKAGE)) == venv_index
    share = Path(get_package_share_directory(PACKAGE))
    assert share == venv_index / "share" / PACKAGE
    assert (venv_index / "share/ament_index/resource_index/packages" / PACKAGE).is_file()
    assert (share / "package.xml").read_text() == (ROOT / "package.xml").read_text()
    launch = share / "launch" / "rig.launch.py"
    assert launch.read_text() == (ROOT / "launch" / "rig.launch.py").read_text()
    assert launch.resolve() == (ROOT / "launch" / "rig.launch.py").resolve()  # a link: never stale
    yamls = sorted(p.name for p in (ROOT / "config").glob("*.yaml"))
    assert "nodes.yaml" in yamls  # what the launch file reads from the share directory
    assert sorted(p.name for p in (share / "config").glob("*.yaml")) == yamls
    for name in yamls:
        assert (share / "config" / name).read_text() == (ROOT / "config" / name).read_text()
    cases = sorted(p.name for p in (ROOT / "config" / "cases").glob("*.yaml"))
    assert sorted(p.name for p in (share / "config" / "cases").glob("*.yaml")) == cases


def test_every_console_script_is_an_executable_of_lib_lubrig_ros(venv_index):
    scripts = _scripts()
    assert {"plant", "belt_drive", "analysis", "recorder", "replay", "view"} <= set(scripts)
    lib = Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE
    # what ros2pkg's get_executable_paths lists: the executable files below PREFIX/lib/<package>
    listed = sorted(p.name for p in lib.iterdir() if p.is_file() and os.access(p, os.X_OK))
    assert listed == scripts


def test_lib_lubrig_ros_plant_answers_help(venv_index):
    plant = Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE / "plant"
    assert plant.is_file() and os.access(plant, os.X_OK)
    done = subprocess.run([str(plant), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: plant")
    assert "exit_when_complete" in done.stdout  # the launch file's parameter, from the contract


def _fake_prefix(tmp_path: Path) -> Path:
    prefix = tmp_path / "prefix"
    (prefix / "bin").mkdir(parents=True)
    for name in _scripts():
        script = prefix / "bin" / name
        script.write_text("#!/bin/sh\nexit 0\n")
        script.chmod(0o755)
    return prefix


def test_install_makes_links_once_and_removes_stale_entries(tmp_path):
    prefix = _fake_prefix(tmp_path)
    assert ament_install.problems(ROOT, prefix)  # nothing registered yet
    changed = ament_install.install(ROOT, prefix)
    assert changed and ament_install.problems(ROOT, prefix) == []
    assert ament_install.install(ROOT, prefix) == []  # current: nothing touched
    link = prefix / "share" / PACKAGE / "config" / "nodes.yaml"
    assert link.is_symlink() and link.resolve() == (ROOT / "config" / "nodes.yaml").resolve()
    assert (prefix / "lib" / PACKAGE / "plant").resolve() == (prefix / "bin" / "plant").resolve()
    stale = prefix / "share" / PACKAGE / "config" / "gone.yaml"
    stale.symlink_to(ROOT / "config" / "rig.yaml")
    wrong = prefix / "lib" / PACKAGE / "plant"
    wrong.unlink()
    wrong.symlink_to(prefix / "bin" / "view")
    found = ament_install.problems(ROOT, prefix)
    assert any("gone.yaml" in line for line in found)
    assert any("lib/lubrig_ros/plant" in line for line in found)
    assert ament_install.main(["--prefix", str(prefix), "--source", str(ROOT), "--check"]) == 1
    assert len(ament_install.install(ROOT, prefix)) == 2
    assert not stale.exists() and wrong.resolve() == (prefix / "bin" / "plant").resolve()
    assert ament_install.main(["--prefix", str(prefix), "--source", str(ROOT), "--check"]) == 0


def test_install_refuses_a_prefix_without_the_console_scripts(tmp_path, capsys):
    prefix = tmp_path / "empty"
    prefix.mkdir()
    assert ament_install.main(["--prefix", str(prefix), "--source", str(ROOT)]) == 1
    assert "run make setup" in capsys.readouterr().err
    assert not (prefix / "lib").exists() and not (prefix / "share").exists()
