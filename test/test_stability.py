"""Linear stability of steady sliding: zones, ζ_crit shape, conventions, study statements."""

from __future__ import annotations

import numpy as np
import pytest

from lubrig_ros.core.friction import friction_coefficient, friction_minimum, friction_peak
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.stability import (
    critical_damping_ratio,
    friction_zone,
    linear_stability,
    stability_map,
    unstable_intervals,
)

PHYSICAL = RigParameters(convention="physical")
PAPER = RigParameters(convention="paper")
PEAK = friction_peak().velocity
MINIMUM = friction_minimum().velocity
ZETAS = np.array([0.0, 1e-9, 1e-3, 0.01, 0.1, 1.0, 10.0, 1e3, 1e6])


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
def test_zones_1_and_3_stable_for_every_damping(rig: RigParameters) -> None:
    zone1 = np.logspace(-15, np.log10(PEAK * (1 - 1e-6)), 400)
    zone3 = np.logspace(np.log10(MINIMUM * (1 + 1e-6)), -2, 400)
    for v in (zone1, zone3):
        assert stability_map(v, ZETAS, rig).all()
    # the study's round numbers: peak "4.1e-12", minimum "1.35e-7"
    assert abs(PEAK / 4.1e-12 - 1) < 0.01
    assert abs(MINIMUM / 1.35e-7 - 1) < 0.01


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
def test_zero_damping_unstable_exactly_in_zone_2(rig: RigParameters) -> None:
    intervals = unstable_intervals(0.0, rig)
    assert len(intervals) == 1
    lo, hi = intervals[0]
    assert lo == pytest.approx(PEAK, rel=1e-8)
    assert hi == pytest.approx(MINIMUM, rel=1e-8)


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
def test_more_damping_shrinks_the_unstable_interval(rig: RigParameters) -> None:
    previous = (PEAK, MINIMUM)
    for zeta in [1e-3, 0.01, 0.1, 1.0, 10.0]:
        (lo, hi), *rest = unstable_intervals(zeta, rig)
        assert not rest
        assert previous[0] <= lo < hi <= previous[1]
        assert hi < previous[1]
        # the edges are where ζ_crit crosses ζ: bracket them within 1e-9 relative in velocity
        # (comparing ζ_crit(lo) with ζ directly is ill-conditioned: near the peak μ' is a small
        # difference of terms ~μ/v, so ζ_crit carries an absolute error ~1e-8 there)
        below, above = critical_damping_ratio([lo * (1 - 1e-9), lo * (1 + 1e-9)], rig)
        assert below < zeta < above
        below, above = critical_damping_ratio([hi * (1 - 1e-9), hi * (1 + 1e-9)], rig)
        assert below > zeta > above
        previous = (lo, hi)


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
def test_critical_damping_shape_in_zone_2(rig: RigParameters) -> None:
    """ζ_crit is 0 at both zone edges, rises steeply to one finite maximum just above the peak
    (the inflection of μ), then falls monotonically to 0 at the minimum (see docs/model.md)."""
    v = np.logspace(np.log10(PEAK), np.log10(MINIMUM), 20001)[1:-1]
    zc = critical_damping_ratio(v, rig)
    assert (zc > 0).all()
    top = int(zc.argmax())
    assert PEAK < v[top] < 3 * PEAK
    assert (np.diff(zc[: top + 1]) > 0).all()
    assert (np.diff(zc[top:]) < 0).all()
    assert np.isfinite(zc[top])
    edges = critical_damping_ratio([PEAK, MINIMUM], rig)
    assert edges.max() < 1e-6 * zc[top]
    # damping just below the maximum leaves that band velocity unstable, just above fixes it
    for factor, stable in ((0.99, False), (1.01, True)):
        damped = RigParameters(damping_ratio=factor * zc[top], convention=rig.convention)
        assert linear_stability(v[top], damped).stable is stable


def test_paper_convention_divides_critical_damping_by_omega0() -> None:
    v = np.logspace(np.log10(PEAK), np.log10(MINIMUM), 50)[1:-1]
    ratio = critical_damping_ratio(v, PHYSICAL) / critical_damping_ratio(v, PAPER)
    np.testing.assert_allclose(ratio, PHYSICAL.angular_frequency, rtol=1e-12)


def test_v1_unstable_at_rig_damping_in_physical_convention() -> None:
    verdict = linear_stability(1e-7, RigParameters(damping_ratio=0.01, convention="physical"))
    assert verdict.zone == 2
    assert not verdict.stable
    assert verdict.critical_damping_ratio > 0.01
    # in the paper convention the same band velocity is linearly stable at ζ = 0.01
    paper = linear_stability(1e-7, RigParameters(damping_ratio=0.01, convention="paper"))
    assert paper.stable
    assert 0.0 < paper.critical_damping_ratio < 0.01


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
def test_study_boundary_3e8_reached_at_zeta_crit_3e8(rig: RigParameters) -> None:
    """The study's 'stabilizable above 3e-8 m/s' holds for damping ζ = ζ_crit(3e-8)."""
    zeta = float(critical_damping_ratio(3e-8, rig))
    (_, hi), *rest = unstable_intervals(zeta, rig)
    assert not rest
    assert hi == pytest.approx(3e-8, rel=1e-6)
    assert stability_map([2e-8], [zeta], rig)[0, 0] == np.False_
    assert stability_map([5e-8, 1.3e-7], [zeta], rig).all()


@pytest.mark.parametrize("rig", [PHYSICAL, PAPER], ids=["physical", "paper"])
@pytest.mark.parametrize("v_band", [2e-12, 1e-11, 1e-9, 2e-8, 1e-7, 1e-6, 1e-4])
@pytest.mark.parametrize("zeta", [0.0, 0.01, 0.3])
def test_verdict_matches_eigenvalues_of_numerical_jacobian(
    rig: RigParameters, v_band: float, zeta: float
) -> None:
    """Independent check: finite-difference Jacobian of the full equation of motion."""
    rig = RigParameters(damping_ratio=zeta, convention=rig.convention)
    m, k, c, n = rig.mass, rig.stiffness, rig.damping, rig.friction.normal_force
    gamma = rig.velocity_factor
    h = 1e-6 * v_band / gamma  # perturbation of ẋ, small against v_band

    def force(xdot: float) -> float:
        return n * float(friction_coefficient(v_band - gamma * xdot, rig.friction))

    d_force = (force(h) - force(-h)) / (2 * h)
    jacobian = np.array([[0.0, 1.0], [-k / m, (-c + d_force) / m]])
    growth = np.linalg.eigvals(jacobian).real.max()
    verdict = linear_stability(v_band, rig)
    assert verdict.stable == (growth < 0), (verdict, growth)
    assert verdict.zone == int(friction_zone(v_band, rig))
