"""core/wavelet.py against pycwt, the reference implementation of Torrence & Compo (1998).

Same signal, same scales, same FFT length (5000 samples: both pad to 8192, TC's "power of two
above N, doubled" and pycwt's next power of two agree there), so the transforms must agree to
rounding. What is compared, with the tolerance and why:

- power |W|²/σ²: 2 e^(−ω0²/2) ≈ 3e-8 of the peak at every scale whose daughter ψ̂(s ω) is below
  1e-6 of its peak at the Nyquist frequency. pycwt's daughter is TC's Morlet without the step
  H(ω) (its "approximate Morlet"): negative frequencies add up to e^(−ω0²/2) = 1.5e-8 of the
  amplitude, so the powers differ by up to twice that. At the smallest scales, which reach the
  Nyquist frequency, the two differ by design: TC's code counts the Nyquist bin of an
  even-length FFT as a positive frequency (as ours does), numpy's fftfreq (pycwt) as a negative
  one, where TC's daughter is 0 and pycwt's nearly so (docs/wavelets.md);
- scales ↔ Fourier periods (the Morlet factor 4π/(ω0 + √(2 + ω0²))): 1e-12 relative;
- local (TC eq. 18) and global (eq. 23, ν from N averaged points) 95 % significance against the
  same AR(1) background: 1e-9 relative;
- global wavelet spectrum (time mean of the power): as the power, 3e-8 of its peak;
- cone of influence: pycwt's is ours plus half a sample (its Bartlett window has non-zero end
  points, n0/2 − |n − (n0 − 1)/2|), ours is TC's own (distance to the nearer end, 1e-5 at the
  ends, as their published code); both equal after that offset, 1e-12 relative (docs/wavelets.md).
"""

from __future__ import annotations

import math

import numpy as np
import pycwt
import pytest

from lubrig_ros.core.wavelet import cwt, fourier_factor

DT = 1e-3
N = 5000
#: pycwt's negative-frequency leakage bounds the power difference (module docstring)
POWER_TOL = 2.0 * math.exp(-0.5 * 6.0**2)


def signal(seed: int) -> np.ndarray:
    """Two tones over AR(1) red noise (α = 0.7), as a rig response with measurement noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) * DT
    noise = np.zeros(N)
    e = rng.standard_normal(N)
    for k in range(1, N):
        noise[k] = 0.7 * noise[k - 1] + e[k]
    return np.sin(2 * np.pi * 12 * t) + 0.4 * np.sin(2 * np.pi * 61 * t + 1.0) + 0.5 * noise


@pytest.fixture(params=[0, 1], ids=["seed0", "seed1"])
def both(request: pytest.FixtureRequest) -> tuple[object, tuple[np.ndarray, ...], np.ndarray]:
    x = signal(request.param)
    ours = cwt(x, DT)
    xc = x - x.mean()
    dj = math.log2(ours.scales[1] / ours.scales[0])
    reference = pycwt.cwt(xc, DT, dj=dj, s0=ours.scales[0], J=ours.scales.size - 1, wavelet=pycwt.Morlet(6))
    return ours, reference, xc


def test_power_scales_and_periods_equal_pycwt(both) -> None:
    ours, (w, sj, freqs, _coi, _, _), xc = both
    assert sj.shape == ours.scales.shape
    np.testing.assert_allclose(sj, ours.scales, rtol=1e-12)
    np.testing.assert_allclose(1.0 / freqs, ours.periods, rtol=1e-12)
    power = np.abs(w) ** 2 / xc.var()
    at_nyquist = np.exp(-0.5 * (ours.scales * math.pi / DT - 6.0) ** 2)  # ψ̂(s ω_Nyquist) / its peak
    clear = at_nyquist < 1e-6
    assert clear.sum() > 0.9 * clear.size  # all but the first few scales
    assert np.abs(power - ours.power)[clear].max() < POWER_TOL * ours.power.max()
    assert np.abs(power - ours.power)[~clear].max() > 1e-6 * ours.power.max()  # the Nyquist bin
    assert ours.power.max() > 10.0  # a real signal: the tones stand far above the mean power


def test_significance_and_global_spectrum_equal_pycwt(both) -> None:
    ours, (w, sj, _freqs, _coi, _, _), xc = both
    variance = xc.var()
    local, _ = pycwt.significance(variance, DT, sj, 0, alpha=ours.lag1, wavelet=pycwt.Morlet(6))
    np.testing.assert_allclose(ours.significance * variance, local, rtol=1e-9)
    dof = np.full(sj.size, float(N))  # every time point of the series averaged
    global_level, _ = pycwt.significance(
        variance, DT, sj, 1, alpha=ours.lag1, dof=dof, wavelet=pycwt.Morlet(6)
    )
    np.testing.assert_allclose(ours.global_significance * variance, global_level, rtol=1e-9)
    spectrum = (np.abs(w) ** 2).mean(axis=1) / variance
    clear = np.exp(-0.5 * (ours.scales * math.pi / DT - 6.0) ** 2) < 1e-6  # as for the power
    assert np.abs(spectrum - ours.global_spectrum)[clear].max() < POWER_TOL * ours.global_spectrum.max()


def test_cone_of_influence_is_pycwts_less_half_a_sample(both) -> None:
    ours, (_w, _sj, _freqs, coi, _, _), _xc = both
    half_sample = fourier_factor() / math.sqrt(2.0) * DT * 0.5
    interior = slice(1, N - 1)
    np.testing.assert_allclose(ours.coi[interior] + half_sample, coi[interior], rtol=1e-12)
    assert ours.coi[0] == ours.coi[-1] == pytest.approx(1e-5 * DT)  # TC's end points
    assert coi[0] == pytest.approx(half_sample)
