"""Friction law: study landmarks, symmetry, contact area, and an independent 50-digit check."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from lubrig_ros.core.friction import (
    friction_coefficient,
    friction_minimum,
    friction_peak,
    friction_slope,
)
from lubrig_ros.core.params import CONTACT_AREA_PRINTED, FrictionParameters

DEFAULT = FrictionParameters()
# log grid over the full operating range, offset so no point sits exactly on a decade
GRID = np.logspace(-15, -2, 131) * 1.0371
GRID = GRID[GRID <= 1e-2]


def mp_mu(v: mpmath.mpf, p: FrictionParameters = DEFAULT) -> mpmath.mpf:
    """μ(v) for v > 0 written straight from the model document, no rearrangement."""
    mpf = mpmath.mpf
    tau0 = mpf(p.thermal_break_time)
    v0 = mpf(p.yield_distance) / tau0
    u = v0 / v
    t_b = tau0 * (1 - mpmath.exp(-u))
    s = v * tau0 * (1 - (1 + u) * mpmath.exp(-u)) / (1 - mpmath.exp(-u))
    v_ref = mpf(p.reference_velocity)
    tau = mpf(p.reference_activation_time) * (v / v_ref) ** mpf(p.activation_exponent)
    phi = t_b / (t_b + tau)
    eta = mpf(p.reference_viscosity) * (v / v_ref) ** mpf(p.shear_thinning_exponent)
    sigma_el = mpf(p.shear_modulus) * phi * s / mpf(p.interface_thickness)
    sigma_visc = (1 - phi) * eta * v / mpf(p.interpenetration_thickness)
    return mpf(p.contact_area) / mpf(p.normal_force) * (sigma_el + sigma_visc)


@pytest.fixture(scope="module")
def reference() -> tuple[np.ndarray, np.ndarray]:
    mu, slope = [], []
    with mpmath.workdps(50):
        for v in GRID:
            x = mpmath.mpf(float(v))
            mu.append(float(mp_mu(x)))
            # relative step: the default absolute step would exceed v at 1e-15 m/s
            slope.append(float(mpmath.diff(mp_mu, x, h=x * mpmath.mpf(10) ** -20)))
    return np.array(mu), np.array(slope)


def test_peak_matches_study_landmark() -> None:
    peak = friction_peak()
    assert peak.mu == pytest.approx(0.161, rel=0.01)
    assert peak.velocity == pytest.approx(4.08e-12, rel=0.01)


def test_minimum_matches_study_landmark() -> None:
    minimum = friction_minimum()
    assert minimum.mu == pytest.approx(6.486e-3, rel=0.01)
    assert minimum.velocity == pytest.approx(1.35e-7, rel=0.01)


@pytest.mark.parametrize(("velocity", "expected"), [(1e-7, 6.553e-3), (2e-7, 6.593e-3), (1e-6, 9.20e-3)])
def test_band_velocity_values_match_study(velocity: float, expected: float) -> None:
    assert float(friction_coefficient(velocity)) == pytest.approx(expected, rel=0.01)


def test_study_range_between_v1_and_v2_cases_1_to_3() -> None:
    # the study: μ stays between 6.5e-3 and 6.6e-3 for band velocities 1e-7 … 2e-7 m/s
    mu = friction_coefficient(np.linspace(1e-7, 2e-7, 201))
    assert mu.min() > 6.48e-3
    assert mu.max() < 6.6e-3


def test_landmarks_are_stationary_points() -> None:
    peak, minimum = friction_peak(), friction_minimum()
    for point in (peak, minimum):
        v = point.velocity
        assert abs(float(friction_slope(v))) < 1e-6 * abs(float(friction_slope(v / 2)))
    assert (friction_coefficient([peak.velocity * 0.99, peak.velocity * 1.01]) < peak.mu).all()
    neighbours = friction_coefficient([minimum.velocity * 0.99, minimum.velocity * 1.01])
    assert (neighbours > minimum.mu).all()


def test_mu_is_odd_and_slope_even() -> None:
    v = np.concatenate([GRID, [0.0]])
    np.testing.assert_array_equal(friction_coefficient(-v), -friction_coefficient(v))
    np.testing.assert_array_equal(friction_slope(-GRID), friction_slope(GRID))
    assert float(friction_coefficient(0.0)) == 0.0


def test_printed_area_gives_exactly_ten_times_smaller_mu() -> None:
    printed = DEFAULT.with_contact_area("printed")
    assert printed.contact_area == CONTACT_AREA_PRINTED
    ratio = friction_coefficient(GRID) / friction_coefficient(GRID, printed)
    np.testing.assert_allclose(ratio, 10.0, rtol=1e-13)
    slope_ratio = friction_slope(GRID) / friction_slope(GRID, printed)
    np.testing.assert_allclose(slope_ratio, 10.0, rtol=1e-13)
    # the stationary points do not move with A, only their height
    assert friction_peak(printed).velocity == pytest.approx(friction_peak().velocity, rel=1e-9)
    assert friction_peak(printed).mu == pytest.approx(friction_peak().mu / 10, rel=1e-12)


def test_value_matches_50_digit_reference(reference: tuple[np.ndarray, np.ndarray]) -> None:
    mu_ref, _ = reference
    rel = np.abs(friction_coefficient(GRID) / mu_ref - 1.0)
    assert rel.max() < 1e-12, f"worst at v={GRID[rel.argmax()]:.3e}: {rel.max():.2e}"


def test_slope_matches_50_digit_reference(reference: tuple[np.ndarray, np.ndarray]) -> None:
    _, slope_ref = reference
    rel = np.abs(friction_slope(GRID) / slope_ref - 1.0)
    assert rel.max() < 1e-10, f"worst at v={GRID[rel.argmax()]:.3e}: {rel.max():.2e}"


def test_slope_sign_defines_the_three_zones(reference: tuple[np.ndarray, np.ndarray]) -> None:
    _, slope_ref = reference
    peak, minimum = friction_peak().velocity, friction_minimum().velocity
    v = GRID
    expected_sign = np.where((v > peak) & (v < minimum), -1.0, 1.0)
    np.testing.assert_array_equal(np.sign(slope_ref), expected_sign)
    np.testing.assert_array_equal(np.sign(friction_slope(GRID)), expected_sign)


def test_finite_over_the_whole_range() -> None:
    v = np.logspace(-15, -2, 20001)
    for values in (friction_coefficient(v), friction_slope(v)):
        assert np.isfinite(values).all()
    assert (friction_coefficient(v) > 0).all()


def test_series_switch_is_seamless() -> None:
    # u = v0/v = 0.1 is where the kernels switch from closed forms to series
    v_switch = DEFAULT.critical_velocity / 0.1
    v = v_switch * (1.0 + np.array([-1e-12, 0.0, 1e-12]))
    mu, slope = friction_coefficient(v), friction_slope(v)
    assert np.ptp(mu) / mu[1] < 1e-11
    assert np.ptp(slope) / abs(slope[1]) < 1e-9


def test_nan_velocity_is_rejected() -> None:
    with pytest.raises(ValueError, match="NaN"):
        friction_coefficient([1e-7, np.nan])


def test_parameters_without_a_friction_peak_give_a_clear_error():
    from lubrig_ros.core.friction import friction_peak
    from lubrig_ros.core.params import FrictionParameters, ParameterError

    with pytest.raises(ParameterError, match=r"no stationary point .*activation_exponent=-1\.0"):
        friction_peak(FrictionParameters(activation_exponent=-1.0))
