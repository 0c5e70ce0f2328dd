"""The velocity coupling γ (v_rel = v_band − γ ẋ) as a first-class parameter: conventions, explicit
values, YAML, CLI, sweep axis, records, and the same γ in the linear stability."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from lubrig_ros.core.params import CONVENTIONS, ParameterError, RigParameters
from lubrig_ros.core.presets import from_mapping, load_case
from lubrig_ros.core.run import simulate, summarize
from lubrig_ros.core.stability import critical_damping_ratio, linear_stability
from lubrig_ros.sweep import parse_spec

LUBRIG = [sys.executable, "-m", "lubrig_ros.cli.main"]


def lubrig(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*LUBRIG, *args], capture_output=True, text=True, timeout=120, check=False)


def test_named_conventions_and_explicit_gamma() -> None:
    omega0 = 2 * math.pi * 10.0
    expected = {"physical": 1.0, "paper": 1 / omega0, "hertz": 0.1}
    assert set(CONVENTIONS) == set(expected)
    for name, gamma in expected.items():
        rig = RigParameters(convention=name)
        assert rig.velocity_factor == pytest.approx(gamma, rel=1e-15)
        assert rig.coupling_name == name
        by_coupling = RigParameters(velocity_coupling=name)
        assert by_coupling.convention == name and by_coupling.velocity_coupling is None
    explicit = RigParameters(convention="paper", velocity_coupling=0.05)
    assert explicit.velocity_factor == 0.05 and explicit.coupling_name == "explicit"
    # s = γ · A / A_default: the printed area with γ = 1 is the hertz reading's s
    printed = RigParameters(friction=RigParameters().friction.with_contact_area("printed"))
    assert printed.coupling_strength == pytest.approx(RigParameters(convention="hertz").coupling_strength)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, "ohm", True])
def test_bad_coupling_names_value_and_choices(bad: object) -> None:
    with pytest.raises(ParameterError, match=r"velocity_coupling=.*physical.*number > 0"):
        RigParameters(velocity_coupling=bad)  # type: ignore[arg-type]


def test_yaml_accepts_names_and_numbers_and_old_files_still_work() -> None:
    assert from_mapping({"rig": {"velocity_coupling": "hertz"}}).rig.velocity_factor == 0.1
    assert from_mapping({"rig": {"velocity_coupling": 0.07}}).rig.velocity_factor == 0.07
    assert from_mapping({"rig": {"convention": "paper"}}).rig.coupling_name == "paper"
    config = load_case(3).with_overrides(velocity_coupling=0.07)
    again = from_mapping(yaml.safe_load(config.to_yaml()))
    assert again.rig.velocity_factor == 0.07 and again == config
    # a named convention given later replaces an explicit γ
    assert config.with_overrides(convention="physical").rig.velocity_factor == 1.0


def test_integrator_and_summary_use_and_record_gamma() -> None:
    config = load_case(1).with_overrides(velocity_coupling=0.05, duration=1.0)
    trajectory = simulate(config)
    assert np.allclose(
        trajectory.relative_velocity,
        trajectory.band_velocity - 0.05 * trajectory.velocity,
        rtol=0,
        atol=1e-22,
    )
    summary = summarize(trajectory, config)
    assert summary["velocity_coupling"] == 0.05 and summary["convention"] == "explicit"
    assert summary["coupling_strength"] == pytest.approx(0.05)
    # only s enters v_rel: γ = 0.5 with a 10 × smaller area gives x scaled by 1/γ ratio
    base = load_case(4).with_overrides(duration=2.0, velocity_coupling=0.05)
    area = replace(base.rig.friction, contact_area=base.rig.friction.contact_area / 10)
    other = replace(base, rig=replace(base.rig, velocity_coupling=0.5, friction=area))
    a, b = simulate(base), simulate(other)
    assert np.allclose(a.relative_velocity, b.relative_velocity, rtol=1e-6, atol=1e-16)


def test_stability_uses_the_same_gamma() -> None:
    v = np.logspace(-11, -7.2, 20)
    unit = RigParameters(velocity_coupling=1.0)
    for gamma in (0.01, 0.1, "paper"):
        rig = RigParameters(velocity_coupling=gamma)
        ratio = critical_damping_ratio(v, rig) / critical_damping_ratio(v, unit)
        assert np.allclose(ratio, rig.velocity_factor, rtol=1e-12)
    # V1 = 1e-7 m/s at ζ = 0.01: stable with the paper γ, unstable with γ = 0.1
    assert linear_stability(1e-7, RigParameters(convention="paper")).stable
    assert not linear_stability(1e-7, RigParameters(convention="hertz")).stable


def test_cli_simulate_and_stability_take_velocity_coupling(tmp_path: Path) -> None:
    res = lubrig(
        "simulate", "--case", "4", "--duration", "1", "--velocity-coupling", "hertz", "--out", str(tmp_path)
    )
    assert res.returncode == 0, res.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["convention"] == "hertz" and summary["velocity_coupling"] == 0.1
    assert yaml.safe_load((tmp_path / "config.yaml").read_text())["rig"]["convention"] == "hertz"
    res = lubrig("stability", "--json", "--velocity-coupling", "0.1")
    assert res.returncode == 0, res.stderr
    report = json.loads(res.stdout)
    assert report["velocity_coupling"] == 0.1 and report["convention"] == "explicit"
    hertz = json.loads(lubrig("stability", "--json", "--convention", "hertz").stdout)
    assert hertz["results"] == report["results"]
    bad = lubrig("simulate", "--case", "1", "--velocity-coupling", "-2", "--out", str(tmp_path / "x"))
    assert (
        bad.returncode == 2 and "--velocity-coupling '-2'" in bad.stderr and len(bad.stderr.splitlines()) == 1
    )


def test_velocity_coupling_is_a_sweep_axis() -> None:
    spec = parse_spec(
        {
            "base_case": 8,
            "wavelet": False,
            "axes": [{"parameter": "rig.velocity_coupling", "values": ["paper", 0.05, 0.1]}],
        }
    )
    gammas = [from_mapping(p.config).rig.velocity_factor for p in spec.points]
    assert gammas == pytest.approx([1 / (20 * math.pi), 0.05, 0.1])


def test_plant_parameter_velocity_coupling() -> None:
    from lubrig_ros.app.interface.contract import parameter
    from lubrig_ros.app.plant.session import config_from, parameter_defaults

    base = load_case(8)
    assert parameter_defaults(base)["velocity_coupling"] == 0.0  # no explicit γ in the preset
    assert config_from(base, {}).rig == base.rig
    assert config_from(base, {"velocity_coupling": 0.07}).rig.velocity_factor == 0.07
    explicit = base.with_overrides(velocity_coupling=0.07)
    assert parameter_defaults(explicit)["velocity_coupling"] == 0.07
    assert config_from(explicit, {"velocity_coupling": 0.0}).rig.coupling_name == "paper"
    spec = parameter("plant", "velocity_coupling")
    assert not spec.read_only and spec.check(0.1) == 0.1
    with pytest.raises(ValueError):
        spec.check(-0.1)
