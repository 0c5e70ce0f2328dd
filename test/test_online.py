"""Online sliding-window analyzer: equals the offline transform of its window, bounded state."""

import numpy as np
import pytest

from lubrig_ros.core.online import DIRECT_COLUMNS_MAX, OnlineWaveletAnalyzer
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.wavelet import cwt

DT = 1e-3
WINDOW = 1024


def signal(n=5000, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    noise = 0.3 * rng.standard_normal(n)
    return np.sin(2 * np.pi * 12 * t) + 0.5 * np.sin(2 * np.pi * 47 * t) + noise


@pytest.mark.parametrize("precision, rtol", [("double", 1e-9), ("single", 1e-4)])
def test_window_power_equals_offline(precision, rtol):
    x = signal()
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=24, precision=precision)
    rng = np.random.default_rng(2)
    pos = 0
    while pos < 3000:
        k = int(rng.integers(1, 200))
        a.push(x[pos : pos + k])
        pos += k
    for k in (1, 7, 300):  # direct columns (few) and FFT columns (many)
        u = a.push(x[pos : pos + k])
        pos += k
        ref = cwt(x[pos - WINDOW : pos], DT, scales=a.scales)
        assert u.ready and u.power.shape == (24, k)
        peak = ref.power.max()
        assert np.abs(u.power - ref.power[:, -k:]).max() < rtol * peak
        assert np.allclose(u.time, np.arange(pos - k, pos) * DT)
        if u.window is not None:
            assert np.abs(u.window.power - ref.power).max() < rtol * peak
            assert np.allclose(u.window.time, ref.time + (pos - WINDOW) * DT)


@pytest.mark.parametrize("precision, rtol", [("double", 1e-9), ("single", 1e-4)])
def test_newest_columns_by_direct_kernels_equal_the_full_transform(precision, rtol):
    """Between full analyses the newest columns come from the direct kernels, up to DIRECT_COLUMNS_MAX."""
    x = signal()
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=24, precision=precision, analysis_every=10**9)
    a.push(x[:2000])  # the first full window: one full analysis
    pos = 2000
    for k in (1, 20, DIRECT_COLUMNS_MAX, DIRECT_COLUMNS_MAX + 1):
        u = a.push(x[pos : pos + k])
        pos += k
        ref = cwt(x[pos - WINDOW : pos], DT, scales=a.scales)
        assert (u.window is None) == (k <= DIRECT_COLUMNS_MAX)  # direct, or the FFT of the window
        assert u.power.shape == (24, k)
        assert np.abs(u.power - ref.power[:, -k:]).max() < rtol * ref.power.max()


def test_direct_kernels_are_exact_for_an_offset_signal():
    """A displacement far from zero (offset 1e4 × its swing): the window is centred before the product."""
    x = 1e-3 + 1e-7 * signal()
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=24, precision="single", analysis_every=10**9)
    a.push(x[:2000])
    u = a.push(x[2000:2020])
    ref = cwt(x[2020 - WINDOW : 2020], DT, scales=a.scales)
    assert np.abs(u.power - ref.power[:, -20:]).max() < 1e-4 * ref.power.max()


def test_components_found_and_labelled():
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=32, fundamental_hz=12.0)
    u = None
    x = signal()
    for i in range(0, 2000, 50):
        u = a.push(x[i : i + 50])
    assert u.ready
    freqs = [c.frequency_hz for c in u.components[:2]]
    assert min(abs(f / 12 - 1) for f in freqs) < 0.05
    assert any(c.label == "fundamental 12 Hz" for c in u.components)


def test_not_ready_until_window_full_and_state_bounded():
    a = OnlineWaveletAnalyzer(DT, window=256, n_scales=8)
    u = a.push(np.zeros(100))
    assert not u.ready and u.power.shape == (8, 0) and u.components == []
    big = signal(10000)
    u = a.push(big)
    assert u.ready and u.power.shape == (8, 256)
    assert a.samples_seen == 10100
    assert a.window_samples().shape == (256,)
    assert np.array_equal(a.window_samples(), big[-256:])


def test_constant_window_gives_zero_power_not_nan():
    a = OnlineWaveletAnalyzer(DT, window=256, n_scales=8)
    u = a.push(np.full(300, 4.0))
    assert u.ready and np.all(u.power == 0.0) and u.components == []
    u = a.push(np.full(3, 4.0))
    assert np.all(np.isfinite(u.power))


def test_bad_input_leaves_state_unchanged():
    a = OnlineWaveletAnalyzer(DT, window=256, n_scales=8)
    a.push(np.arange(10.0))
    with pytest.raises(ValueError, match="NaN"):
        a.push(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="relative_velocity"):
        a.push(np.ones(3), relative_velocity=np.ones(2))
    assert a.samples_seen == 10
    assert not a.push([]).ready


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"window": 4}, "window"),
        ({"n_scales": 1}, "n_scales"),
        ({"precision": "half"}, "precision"),
        ({"fmin": 10.0, "fmax": 5.0}, "fmin"),
        ({"analysis_every": 0}, "analysis_every"),
    ],
)
def test_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        OnlineWaveletAnalyzer(DT, **kwargs)


def test_flags_from_stream():
    rig = RigParameters(natural_frequency=12.0)
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=32, rig=rig, fundamental_hz=4.0)
    x = signal(2000)
    vrel = np.where(np.arange(2000) % 100 < 30, 0.0, 1e-6)
    u = a.push(x, relative_velocity=vrel, band_velocity=1e-6)
    f = u.flags
    assert f is not None and f.zone in (1, 2, 3)
    assert f.resonance and f.resonance_harmonic == 3
    assert abs(f.stick_share - 0.3) < 0.02
    assert f.oscillation == "steady"
