"""Torrence–Compo CWT: tones, two tones, chirp, white noise, PyWavelets cross-check, bad input."""

import math

import numpy as np
import pytest
import pywt

from lubrig_ros.core.wavelet import cwt, fourier_factor, scale_grid
from lubrig_ros.core.wavelet_components import (
    dominant_components,
    dominant_frequencies,
    harmonic_label,
)

DT = 1e-3


def tone(freq, amp=1.0, n=4000, dt=DT):
    t = np.arange(n) * dt
    return amp * np.sin(2 * np.pi * freq * t)


@pytest.mark.parametrize("freq", [7.0, 23.0, 61.0])
def test_pure_tone_frequency_within_one_scale_step(freq):
    dj = 1 / 12
    comps = dominant_frequencies(tone(freq), DT, n=3)
    assert comps, "a tone must give a component"
    step = 2**dj - 1
    assert abs(comps[0].frequency_hz / freq - 1) < step
    # the global spectrum's raw peak is within one scale step too
    f_peak, _ = cwt(tone(freq), DT, dj=dj).global_peak()
    assert abs(math.log2(f_peak / freq)) <= dj


@pytest.mark.parametrize("amp", [0.5, 3.0])
def test_tone_power_normalization_within_5_percent(amp):
    freq = 20.0
    res = cwt(tone(freq, amp), DT, scales=np.array([1 / (freq * fourier_factor())]))
    # analytic peak: |W|² = A² s √π / (2 dt), variance A²/2
    s = res.scales[0]
    expected = (amp**2 * s * math.sqrt(math.pi) / (2 * DT)) / (amp**2 / 2)
    inner = res.power[0][res.outside_coi[0]]
    assert abs(inner.mean() / expected - 1) < 0.05
    comp = dominant_frequencies(tone(freq, amp), DT)[0]
    assert abs(comp.amplitude / amp - 1) < 0.05


def test_variance_reconstruction_within_5_percent():
    rng = np.random.default_rng(3)
    x = tone(12.0, 2.0) + 0.5 * rng.standard_normal(4000)
    res = cwt(x, DT, dj=1 / 8)
    assert abs(res.reconstructed_variance() / res.variance - 1) < 0.05


def test_two_tones_resolved():
    x = tone(10.0, 1.0) + tone(31.0, 0.7)
    comps = dominant_frequencies(x, DT, fundamental_hz=10.0, n=4)
    freqs = sorted(c.frequency_hz for c in comps[:2])
    assert abs(freqs[0] / 10.0 - 1) < 0.03
    assert abs(freqs[1] / 31.0 - 1) < 0.03
    labels = {c.harmonic for c in comps[:2]}
    assert 1 in labels and 3 in labels


def test_white_noise_mean_power_one_and_five_percent_significant():
    rng = np.random.default_rng(11)
    x = rng.standard_normal(16384)
    res = cwt(x, DT, dj=1 / 4, fmin=5.0, fmax=250.0)
    inside = res.outside_coi
    assert abs(res.power[inside].mean() - 1) < 0.05
    share = (res.significance_ratio[inside] > 1).mean()
    assert 0.035 < share < 0.065
    assert res.lag1 < 0.05


def test_red_noise_lag1_estimated():
    rng = np.random.default_rng(5)
    e = rng.standard_normal(20000)
    x = np.empty_like(e)
    x[0] = e[0]
    for i in range(1, e.size):
        x[i] = 0.7 * x[i - 1] + e[i]
    res = cwt(x, DT, dj=1 / 4)
    assert abs(res.lag1 - 0.7) < 0.03
    share = (res.significance_ratio[res.outside_coi] > 1).mean()
    assert 0.03 < share < 0.07


