"""Measurable criteria on sampled responses: plain functions of numpy arrays (SI units, time in s).

These turn the study's statements (model doc, section 8) into numbers: windowed amplitude and its
growth or decay rate, the amplitude of one frequency component over time and when it disappears,
transient overshoot and settling, separation of limit cycles in the phase plane, spectral peaks
and whether given frequencies are among them, stick fraction, and how much of μ the band velocity
alone explains. Each is tested on synthetic signals with a known answer (test/test_criteria.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lubrig_ros.core.errors import InputError


def _arrays(time: np.typing.ArrayLike, signal: np.typing.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(time, dtype=float)
    x = np.asarray(signal, dtype=float)
    if t.shape != x.shape or t.ndim != 1:
        raise InputError(f"time and signal must be 1-D arrays of equal length, got {t.shape}, {x.shape}")
    return t, x


def windowed_peak_to_peak(
    time: np.typing.ArrayLike,
    signal: np.typing.ArrayLike,
    window: float,
    start: float | None = None,
    stop: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Peak-to-peak of the signal in consecutive windows of `window` s: (window centres, p-p)."""
    t, x = _arrays(time, signal)
    if not (math.isfinite(window) and window > 0):
        raise InputError(f"window={window!r} must be a finite duration > 0 s")
    lo = t[0] if start is None else max(float(start), t[0])
    hi = t[-1] if stop is None else min(float(stop), t[-1])
    count = math.floor((hi - lo) / window + 1e-9)
    centres, ptp = [], []
    for k in range(count):
        a, b = lo + k * window, lo + (k + 1) * window
        inside = (t >= a) & (t < b) if k < count - 1 else (t >= a) & (t <= b)
        if inside.sum() >= 2:
            centres.append(0.5 * (a + b))
            ptp.append(float(np.ptp(x[inside])))
    return np.array(centres), np.array(ptp)


def log_slope(time: np.typing.ArrayLike, amplitude: np.typing.ArrayLike) -> float:
    """Least-squares slope of log(amplitude) against time, 1/s (NaN with < 2 positive points)."""
    t = np.asarray(time, dtype=float)
    a = np.asarray(amplitude, dtype=float)
    keep = np.isfinite(a) & (a > 0)
    if keep.sum() < 2:
        return math.nan
    return float(np.polyfit(t[keep], np.log(a[keep]), 1)[0])


def envelope_growth_rate(
    time: np.typing.ArrayLike,
    signal: np.typing.ArrayLike,
    period: float,
    start: float | None = None,
    stop: float | None = None,
) -> float:
    """Growth rate λ (1/s) of the envelope A e^(λt) of an oscillation of the given period.

    Peak-to-peak per period, then the slope of its logarithm: > 0 grows, < 0 decays.
    """
    centres, ptp = windowed_peak_to_peak(time, signal, period, start, stop)
    return log_slope(centres, ptp)


def level_intervals(
    time: np.typing.ArrayLike, reference: np.typing.ArrayLike, level: float, rtol: float = 1e-9
) -> list[tuple[float, float]]:
    """Maximal time intervals [a, b] where `reference` equals `level` (e.g. band plateaus at V1)."""
    t, r = _arrays(time, reference)
    on = np.isclose(r, level, rtol=rtol, atol=0.0)
    intervals = []
    i = 0
    while i < on.size:
        if on[i]:
            j = i
            while j + 1 < on.size and on[j + 1]:
                j += 1
            if j > i:
                intervals.append((float(t[i]), float(t[j])))
            i = j + 1
        else:
            i += 1
    return intervals


def plateau_growth_rates(
    time: np.typing.ArrayLike,
    signal: np.typing.ArrayLike,
    reference: np.typing.ArrayLike,
    level: float,
    period: float,
    start: float = 0.0,
    skip: float | None = None,
) -> list[float]:
    """Envelope growth rate (1/s) on every plateau of `reference` at `level` beginning at >= start.

    The first `skip` seconds of each plateau (default one period: the response to the preceding
    ramp) are left out; a plateau needs at least two periods after that.
    """
    skip = period if skip is None else skip
    rates = []
    for a, b in level_intervals(time, reference, level):
        if a < start or b - (a + skip) < 2 * period:
            continue
        rate = envelope_growth_rate(time, signal, period, a + skip, b)
        if math.isfinite(rate):
            rates.append(rate)
    return rates


