"""Continuous wavelet transform after Torrence & Compo (1998) (ridges, components: wavelet_components).

Morlet mother wavelet (ω0 = 6), energy-normalized daughters computed in Fourier space, scales
s_j = s0 2^(j dj), wavelet power |W|²/σ² (so white noise has expected power 1), cone of influence
(e-folding time √2 s), global wavelet spectrum and 95 % significance against a fitted AR(1)
red-noise background. Everything works on plain numpy arrays; see docs/wavelets.md for the
choices and for the mapping to PyWavelets' normalization.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
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


def check_dt(dt: float) -> float:
    """The sample interval as a float; InputError unless it is finite and > 0 s."""
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
    dt = check_dt(dt)
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
    psi: np.ndarray = norm * np.exp(-0.5 * (s * omega[None, :] - omega0) ** 2)
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
        single: np.ndarray = background * chdtri(2.0, 1.0 - level) / 2.0
        return single
    scales = np.asarray(periods, dtype=float) / fourier_factor()
    n_avg = np.maximum(np.asarray(n_average, dtype=float), 1.0)
    dof = 2.0 * np.sqrt(1.0 + (n_avg * dt / (GAMMA_TIME * scales)) ** 2)
    averaged: np.ndarray = background * chdtri(dof, 1.0 - level) / dof
    return averaged


def cone_of_influence(n: int, dt: float) -> np.ndarray:
    """Largest Fourier period (s) free of edge effects at each sample: √2 s e-folding from ends."""
    idx = np.arange(n, dtype=float)
    distance = np.minimum(idx, n - 1 - idx)
    coi: np.ndarray = fourier_factor() / math.sqrt(2.0) * dt * distance
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
        ratio: np.ndarray = self.power / self.significance[:, None]
        return ratio

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
    dt = check_dt(dt)
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
