"""What a wavelet spectrum shows: its dominant components and their harmonic names.

Read off a :class:`lubrig_ros.core.wavelet.WaveletResult` (the transform); docs/wavelets.md.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError
from lubrig_ros.core.wavelet import (
    DEFAULT_DJ,
    WaveletResult,
    check_dt,
    check_signal,
    cwt,
    fourier_factor,
    significance_level,
)


def _refine_peak(values: np.ndarray, j: int) -> tuple[float, float]:
    """Parabolic interpolation of log-values around index j: (fractional index, peak value)."""
    if j <= 0 or j >= values.size - 1 or np.any(values[j - 1 : j + 2] <= 0.0):
        return float(j), float(values[j])
    a, b, c = np.log(values[j - 1 : j + 2])
    denom = a - 2.0 * b + c
    if denom >= 0.0:
        return float(j), float(values[j])
    offset = 0.5 * (a - c) / denom
    return j + offset, float(math.exp(b - 0.25 * (a - c) * offset))


def _ordinal(k: int) -> str:
    if 10 <= k % 100 <= 20:
        return f"{k}th"
    return f"{k}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th') }"


def harmonic_label(
    frequency_hz: float, fundamental_hz: float | None, tolerance: float = 0.05
) -> tuple[int | None, str]:
    """Name a frequency relative to the band fundamental: (harmonic number or None, label).

    k f within `tolerance` (relative) is the k-th harmonic ("fundamental" for k = 1); f/k is
    called a 1/k subharmonic. Without a fundamental the label is just the frequency.
    """
    text = f"{frequency_hz:.3g} Hz"
    if fundamental_hz is None or not (math.isfinite(fundamental_hz) and fundamental_hz > 0):
        return None, text
    base = f"{fundamental_hz:.3g} Hz"
    ratio = frequency_hz / fundamental_hz
    k = round(ratio)
    if k >= 1 and abs(ratio - k) <= tolerance * k:
        if k == 1:
            return 1, f"fundamental {base}"
        return k, f"{_ordinal(k)} harmonic of {base}"
    m = round(1.0 / ratio) if ratio > 0 else 0
    if m >= 2 and abs(1.0 / ratio - m) <= tolerance * m:
        return None, f"1/{m} subharmonic of {base} ({text})"
    return None, f"{text} (not a harmonic of {base})"


@dataclass(frozen=True)
class Component:
    """One dominant frequency of a time window (outside the cone of influence)."""

    frequency_hz: float
    period_s: float
    power: float  # time-mean normalized wavelet power |W|²/σ² at the peak
    amplitude: float  # sine amplitude that gives this power, in signal units
    significant: bool  # above the 95 % level of the time-averaged red-noise spectrum
    harmonic: int | None  # k when it is the k-th harmonic of the fundamental
    label: str

    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary (JSON friendly)."""
        return asdict(self)


def local_maxima(x: np.ndarray) -> np.ndarray:
    """Indices of the local maxima of a 1-D array, as scipy.signal.find_peaks(x) finds them.

    A maximum is higher than its left neighbour and than the first different value to its right;
    of a flat top, the middle sample (rounded down). The ends are never maxima. Here rather than
    find_peaks because importing scipy.signal costs about 1 s of CPU (every analysis node paid
    it) for a loop over a few dozen scales.
    """
    values = np.asarray(x, dtype=float).reshape(-1)
    out: list[int] = []
    i, last = 1, values.size - 1
    while i < last:
        if values[i - 1] < values[i]:
            ahead = i + 1
            while ahead < last and values[ahead] == values[i]:
                ahead += 1
            if values[ahead] < values[i]:
                out.append((i + ahead - 1) // 2)
                i = ahead
        i += 1
    return np.array(out, dtype=np.intp)


def dominant_components(
    result: WaveletResult,
    fundamental_hz: float | None = None,
    n: int = 5,
    t_start: float | None = None,
    t_end: float | None = None,
    min_relative_power: float = 1e-3,
    tolerance: float = 0.05,
) -> list[Component]:
    """Strongest spectral peaks of the power averaged over [t_start, t_end] outside the COI.

    Peaks are local maxima (in scale) of that time-averaged spectrum, refined by parabolic
    interpolation, strongest first; those below min_relative_power × the strongest are dropped.
    """
    if n < 1:
        raise InputError(f"n={n!r} is not valid; expected at least 1 component")
    if result.variance <= 0.0:
        return []
    mask = result.outside_coi.copy()
    if t_start is not None:
        mask &= result.time[None, :] >= t_start
    if t_end is not None:
        mask &= result.time[None, :] <= t_end
    counts = mask.sum(axis=1)
    usable = counts > 0
    if not usable.any():
        return []
    spectrum = np.zeros(result.scales.size)
    spectrum[usable] = (result.power * mask).sum(axis=1)[usable] / counts[usable]
    padded = np.concatenate(([0.0], spectrum, [0.0]))  # let edge scales count as peaks
    peaks = local_maxima(padded) - 1
    peaks = peaks[usable[peaks]]
    if peaks.size == 0:
        return []
    strongest = spectrum[peaks].max()
    peaks = peaks[spectrum[peaks] >= min_relative_power * strongest]
    peaks = peaks[np.argsort(spectrum[peaks])[::-1]][:n]
    log_s = np.log(result.scales)
    step = log_s[1] - log_s[0] if log_s.size > 1 else 0.0
    components = []
    for j in peaks:
        pos, value = _refine_peak(spectrum, int(j))
        scale = math.exp(log_s[0] + pos * step)
        period = scale * fourier_factor()
        level = significance_level(
            np.array([period]), result.dt, result.lag1, result.level, n_average=counts[j]
        )[0]
        raw_peak = value * result.variance  # |W|² = A² s √π / (2 dt) for a sine of amplitude A
        amplitude = math.sqrt(2.0 * result.dt * raw_peak / (scale * math.sqrt(math.pi)))
        harmonic, label = harmonic_label(1.0 / period, fundamental_hz, tolerance)
        components.append(
            Component(
                frequency_hz=1.0 / period,
                period_s=period,
                power=value,
                amplitude=amplitude,
                significant=bool(value > level),
                harmonic=harmonic,
                label=label,
            )
        )
    return components


def dominant_frequencies(
    signal: Any,
    dt: float,
    fundamental_hz: float | None = None,
    n: int = 5,
    start: float | None = None,
    *,
    dj: float = DEFAULT_DJ,
    fmin: float | None = None,
    fmax: float | None = None,
    min_relative_power: float = 1e-3,
) -> list[Component]:
    """Dominant components of signal[start/dt:] (start in s from the first sample).

    A constant signal gives an empty list; empty, too short or non-finite signals raise ValueError.
    """
    dt = check_dt(dt)
    x = np.asarray(signal, dtype=float)
    if start is not None:
        if not (math.isfinite(start) and start >= 0.0):
            raise InputError(f"start={start!r} s is not valid; expected a time >= 0 s")
        x = x[round(start / dt) :] if x.ndim == 1 else x
    x = check_signal(x, "signal (after start)" if start else "signal")
    if not np.any(x - x.mean()):
        return []
    result = cwt(x, dt, dj=dj, fmin=fmin, fmax=fmax)
    return dominant_components(result, fundamental_hz, n, min_relative_power=min_relative_power)