def component_amplitude(
    time: np.typing.ArrayLike,
    signal: np.typing.ArrayLike,
    frequency: float,
    window: float = 1.0,
    hop: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude over time of the component at `frequency` Hz: (window centres, amplitude).

    Hann-windowed demodulation over `window` s, every `hop` s (default window/4): a sine
    A sin(2π f t) gives A; components further than about 2/window Hz away are rejected.
    """
    t, x = _arrays(time, signal)
    if not (math.isfinite(frequency) and frequency > 0):
        raise InputError(f"frequency={frequency!r} must be a finite frequency > 0 Hz")
    hop = window / 4.0 if hop is None else hop
    dt = float(np.median(np.diff(t)))
    n = round(window / dt)
    if n < 8 or n > t.size:
        raise InputError(f"window={window!r} s holds {n} samples; need 8 … {t.size}")
    step = max(1, round(hop / dt))
    w = np.hanning(n)
    phase = np.exp(-2j * np.pi * frequency * t)
    centres, amplitude = [], []
    for i in range(0, t.size - n + 1, step):
        seg = x[i : i + n]
        seg = seg - np.average(seg, weights=w)
        amplitude.append(2.0 * abs(np.sum(w * seg * phase[i : i + n])) / w.sum())
        centres.append(0.5 * (t[i] + t[i + n - 1]))
    return np.array(centres), np.array(amplitude)


def disappearance_time(
    time: np.typing.ArrayLike,
    signal: np.typing.ArrayLike,
    frequency: float,
    fraction: float = 0.1,
    window: float = 1.0,
    early: float = 2.0,
) -> float:
    """Time (s) after which the component at `frequency` stays below `fraction` of its early level.

    The early level is the largest amplitude of the component with its window inside the first
    `early` seconds. Returns 0 if it is never above, inf if it is still above at the end.
    """
    centres, amplitude = component_amplitude(time, signal, frequency, window)
    first = centres <= float(np.asarray(time)[0]) + early
    reference = float(amplitude[first].max()) if first.any() else float(amplitude[0])
    above = np.nonzero(amplitude >= fraction * reference)[0]
    if above.size == 0:
        return 0.0
    last = int(above[-1])
    if last == amplitude.size - 1:
        return math.inf
    return float(centres[last + 1])


@dataclass(frozen=True)
class Transient:
    """Windowed amplitude of a response: start, stationary level, overshoot, drift, settling."""

    first: float  # peak-to-peak in the first window
    stationary: float  # median peak-to-peak over the last quarter
    peak: float  # largest windowed peak-to-peak before `transient_end`
    peak_time: float  # centre of that window, s
    drift: float  # |median(3rd quarter) − median(4th quarter)| / median(4th quarter)
    settling_time: float  # after it the windowed p-p stays within [1/2, 2] × stationary, s

    @property
    def overshoot(self) -> float:
        """Peak / stationary (> 1: the transient overshoots the stationary amplitude)."""
        return self.peak / self.stationary if self.stationary > 0 else math.inf


def transient(
    time: np.typing.ArrayLike, signal: np.typing.ArrayLike, window: float, transient_end: float = 5.0
) -> Transient:
    """Windowed (e.g. per band period) peak-to-peak statistics of a response (see Transient)."""
    t, _ = _arrays(time, signal)
    centres, ptp = windowed_peak_to_peak(time, signal, window)
    if centres.size < 4:
        raise InputError(f"the record holds {centres.size} windows of {window:g} s; need at least 4")
    duration = t[-1] - t[0]
    q3 = (centres >= t[0] + 0.5 * duration) & (centres < t[0] + 0.75 * duration)
    q4 = centres >= t[0] + 0.75 * duration
    stationary = float(np.median(ptp[q4]))
    third = float(np.median(ptp[q3])) if q3.any() else stationary
    early = centres <= t[0] + transient_end
    k = int(np.argmax(np.where(early, ptp, -np.inf)))
    outside = np.nonzero((ptp > 2.0 * stationary) | (ptp < 0.5 * stationary))[0]
    settling = (
        float(centres[outside[-1] + 1])
        if outside.size and outside[-1] + 1 < centres.size
        else (math.inf if outside.size else float(centres[0]))
    )
    return Transient(
        first=float(ptp[0]),
        stationary=stationary,
        peak=float(ptp[k]),
        peak_time=float(centres[k]),
        drift=abs(third - stationary) / stationary if stationary > 0 else math.inf,
        settling_time=settling,
    )


def limit_cycle_separation(
    displacement: np.typing.ArrayLike,
    scaled_velocity: np.typing.ArrayLike,
    labels: np.typing.ArrayLike,
    first: object,
    second: object,
    quantile: float = 0.95,
) -> float:
    """Separation of two orbits in the phase plane (x, ẋ/ω): centre distance / (r1 + r2).

    Samples are split by `labels` (e.g. which band plateau); each orbit's centre is its mean,
    its radius the `quantile` of the distances to the centre. > 1: the two orbits do not overlap.
    """
    x = np.asarray(displacement, dtype=float)
    y = np.asarray(scaled_velocity, dtype=float)
    lab = np.asarray(labels)
    centres, radii = [], []
    for value in (first, second):
        pick = lab == value
        if pick.sum() < 4:
            raise InputError(f"label {value!r} has {int(pick.sum())} samples; need at least 4")
        cx, cy = x[pick].mean(), y[pick].mean()
        centres.append((cx, cy))
        radii.append(float(np.quantile(np.hypot(x[pick] - cx, y[pick] - cy), quantile)))
    distance = math.hypot(centres[0][0] - centres[1][0], centres[0][1] - centres[1][1])
    total = radii[0] + radii[1]
    return distance / total if total > 0 else math.inf


def spectral_peaks(
    signal: np.typing.ArrayLike, sample_rate: float, count: int = 8, floor: float = 0.01
) -> list[tuple[float, float]]:
    """Strongest peaks of the Hann-windowed amplitude spectrum: [(Hz, amplitude)], strongest first."""
    from .run import spectral_peaks as peaks

    return peaks(np.asarray(signal, dtype=float), sample_rate, count=count, floor=floor)


def near(frequency: float, expected: float, rel: float = 0.02, absolute: float = 0.15) -> bool:
    """Whether a measured frequency is the expected one (within max(rel·expected, absolute) Hz)."""
    return abs(frequency - expected) <= max(rel * expected, absolute)


def matches(frequencies: list[float], expected: list[float]) -> bool:
    """Each expected frequency has a measured one near it (and as many measured as expected)."""
    if len(frequencies) != len(expected):
        return False
    return all(any(near(f, e) for f in frequencies) for e in expected)


def stick_fraction(relative_velocity: np.typing.ArrayLike, threshold: float) -> float:
    """Fraction of samples with |v_rel| below the stick threshold (m/s)."""
    v = np.asarray(relative_velocity, dtype=float)
    return float(np.mean(np.abs(v) < threshold)) if v.size else math.nan


def explained_fraction(observed: np.typing.ArrayLike, model: np.typing.ArrayLike) -> float:
    """R² = 1 − Σ(observed − model)² / Σ(observed − mean)²: how much of `observed` `model` explains."""
    o = np.asarray(observed, dtype=float)
    m = np.asarray(model, dtype=float)
    total = float(np.sum((o - o.mean()) ** 2))
    if total == 0.0:
        return 1.0 if np.allclose(o, m) else -math.inf
    return 1.0 - float(np.sum((o - m) ** 2)) / total
