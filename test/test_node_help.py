"""Every node executable answers -h / --help with its usage and exits 0 without starting."""

from __future__ import annotations

import subprocess

import pytest
from lubrig_testkit.harness import BIN

from lubrig_ros.app.interface.contract import NODE_PARAMETERS


@pytest.mark.parametrize("name", sorted(NODE_PARAMETERS))
@pytest.mark.parametrize("flag", ["-h", "--help"])
def test_rig_node_help_lists_every_parameter_and_does_not_start(name: str, flag: str) -> None:
    res = subprocess.run([str(BIN / name), flag], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(f"usage: {name} ") and "docs/nodes.md" in res.stdout
    for p in NODE_PARAMETERS[name]:
        assert f"  {p.name} ({p.type}, default " in res.stdout, p.name
    assert f"{name}: mode=" not in res.stdout + res.stderr  # the node never started
    assert not res.stderr


@pytest.mark.parametrize("name", ["recorder", "replay", "view"])
def test_script_nodes_help(name: str) -> None:
    res = subprocess.run([str(BIN / name), "--help"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and res.stdout.startswith("usage:"), res.stderr
