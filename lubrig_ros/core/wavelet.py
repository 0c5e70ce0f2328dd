"""Continuous wavelet transform after Torrence & Compo (1998), with ridges and dominant components.

Morlet mother wavelet (ω0 = 6), energy-normalized daughters computed in Fourier space, scales
s_j = s0 2^(j dj), wavelet power |W|²/σ² (so white noise has expected power 1), cone of influence
(e-folding time √2 s), global wavelet spectrum and 95 % significance against a fitted AR(1)
red-noise background. Everything works on plain numpy arrays; see docs/wavelets.md for the
choices and for the mapping to PyWavelets' normalization.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import scipy.fft as sfft
from scipy.special import chdtri

from lubrig_ros.core.errors import InputError

#: Morlet wave number (nondimensional frequency) used by the study and by Torrence & Compo.
OMEGA0 = 6.0
#: Reconstruction factor C_δ of the Morlet (ω0 = 6) wavelet, Torrence & Compo Table 2.
C_DELTA = 0.776
#: Decorrelation factor γ of the Morlet wavelet for time averaging, Torrence & Compo Table 2.
GAMMA_TIME = 2.32
#: Default scale spacing in octaves (12 voices per octave).
DEFAULT_DJ = 1.0 / 12.0
#: Fewest samples accepted by the transforms.
MIN_SAMPLES = 16
#: Largest AR(1) coefficient used for the red-noise background (keeps the spectrum finite).
MAX_LAG1 = 0.999


def fourier_factor(omega0: float = OMEGA0) -> float:
    """Fourier period / scale of the Morlet wavelet: 4π/(ω0 + √(2 + ω0²)) ≈ 1.033 for ω0 = 6."""
    return 4.0 * math.pi / (omega0 + math.sqrt(2.0 + omega0**2))


def padded_length(n: int) -> int:
    """FFT length of Torrence & Compo: the power of two above n, doubled (limits wrap-around)."""
    return int(2 ** (int(math.log2(n) + 0.4999) + 1))


def _check_dt(dt: float) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise InputError(f"dt={dt!r} is not a number; expected a sample interval > 0 s") from None
    if not math.isfinite(value) or value <= 0.0:
        raise InputError(f"dt={dt!r} is not valid; expected a finite sample interval > 0 s")
    return value


def check_signal(signal: Any, name: str = "signal", min_length: int = MIN_SAMPLES) -> np.ndarray:
    """Return the signal as a 1-D float array or raise ValueError naming what is wrong."""
    x = np.asarray(signal, dtype=float)
    if x.ndim != 1:
        raise InputError(f"{name} has shape {x.shape}; expected a 1-D array of samples")
    if x.size < min_length:
        raise InputError(f"{name} has {x.size} samples; at least {min_length} are needed")
    bad = ~np.isfinite(x)
    if bad.any():
        first = int(np.argmax(bad))
        raise InputError(
            f"{name} contains {int(bad.sum())} non-finite value(s) (first {x[first]!r} at index "
            f"{first}); expected finite samples"
        )
    return x


def scale_grid(
    dt: float,
    n_samples: int,
    dj: float = DEFAULT_DJ,
    s0: float | None = None,
    n_scales: int | None = None,
    fmin: float | None = None,
    fmax: float | None = None,
) -> np.ndarray:
    """Scales s0 2^(j dj) in s, j = 0 … J−1.

    Defaults follow Torrence & Compo: s0 = 2 dt and J covering up to the signal length N dt.
    fmax (Hz) sets s0 instead, fmin (Hz) sets the largest scale; n_scales overrides J.
    """
    dt = _check_dt(dt)
    if not (math.isfinite(dj) and dj > 0.0):
        raise InputError(f"dj={dj!r} is not valid; expected a scale step > 0 octaves")
    ff = fourier_factor()
    nyquist = 0.5 / dt
    if fmax is not None:
        if not (math.isfinite(fmax) and 0.0 < fmax <= nyquist):
            raise InputError(f"fmax={fmax!r} Hz is not valid; expected 0 < fmax <= {nyquist:g} Hz")
        s0 = 1.0 / (fmax * ff)
    if s0 is None:
        s0 = 2.0 * dt
    if not (math.isfinite(s0) and s0 > 0.0):
        raise InputError(f"s0={s0!r} is not valid; expected a smallest scale > 0 s")
    if fmin is not None:
        if not (math.isfinite(fmin) and fmin > 0.0):
            raise InputError(f"fmin={fmin!r} Hz is not valid; expected fmin > 0 Hz")
        s_max = 1.0 / (fmin * ff)
    else:
        s_max = n_samples * dt
    if n_scales is None:
        if s_max < s0:
            raise InputError(
                f"largest scale {s_max:g} s is below the smallest {s0:g} s; "
                "check fmin/fmax and the signal length"
            )
        n_scales = math.floor(math.log2(s_max / s0) / dj) + 1
    if n_scales < 1:
        raise InputError(f"n_scales={n_scales!r} is not valid; expected at least 1 scale")
    return s0 * 2.0 ** (dj * np.arange(n_scales))


def daughter_fft(scales: np.ndarray, n_fft: int, dt: float, omega0: float = OMEGA0) -> np.ndarray:
    """Morlet daughters ψ̂(s ω_k) on the non-negative FFT frequencies, shape (J, n_fft//2 + 1).

    ψ̂ = √(2π s/dt) π^(−1/4) exp(−(sω − ω0)²/2) for ω > 0, zero otherwise: normalized so that
    Σ_k |ψ̂(s ω_k)|² = n_fft at every scale (unit energy). Negative frequencies are zero, so they
    are not stored.
    """
    k = np.arange(n_fft // 2 + 1)
    omega = 2.0 * math.pi * k / (n_fft * dt)
    s = np.asarray(scales, dtype=float)[:, None]
    norm = np.sqrt(2.0 * math.pi * s / dt) * math.pi**-0.25
    psi = norm * np.exp(-0.5 * (s * omega[None, :] - omega0) ** 2)
    psi[:, 0] = 0.0
    return psi


def transform_coefficients(
    x: np.ndarray, psi_hat: np.ndarray, n_fft: int, dtype: type = np.complex128
) -> np.ndarray:
    """W_n(s) = IFFT(x̂ · ψ̂) for every scale, first x.size columns; x must be demeaned."""
    n = x.size
    x_hat = sfft.rfft(x, n_fft).astype(dtype, copy=False)
    out: np.ndarray = np.empty((psi_hat.shape[0], n), dtype=dtype)
    chunk = max(1, (1 << 22) // n_fft)
    half = n_fft // 2 + 1
    buffer = np.zeros((min(chunk, psi_hat.shape[0]), n_fft), dtype=dtype)
    for j0 in range(0, psi_hat.shape[0], chunk):
        j1 = min(j0 + chunk, psi_hat.shape[0])
        block = buffer[: j1 - j0]
        block[:, half:] = 0.0
        np.multiply(x_hat[None, :], psi_hat[j0:j1], out=block[:, :half])
        out[j0:j1] = sfft.ifft(block, axis=1)[:, :n]
    return out


def lag1_autocorrelation(x: np.ndarray) -> float:
    """AR(1) coefficient α fitted to a demeaned series (Yule–Walker), clipped to [0, MAX_LAG1]."""
    x = np.asarray(x, dtype=float)
    # np.sum of products, not np.dot: BLAS splits long dot products over its threads, so np.dot's
    # last bits depend on the BLAS thread count of the process (sweep workers vs. the driver)
    denom = float(np.sum(x * x))
    if denom <= 0.0 or x.size < 2:
        return 0.0
    alpha = float(np.sum(x[:-1] * x[1:]) / denom)
    return min(max(alpha, 0.0), MAX_LAG1)


def red_noise_spectrum(periods: np.ndarray, dt: float, lag1: float) -> np.ndarray:
    """Return the normalized AR(1) spectrum (1−α²)/(1+α²−2α cos(2π dt/T)) at periods T."""
    if not (math.isfinite(lag1) and 0.0 <= lag1 < 1.0):
        raise InputError(f"lag1={lag1!r} is not valid; expected an AR(1) coefficient in [0, 1)")
    cos = np.cos(2.0 * math.pi * dt / np.asarray(periods, dtype=float))
    return (1.0 - lag1**2) / (1.0 + lag1**2 - 2.0 * lag1 * cos)


def significance_level(
    periods: np.ndarray, dt: float, lag1: float, level: float = 0.95, n_average: Any = None
) -> np.ndarray:
    """Return the normalized power at the confidence level against AR(1) red noise.

    Without n_average: local power, χ²₂ (TC eq. 18). With n_average (count of averaged points,
    scalar or per scale): time-averaged power with ν = 2√(1 + (n dt/(γ s))²) (TC eq. 23).
    """
    if not 0.0 < level < 1.0:
        raise InputError(f"level={level!r} is not valid; expected a confidence level in (0, 1)")
    background = red_noise_spectrum(periods, dt, lag1)
    if n_average is None:
        return background * chdtri(2.0, 1.0 - level) / 2.0
    scales = np.asarray(periods, dtype=float) / fourier_factor()
    n_avg = np.maximum(np.asarray(n_average, dtype=float), 1.0)
    dof = 2.0 * np.sqrt(1.0 + (n_avg * dt / (GAMMA_TIME * scales)) ** 2)
    return background * chdtri(dof, 1.0 - level) / dof


def cone_of_influence(n: int, dt: float) -> np.ndarray:
    """Largest Fourier period (s) free of edge effects at each sample: √2 s e-folding from ends."""
    idx = np.arange(n, dtype=float)
    distance = np.minimum(idx, n - 1 - idx)
    coi = fourier_factor() / math.sqrt(2.0) * dt * distance
    coi[coi == 0.0] = 1e-5 * dt  # TC mark the end points as (almost) zero
    return coi


@dataclass(frozen=True)
class WaveletResult:
    """Wavelet power spectrum of one signal and everything needed to read it."""

    time: np.ndarray  # (N,) s
    scales: np.ndarray  # (J,) s
    periods: np.ndarray  # (J,) Fourier periods, s
    power: np.ndarray  # (J, N) |W|²/σ², dimensionless
    coi: np.ndarray  # (N,) largest period outside the cone of influence, s
    variance: float  # σ² of the analysed (demeaned) signal, signal units²
    lag1: float  # AR(1) coefficient of the red-noise background
    significance: np.ndarray  # (J,) normalized power at the confidence level (local)
    global_spectrum: np.ndarray  # (J,) time mean of power
    global_significance: np.ndarray  # (J,) significance of the global spectrum
    dt: float
    dj: float
    level: float = 0.95
    coefficients: np.ndarray | None = None  # (J, N) complex W, when asked for

    @property
    def frequencies(self) -> np.ndarray:
        """Fourier frequencies of the scales in Hz."""
        return 1.0 / self.periods

    @property
    def outside_coi(self) -> np.ndarray:
        """Boolean (J, N) mask of points free of edge effects."""
        return self.periods[:, None] <= self.coi[None, :]

    @property
    def significance_ratio(self) -> np.ndarray:
        """Power over its significance level: > 1 is significant at `level`."""
        return self.power / self.significance[:, None]

    def global_peak(self) -> tuple[float, float]:
        """(frequency in Hz, normalized power) of the largest global-spectrum value."""
        j = int(np.argmax(self.global_spectrum))
        return float(self.frequencies[j]), float(self.global_spectrum[j])

    def reconstructed_variance(self) -> float:
        """Return σ² rebuilt from the power, TC eq. 14: (dj dt/C_δ) mean_n Σ_j |W|²/s_j."""
        raw = self.power * self.variance
        return float(self.dj * self.dt / C_DELTA * np.mean(np.sum(raw / self.scales[:, None], 0)))


def build_result(
    x: np.ndarray,
    raw_power: np.ndarray,
    scales: np.ndarray,
    dt: float,
    dj: float,
    t0: float = 0.0,
    lag1: float | None = None,
    level: float = 0.95,
    coefficients: np.ndarray | None = None,
) -> WaveletResult:
    """Assemble a WaveletResult from |W|² of the demeaned signal x (shared with online.py)."""
    n = x.size
    variance = float(np.sum(x * x) / n)  # not np.dot: see lag1_autocorrelation
    periods = scales * fourier_factor()
    alpha = lag1_autocorrelation(x) if lag1 is None else float(lag1)
    power = raw_power / variance if variance > 0.0 else np.zeros_like(raw_power)
    return WaveletResult(
        time=t0 + dt * np.arange(n),
        scales=scales,
        periods=periods,
        power=power,
        coi=cone_of_influence(n, dt),
        variance=variance,
        lag1=alpha,
        significance=significance_level(periods, dt, alpha, level),
        global_spectrum=power.mean(axis=1),
        global_significance=significance_level(periods, dt, alpha, level, n_average=n),
        dt=dt,
        dj=dj,
        level=level,
        coefficients=coefficients,
    )


def cwt(
    signal: Any,
    dt: float,
    *,
    dj: float = DEFAULT_DJ,
    s0: float | None = None,
    n_scales: int | None = None,
    fmin: float | None = None,
    fmax: float | None = None,
    scales: np.ndarray | None = None,
    lag1: float | None = None,
    level: float = 0.95,
    t0: float = 0.0,
    keep_coefficients: bool = False,
) -> WaveletResult:
    """Torrence–Compo Morlet wavelet power spectrum of a uniformly sampled signal.

    The mean is removed; the series is zero-padded to padded_length(N). Raises ValueError for
    empty, too short, non-finite or constant signals (power normalized by σ² is undefined).
    Pass `scales` (s) to reuse a grid (dj is then only used for the variance check).
    """
    dt = _check_dt(dt)
    x = check_signal(signal)
    x = x - x.mean()
    if not np.any(x):
        raise InputError("signal is constant (variance 0); its normalized wavelet power is undefined")
    if scales is None:
        scales = scale_grid(dt, x.size, dj, s0, n_scales, fmin, fmax)
    else:
        scales = np.asarray(scales, dtype=float)
        if scales.ndim != 1 or scales.size == 0 or not np.all(np.isfinite(scales) & (scales > 0)):
            raise InputError("scales must be a non-empty 1-D array of finite scales > 0 s")
    n_fft = padded_length(x.size)
    coeffs = transform_coefficients(x, daughter_fft(scales, n_fft, dt), n_fft)
    raw = coeffs.real**2 + coeffs.imag**2
    return build_result(x, raw, scales, dt, dj, t0, lag1, level, coeffs if keep_coefficients else None)


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


def ridge(result: WaveletResult) -> np.ndarray:
    """Frequency (Hz) of the power maximum at each time, interpolated between scales.

    NaN where every scale is inside the cone of influence.
    """
    inside = ~result.outside_coi
    power = np.where(inside, -np.inf, result.power)
    j = np.argmax(power, axis=0)
    out = np.full(result.time.size, np.nan)
    log_periods = np.log(result.periods)
    step = log_periods[1] - log_periods[0] if result.periods.size > 1 else 0.0
    for n in np.flatnonzero(~inside.all(axis=0)):
        column = np.where(np.isfinite(power[:, n]), result.power[:, n], 0.0)
        pos, _ = _refine_peak(column, int(j[n]))
        out[n] = math.exp(-(log_periods[0] + pos * step))
    return out


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
    dt = _check_dt(dt)
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
