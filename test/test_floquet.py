"""Floquet multipliers by shooting (core/floquet.py) and case 8's period-doubling threshold.

Known answers: a linear damped oscillator driven through the project's integrator (Stribeck law
with μ = μ_v v only, so the friction is a linear viscous force and the band a periodic forcing)
has the multipliers exp(λT) of m λ² + (c + γ N μ_v) λ + k = 0; a damped Meissner equation
(piecewise-constant stiffness over the period) has a closed-form monodromy matrix, so the
parameter where a multiplier passes −1 is known independently of the shooting code.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from lubrig_ros.core import floquet
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.core.stribeck import StribeckParameters


def _viscous_case8(mu_v: float):  # type: ignore[no-untyped-def]
    """Case 8's band driving a rig whose friction is μ = μ_v · v_rel (linear), physical coupling."""
    config = load_case(8)
    law = StribeckParameters(static_coefficient=0.0, kinetic_coefficient=0.0, viscous_coefficient=mu_v)
    rig = replace(RigParameters(), friction=law, velocity_coupling=1.0)
    return replace(config, rig=rig, rtol=1e-13)


def test_linear_oscillator_multipliers_are_exp_lambda_t() -> None:
    mu_v = 400.0  # s/m: adds c_v = γ N μ_v = 0.4 N·s/m to c (ζ from 0.01 to about 0.042)
    config = _viscous_case8(mu_v)
    rig = config.rig
    period = 1.0 / config.band.fundamental_hz  # 0.05 s, half the natural period
    flow = floquet.rig_period_map(rig, config.band, period, config.sample_rate, config.rtol)
    scale = floquet.rig_scale(rig)
    orbit = floquet.periodic_orbit(flow, np.array([0.0, 0.0]), scale)
    c_total = rig.damping + rig.velocity_factor * rig.normal_force * mu_v
    lam = np.roots([rig.mass, c_total, rig.stiffness])
    expected = np.exp(lam * period)
    got = orbit.multipliers
    assert np.abs(expected).max() < 0.9  # a genuinely damped case, multipliers a complex pair
    for value in expected:
        assert np.min(np.abs(got - value)) < 1e-6, (got, expected)
    assert orbit.residual < 1e-9
    # the orbit found by shooting is the state a long run settles to (|λ|^400 ≈ 1e-23)
    run = simulate(replace(config, duration=20.0))
    settled = np.array([run.displacement[-1], run.velocity[-1]])
    assert np.all(np.abs(settled - orbit.state) < 1e-9 * scale)


def _meissner(eps: float, zeta: float = 0.02, delta: float = 0.25):  # type: ignore[no-untyped-def]
    """x'' + 2ζ x' + ω(t)² x = cos t, ω² = δ + ε on the first half of T = 2π, δ − ε on the second."""
    period = 2.0 * math.pi

    def rhs(t: float, z: np.ndarray) -> list[float]:
        w2 = delta + eps if (t % period) < 0.5 * period else delta - eps
        return [z[1], -2.0 * zeta * z[1] - w2 * z[0] + math.cos(t)]

    def flow(z: np.ndarray) -> np.ndarray:
        first = solve_ivp(rhs, (0.0, 0.5 * period), z, method="DOP853", rtol=1e-13, atol=1e-15)
        second = solve_ivp(
            rhs, (0.5 * period, period), first.y[:, -1], method="DOP853", rtol=1e-13, atol=1e-15
        )
        return np.asarray(second.y[:, -1])

    def exact_monodromy() -> np.ndarray:
        # exp(A τ) = e^(−ζτ) [cos(ντ) I + sin(ντ)/ν (A + ζ I)], ν = sqrt(ω² − ζ²), per half period
        tau = 0.5 * period
        halves = []
        for w2 in (delta + eps, delta - eps):
            a = np.array([[0.0, 1.0], [-w2, -2.0 * zeta]])
            nu = math.sqrt(w2 - zeta**2)
            halves.append(
                math.exp(-zeta * tau)
                * (math.cos(nu * tau) * np.eye(2) + math.sin(nu * tau) / nu * (a + zeta * np.eye(2)))
            )
        return halves[1] @ halves[0]

    return flow, exact_monodromy


def test_meissner_monodromy_matches_closed_form() -> None:
    flow, exact = _meissner(0.05)
    orbit = floquet.periodic_orbit(flow, np.zeros(2), np.ones(2))
    assert np.max(np.abs(orbit.monodromy - exact())) < 1e-6
    assert (
        np.max(np.abs(np.sort_complex(orbit.multipliers) - np.sort_complex(np.linalg.eigvals(exact()))))
        < 1e-6
    )


def test_threshold_is_where_a_multiplier_crosses_minus_one() -> None:
    expected = brentq(lambda e: floquet.doubling_margin(_meissner(e)[1]()), 0.01, 0.2, xtol=1e-14)
    at = np.linalg.eigvals(_meissner(expected)[1]())
    assert np.min(np.abs(at + 1.0)) < 1e-9  # the closed form's root is a multiplier −1, real

    def orbit_at(eps: float) -> floquet.Orbit:
        return floquet.periodic_orbit(_meissner(eps)[0], np.zeros(2), np.ones(2))

    found = floquet.period_doubling_threshold(orbit_at, 0.01, 0.2, rtol=1e-6)
    assert abs(found.parameter / expected - 1.0) < 1e-5, (found.parameter, expected)
    assert found.below.multipliers.real.min() > -1.0 > found.above.multipliers.real.min()
    with pytest.raises(ValueError, match="no multiplier crosses"):
        floquet.period_doubling_threshold(orbit_at, 0.01, 0.5 * expected)


def test_period_map_needs_a_whole_number_of_samples() -> None:
    config = load_case(8)
    with pytest.raises(ValueError, match="whole number of samples"):
        floquet.rig_period_map(config.rig, config.band, 0.0505, 1000.0, 1e-12)


@pytest.mark.slow
def test_case8_threshold_and_growth_across_it() -> None:
    """Case 8's forced orbit period-doubles near s ≈ 0.053 (issue 25's review), and the computed
    multiplier is the rate at which a perturbation grows or decays over many periods of the flow."""
    from lubrig_ros.study import floquet as study_floquet
    from lubrig_ros.study.runs import study_configs

    result = study_floquet.period_doubling()
    assert 0.045 < result.threshold < 0.06
    assert result.bracket[0] <= result.threshold <= result.bracket[1]
    for factor in (0.9, 1.1):
        s = factor * result.threshold
        config = study_configs(s, 4.0)[8]
        flow = floquet.rig_period_map(config.rig, config.band, 0.05, config.sample_rate, study_floquet.RTOL)
        scale = floquet.rig_scale(config.rig)
        run = simulate(config)
        orbit = floquet.periodic_orbit(flow, np.array([run.displacement[-1], run.velocity[-1]]), scale)
        leading = orbit.multipliers[0]
        assert abs(leading.imag) < 1e-9 and (leading.real < -1.0) == (factor > 1.0)
        values, vectors = np.linalg.eig(orbit.monodromy)
        direction = np.real(vectors[:, int(np.argmin(values.real))])
        z = orbit.state + 1e-3 * direction / np.max(np.abs(direction / scale))
        first = np.max(np.abs(z - orbit.state) / scale)
        periods = 100
        for _ in range(periods):
            z = flow(z)
        rate = (np.max(np.abs(z - orbit.state) / scale) / first) ** (1.0 / periods)
        assert abs(rate - abs(leading.real)) < 2e-4, (s, rate, leading)
        assert (rate > 1.0) == (factor > 1.0)
