"""Offline runs: integrate a RunConfig and summarize the response (shared by CLI, nodes, sweeps)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .friction import stick_velocity_or_none
from .integrator import RigIntegrator
from .presets import RunConfig
from .trajectory import Trajectory, concatenate


def integrator_for(config: RunConfig) -> RigIntegrator:
    """A fresh integrator at t = 0 for this configuration."""
    return RigIntegrator(
        config.rig,
        float(config.band(0.0)),
        sample_rate=config.sample_rate,
        rtol=config.rtol,
        initial_perturbation=config.initial_perturbation,
    )


def band_samples(config: RunConfig, start: int, count: int) -> np.ndarray:
    """Band velocity at samples start+1 … start+count (t = k / sample_rate)."""
    k = np.arange(start + 1, start + count + 1, dtype=float)
    return np.asarray(config.band(k / config.sample_rate), dtype=float)


def simulate(config: RunConfig) -> Trajectory:
    """Integrate the whole run; sample 0 is the initial condition at t = 0."""
    integrator = integrator_for(config)
    first = integrator.current()
    return concatenate([first, integrator.advance(band_samples(config, 0, config.samples))])


def spectral_peaks(
    signal: np.ndarray, sample_rate: float, count: int = 5, floor: float = 0.01
) -> list[tuple[float, float]]:
    """Strongest peaks of the Hann-windowed amplitude spectrum: [(frequency Hz, amplitude)].

    Peaks below `floor` times the strongest are dropped; frequencies refined by parabolic
    interpolation of the log spectrum.
    """
    x = np.asarray(signal, dtype=float)
    if x.size < 8 or not np.isfinite(x).all():
        return []
    x = x - x.mean()
    if not np.any(x):
        return []
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    spectrum[0] = 0.0
    inner = spectrum[1:-1]
    is_peak = (inner > spectrum[:-2]) & (inner >= spectrum[2:])
    index = np.nonzero(is_peak)[0] + 1
    if index.size == 0:
        return []
    top = spectrum[index].max()
    index = index[spectrum[index] >= floor * top]
    index = index[np.argsort(-spectrum[index])][:count]
    peaks = []
    for i in index:
        a, b, c = np.log(spectrum[i - 1 : i + 2] + 1e-300)
        denom = a - 2 * b + c
        shift = 0.5 * (a - c) / denom if denom != 0 else 0.0
        peaks.append((float((i + shift) * sample_rate / x.size), float(spectrum[i])))
    return peaks


def summarize(trajectory: Trajectory, config: RunConfig) -> dict[str, Any]:
    """Stationary measures over the second half of the run (the first half is transient).

    The stick threshold is the friction-peak velocity; for a law without a peak (with these
    parameters) there is none, and stick_threshold_m_s and stick_fraction are None.
    """
    half = trajectory.time >= trajectory.time[-1] / 2.0
    x = trajectory.displacement[half]
    mu = trajectory.friction_coefficient[half]
    stick_threshold = stick_velocity_or_none(config.rig.friction)
    stick_fraction = None
    if stick_threshold is not None:
        stick_fraction = float((np.abs(trajectory.relative_velocity[half]) < stick_threshold).mean())
    peaks = spectral_peaks(x, config.sample_rate)
    return {
        "name": config.name,
        "convention": config.rig.coupling_name,
        "velocity_coupling": config.rig.velocity_factor,  # γ in v_rel = v_band − γ ẋ
        "coupling_strength": config.rig.coupling_strength,  # s = γ · A / A_default
        "duration": config.duration,
        "sample_rate_hz": config.sample_rate,
        "samples": len(trajectory),
        "natural_frequency_hz": config.rig.natural_frequency,
        "band_fundamental_hz": config.band.fundamental_hz,
        "x_peak_to_peak": float(np.ptp(x)),
        "mu_min": float(mu.min()),
        "mu_max": float(mu.max()),
        "stick_threshold_m_s": stick_threshold,
        "stick_fraction": stick_fraction,
        "dominant_frequencies_hz": [f for f, _ in peaks],
        "spectral_amplitudes": [a for _, a in peaks],
        "window": "second half of the run",
    }
