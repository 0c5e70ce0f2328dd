"""The junction law over every velocity a double holds: 0, subnormals, 1e-320 … 1.8e308 m/s.

Values against a high-precision evaluation of the model document's formulas (mpmath, enough
digits for the cancellation in s(v) at the largest velocities), the small-velocity limit
μ → (A/N)(η_ref/d) v_ref^−k2 |v|^(1+k2) of the model document, infinities refused, and the
degenerate bands of `lubrig simulate`.
"""

from __future__ import annotations

import json
import math

import mpmath
import numpy as np
import pytest
from lubrig_testkit.cli import lubrig
from test_friction import mp_mu

from lubrig_ros.core import junction
from lubrig_ros.core.friction import friction_coefficient, friction_law, friction_slope
from lubrig_ros.core.params import FrictionParameters

DEFAULT = FrictionParameters()
TINIEST = 5e-324
LARGEST = 1.7976931348623157e308
EXTREMES = np.array(
    [TINIEST, 1e-322, 7.9e-321, 1e-320, 1e-310, 2.3e-308, 1e-300, 1e-200, 1.2e-166, 1e-166, 1e-100,
     1e-50, 1e-20, 2e-15, 3e-15, 1e-12, 1e-7, 1e10, 1e88, 2e88, 1e100, 1e200, 1.7e298, 1e300, 1e305,
     LARGEST]
)  # fmt: skip


def _digits(v: float) -> int:
    """Working digits: the closed form of s(v) cancels to about u² = (v0/v)² at large v."""
    decades = math.log10(v) - math.log10(DEFAULT.critical_velocity)  # -log10(u), u = v0 / v
    return 60 + 2 * max(0, math.ceil(decades))


@pytest.fixture(scope="module")
def reference() -> tuple[np.ndarray, np.ndarray]:
    mu, slope = [], []
    for v in EXTREMES:
        x = mpmath.mpf(float(v))
        with mpmath.workdps(_digits(float(v))):
            mu.append(float(mp_mu(x)))
            slope.append(float(mpmath.diff(mp_mu, x, h=x * mpmath.mpf(10) ** -30)))
    return np.array(mu), np.array(slope)


def test_value_and_slope_match_high_precision_everywhere(reference) -> None:
    mu_ref, slope_ref = reference
    for values, ref, name in ((friction_coefficient(EXTREMES), mu_ref, "μ"),
                              (friction_slope(EXTREMES), slope_ref, "dμ/dv")):  # fmt: skip
        assert np.isfinite(values).all()
        rel = np.abs(values / ref - 1.0)
        assert rel.max() < 1e-12, f"{name} worst at v={EXTREMES[rel.argmax()]:.3g}: {rel.max():.2g}"


def test_odd_and_even_at_the_extremes() -> None:
    np.testing.assert_array_equal(friction_coefficient(-EXTREMES), -friction_coefficient(EXTREMES))
    np.testing.assert_array_equal(friction_slope(-EXTREMES), friction_slope(EXTREMES))


def test_small_velocity_limit_of_the_model_document() -> None:
    p = DEFAULT
    k2 = p.shear_thinning_exponent
    v = np.array([TINIEST, 1e-320, 1e-300, 1e-250])
    limit = p.contact_area / p.normal_force * p.reference_viscosity / p.interpenetration_thickness
    limit_mu = limit * p.reference_velocity ** (-k2) * v ** (1.0 + k2)
    np.testing.assert_allclose(friction_coefficient(v), limit_mu, rtol=1e-12)
    np.testing.assert_allclose(friction_slope(v), (1.0 + k2) * limit_mu / v, rtol=1e-12)
    assert friction_coefficient(0.0) == 0.0 and friction_slope(0.0) == math.inf  # unbounded at 0


def test_overflow_free_form_is_the_same_law_over_the_operating_range() -> None:
    grid = np.logspace(-15, -2, 131) * 1.0371
    p = friction_law().pack(DEFAULT)
    scaled = np.array([junction._scaled_mu_and_slope(float(v), p) for v in grid])
    direct = np.array([junction.mu_and_slope(float(v), p) for v in grid])
    np.testing.assert_allclose(scaled, direct, rtol=1e-13)


@pytest.mark.parametrize("bad", [math.inf, -math.inf])
def test_infinite_velocity_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="inf; expected finite"):
        friction_coefficient([1e-7, bad])


def test_a_band_at_rest_gives_a_mass_at_rest(tmp_path) -> None:
    done = lubrig("simulate", "--band-velocity", "0", "--duration", "0.5", "--out", str(tmp_path / "run"))
    assert done.returncode == 0, done.stderr
    data = np.loadtxt(tmp_path / "run" / "timeseries.csv", delimiter=",", skiprows=1)
    assert not data[:, 1:].any()  # x, ẋ, μ, v_band, v_rel all 0
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["x_peak_to_peak"] == 0.0


@pytest.mark.parametrize("velocity", ["1e-322", "-4e-320", "1e-19"])
def test_a_band_below_the_velocity_resolution_is_refused_in_one_line(tmp_path, velocity: str) -> None:
    done = lubrig("simulate", "--band-velocity", velocity, "--duration", "0.5", "--out", str(tmp_path / "r"))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"band velocity {float(velocity)!r} m/s" in lines[0]
    assert "expected 0 (band at rest) or |v| >=" in lines[0]
