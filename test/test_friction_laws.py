"""Friction laws as plug-ins: the registry, the Stribeck law (worked example), the compiled adapter.

The Stribeck law is checked against a 50-digit evaluation written straight from its formula; runs
with it go through YAML like any configuration; summaries, stability and flags work for a law
without a friction peak; and the compiled stepper never keeps a stale copy of a law's kernel.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import mpmath
import numpy as np
import pytest

from lubrig_ros.core.flags import evaluate_flags
from lubrig_ros.core.friction import (
    friction_coefficient,
    friction_landmarks,
    friction_law,
    friction_minimum,
    friction_peak,
    friction_slope,
    stick_velocity,
    stick_velocity_or_none,
)
from lubrig_ros.core.friction_laws import DEFAULT_LAW, law_named, law_names
from lubrig_ros.core.params import FrictionParameters, ParameterError, RigParameters
from lubrig_ros.core.presets import from_mapping, load_config
from lubrig_ros.core.run import simulate, summarize
from lubrig_ros.core.stability import friction_zone, linear_stability, unstable_intervals
from lubrig_ros.core.stribeck import StribeckParameters

DEFAULT = StribeckParameters()
GRID = np.logspace(-15, -2, 131) * 1.0371
GRID = GRID[GRID <= 1e-2]
NO_MINIMUM = StribeckParameters(viscous_coefficient=0.0)  # falls to μ_c and stays: peak only
NO_PEAK = StribeckParameters(static_coefficient=0.006)  # μ_s = μ_c: rises monotonically


def mp_mu(v: mpmath.mpf, p: StribeckParameters = DEFAULT) -> mpmath.mpf:
    """μ(v) for v > 0 from the module docstring's formula, in mpmath."""
    mpf = mpmath.mpf
    mu_s, mu_c = mpf(p.static_coefficient), mpf(p.kinetic_coefficient)
    bracket = mu_c + (mu_s - mu_c) * mpmath.exp(-((v / mpf(p.stribeck_velocity)) ** mpf(p.stribeck_exponent)))
    return mpmath.tanh(v / mpf(p.regularization_velocity)) * bracket + mpf(p.viscous_coefficient) * v


@pytest.fixture(scope="module")
def reference() -> tuple[np.ndarray, np.ndarray]:
    mu, slope = [], []
    with mpmath.workdps(50):
        for v in GRID:
            x = mpmath.mpf(float(v))
            mu.append(float(mp_mu(x)))
            slope.append(float(mpmath.diff(mp_mu, x, h=x * mpmath.mpf(10) ** -20)))
    return np.array(mu), np.array(slope)


def test_registry_names_both_laws_and_rejects_unknown_ones() -> None:
    assert law_names()[:2] == [DEFAULT_LAW, "stribeck"]
    assert friction_law().name == "junction_kinetics" and friction_law(DEFAULT).name == "stribeck"
    with pytest.raises(ParameterError, match=r"law='coulomb' is not valid; expected one of \['junction_kin"):
        law_named("coulomb")
    with pytest.raises(ParameterError, match="not a friction-law parameter set"):
        friction_coefficient(1e-7, object())


def test_stribeck_matches_a_50_digit_evaluation(reference: tuple[np.ndarray, np.ndarray]) -> None:
    mu_ref, slope_ref = reference
    mu, slope = friction_coefficient(GRID, DEFAULT), friction_slope(GRID, DEFAULT)
    np.testing.assert_allclose(mu, mu_ref, rtol=1e-12)
    # the slope crosses zero at the landmarks: compare relative to its local scale there
    scale = np.maximum(np.abs(slope_ref), DEFAULT.viscous_coefficient)
    assert np.max(np.abs(slope - slope_ref) / scale) < 1e-9


