"""The scorecard's criteria on synthetic signals with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lubrig_ros.core import criteria

FS = 1000.0
T = np.arange(0, 20.0, 1 / FS)


def test_growing_and_decaying_envelope_rates() -> None:
    for rate in (0.3, -0.27, 1.5):
        x = np.exp(rate * T) * np.sin(2 * np.pi * 10 * T)
        assert criteria.envelope_growth_rate(T, x, 0.1, 1.0, 10.0) == pytest.approx(rate, abs=0.01)


def test_plateau_growth_rates_on_a_two_level_reference() -> None:
    # reference alternates between two levels every 1 s; the envelope grows on one, decays on the other
    level = np.where((T % 2.0) < 1.0, 1.0, 2.0)
    rate = np.where(level == 1.0, 0.8, -0.5)
    log_amp = np.cumsum(rate) / FS
    x = np.exp(log_amp) * np.sin(2 * np.pi * 10 * T)
    grow = criteria.plateau_growth_rates(T, x, level, 1.0, 0.1, start=4.0)
    decay = criteria.plateau_growth_rates(T, x, level, 2.0, 0.1, start=4.0)
    assert len(grow) == 8 and len(decay) == 8
    assert np.allclose(grow, 0.8, atol=0.05) and np.allclose(decay, -0.5, atol=0.05)


def test_component_amplitude_and_disappearance_of_a_decaying_10_hz_component() -> None:
    rate = 0.5  # 10 Hz component falls to 10 % after ln(10)/0.5 = 4.6 s
    x = np.exp(-rate * T) * np.sin(2 * np.pi * 10 * T) + 0.2 * np.sin(2 * np.pi * 33.33 * T)
    centres, amplitude = criteria.component_amplitude(T, x, 10.0, window=1.0)
    expected = np.exp(-rate * centres)
    assert np.allclose(amplitude, expected, rtol=0.03, atol=2e-3)
    early = np.exp(-rate * 0.5)  # largest amplitude with its window inside the first 2 s
    gone = criteria.disappearance_time(T, x, 10.0, fraction=0.1)
    assert gone == pytest.approx(math.log(10 / early) / rate + 0.5 - 0.5, abs=0.3)
    # the 33 Hz component never disappears; a pure 33 Hz signal has no 10 Hz component
    assert criteria.disappearance_time(T, x, 33.33) == math.inf
    assert criteria.component_amplitude(T, np.sin(2 * np.pi * 33.33 * T), 10.0)[1].max() < 1e-3


def test_two_level_limit_cycle_separation() -> None:
    phase = 2 * np.pi * 10 * T
    on_first = (T % 1.0) < 0.5
    centre = np.where(on_first, 0.0, 10.0)
    radius = np.where(on_first, 2.0, 3.0)
    x = centre + radius * np.cos(phase)
    y = radius * np.sin(phase)
    separation = criteria.limit_cycle_separation(x, y, on_first, True, False, quantile=1.0)
    assert separation == pytest.approx(10.0 / 5.0, rel=1e-3)
    # the same orbit split in two halves: centres coincide, no separation
    same = criteria.limit_cycle_separation(np.cos(phase), np.sin(phase), on_first, True, False)
    assert same < 0.05


def test_transient_overshoot_then_stationary() -> None:
    envelope = 1.0 + 0.5 * np.exp(-(((T - 1.0) / 0.3) ** 2)) - 0.9 * np.exp(-T / 0.1)
    x = envelope * np.sin(2 * np.pi * 4.76 * T)
    result = criteria.transient(T, x, 1 / 4.76)
    assert 0.7 < result.peak_time < 1.3
    assert result.overshoot == pytest.approx(1.5, rel=0.05)
    assert result.stationary == pytest.approx(2.0, rel=0.02)
    assert result.first < result.stationary and result.drift < 0.01
    decaying = (1 + 20 * np.exp(-T / 0.3)) * np.sin(2 * np.pi * 33.3 * T)
    assert criteria.transient(T, decaying, 0.03).settling_time == pytest.approx(0.3 * math.log(20), abs=0.1)


def test_spectral_peaks_match_harmonics_and_mono_harmonic() -> None:
    x = np.sin(2 * np.pi * 3.33 * T) + 0.5 * np.sin(2 * np.pi * 9.99 * T) + 0.1 * np.sin(2 * np.pi * 6.66 * T)
    peaks = criteria.spectral_peaks(x, FS)
    top = [f for f, _ in peaks]
    assert criteria.matches(top[:2], [3.33, 9.99]) and not criteria.matches(top[:2], [3.33, 6.66])
    assert criteria.near(top[2], 6.66)
    mono = criteria.spectral_peaks(np.sin(2 * np.pi * 10 * T), FS, floor=0.05)
    assert len(mono) == 1 and criteria.near(mono[0][0], 10.0)


def test_stick_fraction_and_explained_fraction() -> None:
    v = np.where((T % 1.0) < 0.25, 0.0, 1e-7)
    assert criteria.stick_fraction(v, 4e-12) == pytest.approx(0.25, abs=1e-3)
    signal = np.sin(2 * np.pi * T)
    assert criteria.explained_fraction(signal, signal) == 1.0
    assert criteria.explained_fraction(signal, 0.5 * signal) == pytest.approx(0.75)
    assert criteria.explained_fraction(signal, np.zeros_like(T)) == pytest.approx(0.0, abs=1e-3)


def test_bad_input_names_the_value() -> None:
    with pytest.raises(ValueError, match="window=0"):
        criteria.windowed_peak_to_peak(T, T, 0)
    with pytest.raises(ValueError, match="equal length"):
        criteria.envelope_growth_rate(T, T[:-1], 0.1)
