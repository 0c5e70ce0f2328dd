"""A sim rig whose friction law cannot give a sample: the run ends non-zero, naming it; nothing made up.

The law is an extension law (core.friction_laws.register_law), loaded into every process of the
rig (launcher, nodes, recorder) by a sitecustomize module on PYTHONPATH, as a user's own law
would be. It is well behaved below V_FAIL and undefined (NaN) above it; the band is a sine
that crosses V_FAIL after a few dozen samples. The plant must publish only the samples it
integrated, end with EXIT_INTEGRATION_FAILED, and `lubrig rig` must say why (time, band value,
parameters) with that status, leaving a bag that verifies and holds exactly those samples.
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from lubrig_testkit.crosscheck import read_mcap, read_rosbags

from lubrig_ros.app.interface.contract import EXIT_INTEGRATION_FAILED

V_FAIL = 1.5e-7  # m/s: the law has no value above this relative velocity

LAW = f"""
import math
from dataclasses import dataclass
from typing import ClassVar

from lubrig_ros.core.friction_laws import KernelLaw, register_law
from lubrig_ros.core.friction_laws import law_kernel


@dataclass(frozen=True)
class BrokenParameters:
    law: ClassVar[str] = "broken_above_test"
    slope: float = 1e5
    normal_force: float = 1e-3


@law_kernel
def broken_kernel(v, p):
    if abs(v) > {V_FAIL!r}:
        return math.nan, math.nan
    return p[0] * 1e-9 * math.tanh(v / 1e-9), p[0] / math.cosh(v / 1e-9) ** 2


class Broken(KernelLaw):
    name = "broken_above_test"
    parameters = BrokenParameters
    kernel = broken_kernel


register_law(Broken())
"""


@pytest.mark.slow  # a whole `lubrig rig` run with recorder
def test_a_sample_that_cannot_be_integrated_ends_the_sim_rig_naming_it(procs, tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "broken_law.py").write_text(textwrap.dedent(LAW))
    (site / "sitecustomize.py").write_text("import broken_law  # noqa: F401\n")
    config = tmp_path / "broken.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "name": "broken_law_run",
                "rig": {"friction": {"law": "broken_above_test", "slope": 1e5, "normal_force": 1e-3}},
                "band": {"kind": "sine", "mean_velocity": 1e-7, "amplitude": 1e-7, "frequency": 5.0},
                "simulation": {"duration": 2.0},
            }
        )
    )
    env = {**procs.env, "PYTHONPATH": str(site)}
    run = tmp_path / "run"
    res = procs.run_module(
        "lubrig_ros.cli.main", "rig", "--config", str(config), "--bag", str(run), timeout=300, env=env
    )
    assert res.returncode == EXIT_INTEGRATION_FAILED, res.stdout + res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith("lubrig rig: error: the run ends") and "integration failed at t = " in line, line
    assert "band velocity" in line and "rtol" in line and "BrokenParameters(slope=" in line, line
    plant_log = (run / "logs" / "plant.log").read_text()
    # said once by the session (ERROR) and once as the node ends (FATAL); no warning after it
    assert plant_log.count("; no more output until a reset") == 1, plant_log
    assert plant_log.count("[FATAL]") == 1 and "band block starts at sample" not in plant_log, plant_log
    # the bag verifies and holds the samples before the failure, every one once, all finite
    check = procs.run_module("lubrig_ros.cli.main", "bag", "check", str(run / "bag"), env=env)
    assert check.returncode == 0, check.stdout + check.stderr
    by_rosbags, by_mcap = read_rosbags(run / "bag"), read_mcap(run / "bag")
    assert by_rosbags == by_mcap
    x = np.array(by_rosbags["/lubrig/state_block"])
    assert 1 < x.size < 2000 and np.isfinite(x).all()
    accounting = json.loads((run / "bag" / "accounting.json").read_text())
    assert accounting["streams"]["/lubrig/state_block"]["samples"] == x.size
    # the failure is where the band crosses V_FAIL: t = first sample whose band exceeds it
    t_fail = float(line.split("integration failed at t = ")[1].split(" s")[0])
    t = np.arange(0, 2.0, 1e-3)
    band = 1e-7 + 1e-7 * np.sin(2 * np.pi * 5.0 * t)
    assert t_fail <= t[np.argmax(band > V_FAIL)] + 1e-3
    assert x.size == round(t_fail * 1000)  # the initial state and every sample before the failed one