def test_stribeck_is_odd_with_an_even_finite_slope() -> None:
    v = np.concatenate((GRID, [1e-13, 1e-12, 3e-12]))
    np.testing.assert_array_equal(friction_coefficient(-v, DEFAULT), -friction_coefficient(v, DEFAULT))
    np.testing.assert_array_equal(friction_slope(-v, DEFAULT), friction_slope(v, DEFAULT))
    assert friction_coefficient(0.0, DEFAULT) == 0.0
    at_zero = float(friction_slope(0.0, DEFAULT))
    p = DEFAULT
    assert at_zero == p.static_coefficient / p.regularization_velocity + p.viscous_coefficient
    # continuous at 0: beside it the slope is smaller by ≈ (1 + δ)(μ_s − μ_c)(|v|/v_s)^δ / v_r → 0
    for v in (1e-18, 1e-24):
        rel = 1.5 * (0.16 - 0.006) * (v / 2e-9) ** 0.5 / 0.16
        assert float(friction_slope(v, DEFAULT)) == pytest.approx(at_zero * (1 - rel), rel=1e-3 * rel)


def test_stribeck_landmarks_are_stationary_points_near_the_study_laws() -> None:
    peak, minimum = friction_peak(DEFAULT), friction_minimum(DEFAULT)
    for mark in (peak, minimum):
        assert abs(float(friction_slope(mark.velocity, DEFAULT))) * mark.velocity < 1e-9 * mark.mu
        assert mark.mu == pytest.approx(float(friction_coefficient(mark.velocity, DEFAULT)), rel=1e-15)
    beside = friction_slope(peak.velocity * np.array([0.9, 1.1]), DEFAULT)
    assert beside[0] > 0 > beside[1]
    assert peak.velocity == pytest.approx(3.25e-12, rel=0.01) and peak.mu == pytest.approx(0.153, rel=0.01)
    assert minimum.velocity == pytest.approx(1.32e-7, rel=0.01)
    assert minimum.mu == pytest.approx(6.23e-3, rel=0.01)
    junction_peak, junction_min = friction_peak(), friction_minimum()  # the study's, for comparison
    assert 0.5 < peak.velocity / junction_peak.velocity < 2
    assert 0.5 < minimum.velocity / junction_min.velocity < 2


def test_laws_without_landmarks_say_so() -> None:
    peak, minimum = friction_landmarks(NO_MINIMUM)
    assert peak is not None and minimum is None
    assert friction_landmarks(NO_PEAK) == (None, None)
    assert np.all(friction_slope(GRID, NO_PEAK) > 0)
    with pytest.raises(ParameterError, match=r"stribeck friction law has no friction peak .*=0\.006"):
        friction_peak(NO_PEAK)
    with pytest.raises(ParameterError, match="no friction minimum"):
        friction_minimum(NO_MINIMUM)
    with pytest.raises(ParameterError, match="no friction peak"):
        stick_velocity(NO_PEAK)
    assert stick_velocity_or_none(NO_PEAK) is None
    assert stick_velocity_or_none(NO_MINIMUM) == peak.velocity


def test_stribeck_parameters_are_validated() -> None:
    for bad, text in (
        ({"static_coefficient": -0.1}, "static_coefficient=-0.1 must be >= 0"),
        ({"stribeck_exponent": 0.0}, r"stribeck_exponent=0.0 is outside the valid range \(0, 10\]"),
        ({"regularization_velocity": 0.0}, "regularization_velocity=0.0 must be > 0"),
        ({"stribeck_velocity": float("nan")}, "stribeck_velocity=nan is not finite"),
        ({"normal_force": "heavy"}, "normal_force='heavy' is not a number"),
    ):
        with pytest.raises(ParameterError, match=text):
            StribeckParameters(**bad)