def test_matches_pywavelets_cmor_within_tolerance():
    # TC Morlet ψ0(η) = π^-1/4 e^{iω0η} e^{-η²/2}  <->  pywt cmorB-C: (πB)^-1/2 e^{-t²/B} e^{2πiCt}
    # with B = 2, C = ω0/(2π); pywt scales are in samples and normalize by 1/√s like TC, so
    # |W_TC|² = |W_pywt|² · 2√π  (ratio of the two mother amplitudes squared).
    rng = np.random.default_rng(0)
    x = rng.standard_normal(4096) + 3 * tone(25.0, n=4096)
    res = cwt(x, DT, fmin=4.0, fmax=60.0, keep_coefficients=True)
    wav = pywt.ContinuousWavelet(f"cmor2.0-{6 / (2 * np.pi)}")
    coef, _ = pywt.cwt(x - x.mean(), res.scales / DT, wav, sampling_period=DT, method="fft", precision=18)
    p_pywt = np.abs(coef) ** 2 * 2 * np.sqrt(np.pi) / res.variance
    m = res.outside_coi
    scale_mean = res.power.mean(axis=1, keepdims=True)
    err = np.abs(p_pywt - res.power) / scale_mean
    # pywt differentiates a tabulated integral of ψ: a one-sample box filter and half-sample
    # offset that matter at small scales; from 32 samples per scale pointwise error < 5 %.
    large = res.scales >= 32 * DT
    assert err[m & large[:, None]].max() < 0.05
    assert np.median(err[m]) < 0.01
    g_pywt = np.array([p_pywt[j][m[j]].mean() for j in range(res.scales.size)])
    g_own = np.array([res.power[j][m[j]].mean() for j in range(res.scales.size)])
    assert np.max(np.abs(g_pywt / g_own - 1)) < 0.02


def test_harmonic_labels():
    assert harmonic_label(10.0, 10 / 3)[1] == "3rd harmonic of 3.33 Hz"
    assert harmonic_label(3.3, 10 / 3) == (1, "fundamental 3.33 Hz")
    assert harmonic_label(12.0, 10 / 3)[0] is None
    assert "subharmonic" in harmonic_label(5.0, 10.0)[1]
    assert harmonic_label(5.0, None) == (None, "5 Hz")


def test_components_window_restriction():
    x = np.concatenate((tone(10.0, n=3000), tone(40.0, n=3000)))
    res = cwt(x, DT, fmin=3.0, fmax=100.0)
    first = dominant_components(res, t_end=2.5, n=1)[0]
    last = dominant_components(res, t_start=3.5, n=1)[0]
    assert abs(first.frequency_hz / 10 - 1) < 0.03
    assert abs(last.frequency_hz / 40 - 1) < 0.03


@pytest.mark.parametrize(
    "signal, match",
    [
        ([], "0 samples"),
        (np.ones(5), "5 samples"),
        (np.r_[np.zeros(50), np.nan, np.zeros(50)], "non-finite"),
        (np.ones((4, 40)), "1-D"),
    ],
)
def test_bad_signals_raise_clear_errors(signal, match):
    with pytest.raises(ValueError, match=match):
        cwt(signal, DT)
    with pytest.raises(ValueError, match=match):
        dominant_frequencies(signal, DT)


def test_constant_signal():
    with pytest.raises(ValueError, match="constant"):
        cwt(np.full(100, 2.5), DT)
    assert dominant_frequencies(np.full(100, 2.5), DT) == []


@pytest.mark.parametrize("dt", [0.0, -1.0, float("nan"), "x"])
def test_bad_dt(dt):
    with pytest.raises(ValueError, match="dt="):
        cwt(tone(5.0), dt)


def test_scale_grid_and_start():
    s = scale_grid(DT, 1000, dj=0.25, fmin=2.0, fmax=100.0)
    f = 1 / (s * fourier_factor())
    assert abs(f[0] - 100.0) < 1e-9 and f[-1] >= 2.0 and np.allclose(np.diff(np.log2(s)), 0.25)
    with pytest.raises(ValueError, match="fmax"):
        scale_grid(DT, 1000, fmax=900.0)
    x = np.concatenate((tone(40.0, 5.0, n=2000), tone(10.0, n=4000)))
    comps = dominant_frequencies(x, DT, start=2.0, n=1)
    assert abs(comps[0].frequency_hz / 10 - 1) < 0.03
    out = cwt(tone(10.0), DT)
    assert np.all(np.isfinite(out.power)) and np.all(np.isfinite(out.significance))
