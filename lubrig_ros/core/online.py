"""Online sliding-window wavelet analysis: push samples as they arrive, get the latest power.

The analyzer keeps the last `window` samples in a ring buffer (no history is stored) and, on each
update, gives exactly the Torrence–Compo transform of the current window (same as wavelet.cwt on
those samples):

* the newest power columns by direct dot products with precomputed wavelet kernels (rows of the
  circular kernel h = IFFT(ψ̂) of the padded window), one matrix product for all new columns,
  cost J × (window + k) × k for k new columns, when no full analysis is due and k is at most
  DIRECT_COLUMNS_MAX (otherwise they are read from it);
* the whole-window power, dominant components and flags by one rfft + multiply + batched ifft
  with precomputed daughter FFTs, cost O(J × P log P) with P the padded window length.

Both costs depend on the window and the number of scales only, never on the length of the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from .flags import StabilityFlags, evaluate_flags
from .params import RigParameters
from .wavelet import (
    MIN_SAMPLES,
    WaveletResult,
    build_result,
    check_dt,
    daughter_fft,
    fourier_factor,
    padded_length,
    transform_coefficients,
)
from .wavelet_components import Component, dominant_components

#: New columns per update up to which direct kernels are used (above it: take them from the FFT).
#: The direct product costs J × (window + k) × k; at the analysis node's defaults (window 2048,
#: 32 scales) it stays below half the cost of the whole-window FFT up to here (docs/benchmarks.md).
DIRECT_COLUMNS_MAX = 128


@dataclass(frozen=True)
class OnlineUpdate:
    """What one push returns. Empty arrays and no components until the window is full."""

    ready: bool  # the window is full and the numbers below are defined
    time: np.ndarray  # (k,) times of the newest columns, s
    power: np.ndarray  # (J, k) normalized power |W|²/σ²_window of the newest samples
    frequencies: np.ndarray  # (J,) Fourier frequencies of the scales, Hz
    components: list[Component] = field(default_factory=list)
    window: WaveletResult | None = None  # full-window analysis when it was computed
    flags: StabilityFlags | None = None


class OnlineWaveletAnalyzer:
    """Sliding-window Morlet analysis of a uniformly sampled stream (e.g. the displacement).

    dt: sample interval (s); window: samples analysed; n_scales scales spaced evenly in log
    between fmax (default a quarter of the sample rate) and fmin (default 4 cycles per window).
    analysis_every: samples between full-window analyses (components, flags); 1 = every update.
    precision: 'single' (complex64 FFTs, relative error ~1e-6 of the peak) or 'double'.
    rig/natural frequency: when rig is given, flags are evaluated from the window.
    """

    def __init__(
        self,
        dt: float,
        window: int = 4096,
        n_scales: int = 64,
        fmin: float | None = None,
        fmax: float | None = None,
        fundamental_hz: float | None = None,
        n_components: int = 5,
        analysis_every: int = 1,
        precision: str = "single",
        rig: RigParameters | None = None,
        t0: float = 0.0,
    ) -> None:
        self.dt = check_dt(dt)
        if not isinstance(window, (int, np.integer)) or window < MIN_SAMPLES:
            raise InputError(f"window={window!r} is not valid; expected an integer >= {MIN_SAMPLES}")
        if not isinstance(n_scales, (int, np.integer)) or n_scales < 2:
            raise InputError(f"n_scales={n_scales!r} is not valid; expected an integer >= 2")
        if precision not in ("single", "double"):
            raise InputError(f"precision={precision!r} is not valid; expected 'single' or 'double'")
        if not isinstance(analysis_every, (int, np.integer)) or analysis_every < 1:
            raise InputError(f"analysis_every={analysis_every!r} is not valid; expected >= 1")
        fmax = 0.25 / self.dt if fmax is None else float(fmax)
        fmin = 4.0 / (window * self.dt) if fmin is None else float(fmin)
        if not (0.0 < fmin < fmax <= 0.5 / self.dt):
            raise InputError(
                f"fmin={fmin!r} Hz, fmax={fmax!r} Hz are not valid; expected "
                f"0 < fmin < fmax <= {0.5 / self.dt:g} Hz (Nyquist)"
            )
        ff = fourier_factor()
        s0, s1 = 1.0 / (fmax * ff), 1.0 / (fmin * ff)
        self.dj = math.log2(s1 / s0) / (n_scales - 1)
        self.scales = s0 * 2.0 ** (self.dj * np.arange(n_scales))
        self.frequencies = 1.0 / (self.scales * ff)
        self.window = int(window)
        self.fundamental_hz = fundamental_hz
        self.n_components = n_components
        self.analysis_every = int(analysis_every)
        self.rig = rig
        self.t0 = float(t0)
        self._dtype = np.complex64 if precision == "single" else np.complex128
        self._n_fft = padded_length(self.window)
        psi = daughter_fft(self.scales, self._n_fft, self.dt)
        self._psi = psi.astype(np.float32 if precision == "single" else np.float64)
        # Circular kernel h_j[l] = IFFT(ψ̂_j)[l]; column n of the window is Σ_m x_m h[(n − m) mod P].
        full = np.zeros((n_scales, self._n_fft), dtype=complex)
        full[:, : psi.shape[1]] = psi
        h = np.fft.ifft(full, axis=1)
        lags = (self.window - 1 - np.arange(2 * self.window - 1)) % self._n_fft
        # kernel[:, d + m] multiplies x_m for the column d samples before the end
        kernel = h[:, lags]
        # real rows, then imaginary rows: one matrix product per update
        stacked = np.concatenate((kernel.real, kernel.imag))
        real = np.float32 if precision == "single" else np.float64
        self._kernel = np.ascontiguousarray(stacked, dtype=real)
        self._buf = np.zeros(self.window)
        self._vrel = np.zeros(self.window)
        self._have_vrel = False
        self._pos = 0
        self._count = 0
        self._since_analysis = 0
        self._band_velocity: float | None = None

    @property
    def samples_seen(self) -> int:
        """Total samples pushed since construction (only the last `window` are kept)."""
        return self._count

    def window_samples(self) -> np.ndarray:
        """Copy of the current window in time order (shorter until the window fills)."""
        if self._count < self.window:
            return self._buf[: self._count].copy()
        return np.concatenate((self._buf[self._pos :], self._buf[: self._pos]))

    def _write(self, ring: np.ndarray, x: np.ndarray) -> None:
        """Write x at the ring position (only its last `window` samples survive)."""
        start = (self._pos + x.size - min(x.size, self.window)) % self.window
        x = x[-self.window :]
        first = min(x.size, self.window - start)
        ring[start : start + first] = x[:first]
        ring[: x.size - first] = x[first:]

    def _direct_columns(self, xc: np.ndarray, k: int) -> np.ndarray:
        """|W|² of the k newest columns of the centred window xc by direct kernels, oldest first, (J, k).

        Column i (d = k − 1 − i samples before the end) is Σ_m kernel[:, d + m] · xc_m; for all k
        columns at once that is kernel[:, :n + k − 1] @ H with the Hankel matrix H[u, i] =
        xc_pad[u + i] (xc with k − 1 zeros on each side): one matrix product of the stacked real
        and imaginary kernels.
        """
        n, j = self.window, self.scales.size
        pad = np.zeros(k - 1, dtype=self._kernel.dtype)
        padded = np.concatenate((pad, xc.astype(self._kernel.dtype), pad))
        hankel = np.ascontiguousarray(np.lib.stride_tricks.sliding_window_view(padded, k))
        both = self._kernel[:, : n + k - 1] @ hankel
        re, im = both[:j].astype(float), both[j:].astype(float)
        power: np.ndarray = re * re + im * im
        return power

    def push(
        self,
        samples: Any,
        relative_velocity: Any = None,
        band_velocity: float | None = None,
    ) -> OnlineUpdate:
        """Add samples (any length ≥ 0) and return the newest columns and, when due, the analysis.

        relative_velocity (same length as samples) feeds stick detection; band_velocity (m/s)
        the linear verdict (the last value given is kept for later pushes). Non-finite
        samples raise ValueError and leave the state unchanged.
        """
        x_new = np.atleast_1d(np.asarray(samples, dtype=float))
        if x_new.ndim != 1:
            raise InputError(f"samples have shape {x_new.shape}; expected a 1-D array")
        if not np.all(np.isfinite(x_new)):
            raise InputError("samples contain NaN or infinite values; expected finite samples")
        v_new = None
        if relative_velocity is not None:
            v_new = np.atleast_1d(np.asarray(relative_velocity, dtype=float))
            if v_new.shape != x_new.shape or not np.all(np.isfinite(v_new)):
                raise InputError(f"relative_velocity must be finite with the samples' shape {x_new.shape}")
        if band_velocity is not None:
            self._band_velocity = float(band_velocity)
        empty = OnlineUpdate(False, np.empty(0), np.empty((self.scales.size, 0)), self.frequencies)
        if x_new.size == 0:
            return empty
        self._write(self._buf, x_new)
        if v_new is not None:
            self._write(self._vrel, v_new)
            self._have_vrel = True
        self._pos = (self._pos + x_new.size) % self.window
        self._count += x_new.size
        self._since_analysis += x_new.size
        if self._count < self.window:
            return empty
        x = self.window_samples()
        mean = float(x.mean())
        xc = x - mean
        variance = float(np.sum(xc * xc) / xc.size)  # as wavelet.cwt: independent of BLAS threads
        k = min(x_new.size, self.window)
        t_end = self.t0 + (self._count - 1) * self.dt
        times = t_end - self.dt * np.arange(k - 1, -1, -1)
        result = None
        if self._since_analysis >= self.analysis_every or k > DIRECT_COLUMNS_MAX:
            self._since_analysis = 0
            coeffs = transform_coefficients(xc, self._psi, self._n_fft, self._dtype)
            raw = (coeffs.real**2 + coeffs.imag**2).astype(float)
            t_start = t_end - self.dt * (x.size - 1)
            result = build_result(xc, raw, self.scales, self.dt, self.dj, t_start)
        if variance <= 0.0:
            columns = np.zeros((self.scales.size, k))
        elif result is not None:
            columns = result.power[:, -k:]
        else:
            columns = self._direct_columns(xc, k) / variance
        components: list[Component] = []
        flags = None
        if result is not None:
            components = dominant_components(result, self.fundamental_hz, self.n_components)
            if self.rig is not None:
                vrel = None
                if self._have_vrel:
                    vrel = np.concatenate((self._vrel[self._pos :], self._vrel[: self._pos]))
                flags = evaluate_flags(
                    self.rig,
                    band_velocity=self._band_velocity,
                    relative_velocity=vrel,
                    dt=self.dt,
                    fundamental_hz=self.fundamental_hz,
                    wavelet=result,
                )
        return OnlineUpdate(True, times, columns, self.frequencies, components, result, flags)