def test_yaml_names_the_law_and_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "stribeck.yaml"
    path.write_text(
        "rig:\n  friction:\n    law: stribeck\n    viscous_coefficient: 2000.0\n"
        "band: {kind: constant, velocity: 1.0e-6}\nsimulation: {duration: 0.5}\n"
    )
    config = load_config(path)
    # not merged with the default law's fields
    assert config.rig.friction == StribeckParameters(viscous_coefficient=2000.0)
    assert config.to_dict()["rig"]["friction"]["law"] == "stribeck"
    assert from_mapping(config.to_dict()) == config
    # the default law is still written without `law`, exactly as before
    assert "law" not in from_mapping({}).to_dict()["rig"]["friction"]
    assert from_mapping({"rig": {"friction": {"law": "junction_kinetics"}}}) == from_mapping({})
    with pytest.raises(ParameterError, match=r"unknown stribeck friction parameter\(s\) \['shear_modulus'\]"):
        from_mapping({"rig": {"friction": {"law": "stribeck", "shear_modulus": 1.0}}})
    with pytest.raises(ParameterError, match="law='coulomb' is not valid"):
        from_mapping({"rig": {"friction": {"law": "coulomb"}}})


def test_simulate_with_the_stribeck_law_matches_its_equilibrium_and_stability(tmp_path: Path) -> None:
    """Zone 3 band (stable): the run settles on x0 = N μ(v)/k; zone 2 band, undamped: it sticks."""
    stable = from_mapping(
        {
            "rig": {"friction": {"law": "stribeck"}, "damping_ratio": 0.05},
            "band": {"kind": "constant", "velocity": 1e-6},
            "simulation": {"duration": 2.0},
        }
    )
    verdict = linear_stability(1e-6, stable.rig)
    assert verdict.zone == 3 and verdict.stable
    trajectory = simulate(stable)
    x0 = verdict.equilibrium_displacement
    assert trajectory.displacement[0] == pytest.approx(1.01 * x0, rel=1e-12)
    assert abs(trajectory.displacement[-1] - x0) < 1e-3 * x0  # the 1 % perturbation has decayed
    np.testing.assert_allclose(
        trajectory.friction_coefficient,
        friction_coefficient(trajectory.relative_velocity, stable.rig.friction),
        rtol=1e-15,
    )
    summary = summarize(trajectory, stable)
    assert summary["stick_threshold_m_s"] == friction_peak(DEFAULT).velocity
    assert summary["stick_fraction"] == 0.0

    unstable = replace(
        stable, band=replace(stable.band, velocity=1e-8), rig=replace(stable.rig, damping_ratio=0.0)
    )
    verdict = linear_stability(1e-8, unstable.rig)
    assert verdict.zone == 2 and not verdict.stable
    run = simulate(unstable)
    # the perturbation grows into a slip, after which the mass sticks to the band (the stick phase
    # of a stick-slip cycle lasts ≈ N Δμ / (k v_band) ≈ 40 s, longer than the run)
    assert np.ptp(run.velocity[run.time < 0.05]) > 100 * unstable.band.velocity
    assert summarize(run, unstable)["stick_fraction"] == 1.0


def test_summary_stability_and_flags_for_a_law_without_a_peak() -> None:
    rig = RigParameters(friction=NO_PEAK, damping_ratio=0.01)
    config = from_mapping(
        {
            "rig": {"friction": {"law": "stribeck", "static_coefficient": 0.006}, "damping_ratio": 0.01},
            "simulation": {"duration": 0.5},
        }
    )
    assert config.rig == rig
    summary = summarize(simulate(config), config)
    assert summary["stick_threshold_m_s"] is None and summary["stick_fraction"] is None
    assert np.isfinite(summary["x_peak_to_peak"])
    verdict = linear_stability(1e-7, rig)
    assert verdict.zone is None and verdict.stable and verdict.critical_damping_ratio == 0.0
    assert unstable_intervals(0.0, rig) == []  # μ rises everywhere: never unstable
    with pytest.raises(ParameterError, match="no friction peak"):
        friction_zone(1e-7, rig)
    flags = evaluate_flags(rig, band_velocity=1e-7, relative_velocity=np.full(16, 1e-7), dt=1e-3)
    assert flags.zone is None and flags.zone_name is None and flags.linear_stable is True
    assert flags.stick_threshold_m_s is None and flags.stick_share is None
    given = evaluate_flags(rig, relative_velocity=np.full(16, 1e-9), dt=1e-3, stick_threshold_m_s=1e-8)
    assert given.stick_share == 1.0


def test_a_law_with_a_peak_but_no_minimum_has_no_zone_3() -> None:
    rig = RigParameters(friction=NO_MINIMUM)
    peak = friction_peak(NO_MINIMUM).velocity
    np.testing.assert_array_equal(friction_zone([peak / 2, peak * 2, 1e-3], rig), [1, 2, 2])


def test_default_law_figures_are_unchanged() -> None:
    """The junction law through the registry gives what it gave before laws had names."""
    assert friction_landmarks() == (friction_peak(), friction_minimum())
    assert friction_landmarks(FrictionParameters()) == friction_landmarks()
    assert friction_peak().velocity == 4.079249922642719e-12  # printed before this change
    assert friction_minimum().velocity == 1.3539537323168316e-07


LAW_MODULE = """
import math
from dataclasses import dataclass
from typing import ClassVar

from lubrig_ros.core.friction_laws import KernelLaw, register_law
from lubrig_ros.core.friction_laws import law_kernel


@dataclass(frozen=True)
class LinearParameters:
    law: ClassVar[str] = "linear_test"
    slope: float = 1e6
    normal_force: float = 1e-3


@law_kernel
def linear_kernel(v, p):
    return SCALE * p[0] * math.tanh(v / 1e-9) * 1e-9, SCALE * p[0] / math.cosh(v / 1e-9) ** 2


class Linear(KernelLaw):
    name = "linear_test"
    parameters = LinearParameters
    kernel = linear_kernel


register_law(Linear())
"""

RUN = """
import json, sys
sys.path.insert(0, sys.argv[1])
import lawmod
from lubrig_ros.core import junction, kernels
from lubrig_ros.core.integrator import RigIntegrator
from lubrig_ros.core.params import RigParameters
out = RigIntegrator(RigParameters(friction=lawmod.LinearParameters()), 1e-7).advance([1e-7] * 5)
RigIntegrator(RigParameters(), 1e-7).advance([1e-7] * 5)  # the default law, same process
law_stepper = kernels.specialize(lawmod.linear_kernel)[0]
default_stepper = kernels.specialize(junction.mu_and_slope)[0]
print(json.dumps({
    "mu": float(out.friction_coefficient[-1]),
    "x": float(out.displacement[-1]),
    "law_stepper_misses": sum(law_stepper.stats.cache_misses.values()),
    "default_stepper_hits": sum(default_stepper.stats.cache_hits.values()),
}))
"""


def _run_law(folder: Path) -> dict[str, float]:
    done = subprocess.run(
        [sys.executable, "-c", RUN, str(folder)], capture_output=True, text=True, timeout=600, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_changed_law_file_recompiles_that_laws_stepper_and_nothing_else(tmp_path: Path) -> None:
    """Fresh processes: edit a law's module between two runs; the new law runs, not a stale copy.

    The law's kernel is inlined into its own compiled stepper, whose cache is keyed on kernels.py
    and on the law's file (core.kernels._LawLocator); the default law's stepper is not touched.
    """
    module = tmp_path / "lawmod.py"
    module.write_text("SCALE = 1.0\n" + textwrap.dedent(LAW_MODULE))
    first = _run_law(tmp_path)
    module.write_text("SCALE = 2.25\n" + textwrap.dedent(LAW_MODULE))
    second = _run_law(tmp_path)
    assert second["law_stepper_misses"] >= 1  # its law's file changed: compiled again
    assert second["default_stepper_hits"] >= 1  # the default law's stepper came from the cache
    assert second["mu"] == pytest.approx(2.25 * first["mu"], rel=1e-12)  # the new law ran
    assert second["x"] != first["x"]
    third = _run_law(tmp_path)  # unchanged file: from the cache, same result
    assert third["law_stepper_misses"] == 0
    assert (third["mu"], third["x"]) == (second["mu"], second["x"])
