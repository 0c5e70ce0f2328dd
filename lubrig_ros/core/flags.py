"""Stability flags that combine the linear model with what the signal shows.

* linear verdict and friction zone at the current band velocity (core.stability);
* observed growth/decay rate of the oscillation envelope, 1/s: least-squares slope of the log of
  the wavelet amplitude √power at the natural-frequency scale, outside the cone of influence;
* stick: |v_rel| < threshold, by default the friction-peak velocity (core.friction.stick_velocity,
  as in the run summaries) (share of samples, episodes);
* resonance: the band fundamental or one of its low harmonics within a relative margin of f0.

Each field is None when the inputs needed for it were not given. `to_dict` gives plain values
for diagnostics (the ROS analysis node turns each group into one status).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from .friction import stick_velocity_or_none
from .params import RigParameters
from .stability import ZONE_NAMES, linear_stability
from .wavelet import WaveletResult, check_signal, cwt, fourier_factor

#: Default stick threshold as a fraction of |v_band|: |v_rel| below 1 % of the band speed.
#: Default relative margin for the resonance warning: |k f_band − f0| ≤ 5 % of f0.
RESONANCE_MARGIN = 0.05
#: Harmonics of the band fundamental checked for resonance (k = 1 … 3).
RESONANCE_HARMONICS = 3
#: Fewest outside-COI points needed to fit an envelope growth rate.
MIN_FIT_POINTS = 8


@dataclass(frozen=True)
class StickStats:
    """Stick phases of a relative-velocity record."""

    threshold_m_s: float
    share: float  # fraction of samples in stick, 0 … 1
    episodes: int  # number of separate stick runs
    longest_s: float  # longest stick run, s


def detect_stick(relative_velocity: Any, dt: float, threshold_m_s: float) -> StickStats:
    """Count stick runs (|v_rel| < threshold) and their share of the samples."""
    if not (math.isfinite(threshold_m_s) and threshold_m_s > 0.0):
        raise InputError(f"threshold_m_s={threshold_m_s!r} is not valid; expected > 0 m/s")
    v = check_signal(relative_velocity, "relative_velocity", min_length=1)
    stuck = np.abs(v) < threshold_m_s
    edges = np.diff(np.concatenate(([0], stuck.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = float((ends - starts).max() * dt) if starts.size else 0.0
    return StickStats(float(threshold_m_s), float(stuck.mean()), int(starts.size), longest)


def envelope_growth_rate(result: WaveletResult, frequency_hz: float) -> tuple[float | None, float | None]:
    """(rate in 1/s, R² of the fit) of log √power at the scale nearest frequency_hz.

    Uses only points outside the cone of influence; (None, None) when fewer than MIN_FIT_POINTS
    are available or the power vanishes.
    """
    j = int(np.argmin(np.abs(np.log(result.frequencies / frequency_hz))))
    mask = result.outside_coi[j] & (result.power[j] > 0.0)
    if mask.sum() < MIN_FIT_POINTS:
        return None, None
    t = result.time[mask]
    y = 0.5 * np.log(result.power[j, mask])
    slope, intercept = np.polyfit(t, y, 1)
    residual = y - (slope * t + intercept)
    spread = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(residual**2)) / spread if spread > 0.0 else 1.0
    return float(slope), r2


def signal_growth_rate(signal: Any, dt: float, frequency_hz: float) -> tuple[float | None, float | None]:
    """Envelope growth rate (1/s, R²) of a signal's component at frequency_hz (one-scale CWT)."""
    x = check_signal(signal)
    if not np.any(x - x.mean()):
        return None, None
    scale = 1.0 / (frequency_hz * fourier_factor())
    return envelope_growth_rate(cwt(x, dt, scales=np.array([scale])), frequency_hz)


def resonance_check(
    fundamental_hz: float,
    natural_hz: float,
    margin: float = RESONANCE_MARGIN,
    harmonics: int = RESONANCE_HARMONICS,
) -> tuple[bool, int | None, str]:
    """(warning, harmonic k, text): is some k f_band (k ≤ harmonics) within margin × f0 of f0."""
    if not (math.isfinite(fundamental_hz) and fundamental_hz > 0.0):
        raise InputError(f"fundamental_hz={fundamental_hz!r} is not valid; expected > 0 Hz")
    if not (0.0 < margin < 1.0):
        raise InputError(f"margin={margin!r} is not valid; expected a fraction in (0, 1)")
    best = min(range(1, harmonics + 1), key=lambda k: abs(k * fundamental_hz - natural_hz))
    distance = abs(best * fundamental_hz - natural_hz) / natural_hz
    name = "fundamental" if best == 1 else f"harmonic {best}"
    text = (
        f"band {name} {best * fundamental_hz:.3g} Hz is {100 * distance:.1f} % from the natural "
        f"frequency {natural_hz:.3g} Hz (margin {100 * margin:.0f} %)"
    )
    return distance <= margin, (best if distance <= margin else None), text


@dataclass(frozen=True)
class StabilityFlags:
    """Model verdict and signal observations at one moment; None where not computable."""

    band_velocity_m_s: float | None = None
    zone: int | None = None
    zone_name: str | None = None
    linear_stable: bool | None = None
    effective_damping: float | None = None
    critical_damping_ratio: float | None = None
    growth_rate_per_s: float | None = None
    growth_fit_r2: float | None = None
    oscillation: str = "unknown"  # 'growing', 'decaying', 'steady' or 'unknown'
    stick_threshold_m_s: float | None = None
    stick_share: float | None = None
    stick_episodes: int | None = None
    longest_stick_s: float | None = None
    resonance: bool | None = None
    resonance_harmonic: int | None = None
    resonance_detail: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary of every flag (JSON friendly)."""
        return asdict(self)


def evaluate_flags(
    rig: RigParameters,
    *,
    band_velocity: float | None = None,
    displacement: Any = None,
    relative_velocity: Any = None,
    dt: float | None = None,
    fundamental_hz: float | None = None,
    wavelet: WaveletResult | None = None,
    stick_threshold_m_s: float | None = None,
    resonance_margin: float = RESONANCE_MARGIN,
) -> StabilityFlags:
    """Combine the linear verdict with the observed envelope trend, stick and resonance.

    The growth rate comes from `wavelet` (a transform of the displacement) if given, else from
    `displacement` and `dt`. The oscillation is 'growing'/'decaying' when the fitted envelope
    changes by more than a factor 2 over the fitted span, else 'steady'. The stick threshold
    defaults to the friction-peak velocity (core.friction.stick_velocity); for a friction law
    without a peak there is no default, and the stick fields stay None unless one is given. The
    zone is None for such a law too; the linear verdict is still given.
    """
    values: dict[str, Any] = {}
    # A band at rest has no sliding equilibrium: no linear verdict and no default stick threshold.
    moving = band_velocity is not None and math.isfinite(band_velocity) and band_velocity != 0.0
    if band_velocity is not None:
        values["band_velocity_m_s"] = float(band_velocity)
    if moving and band_velocity is not None:  # (moving implies it; said again for the type checker)
        verdict = linear_stability(abs(float(band_velocity)), rig)
        values.update(
            zone=verdict.zone,
            zone_name=None if verdict.zone is None else ZONE_NAMES[verdict.zone],
            linear_stable=verdict.stable,
            effective_damping=verdict.effective_damping,
            critical_damping_ratio=verdict.critical_damping_ratio,
        )
    f0 = rig.natural_frequency
    rate = r2 = None
    span = None
    if wavelet is not None:
        rate, r2 = envelope_growth_rate(wavelet, f0)
        span = wavelet.time[-1] - wavelet.time[0]
    elif displacement is not None:
        if dt is None:
            raise InputError("dt is required with displacement (sample interval in s)")
        rate, r2 = signal_growth_rate(displacement, dt, f0)
        span = (np.asarray(displacement).size - 1) * dt
    if rate is not None and span:
        threshold = math.log(2.0) / span
        values["oscillation"] = (
            "growing" if rate > threshold else "decaying" if rate < -threshold else "steady"
        )
    values.update(growth_rate_per_s=rate, growth_fit_r2=r2)
    if relative_velocity is not None:
        if dt is None:
            raise InputError("dt is required with relative_velocity (sample interval in s)")
        threshold = stick_threshold_m_s
        if threshold is None:
            threshold = stick_velocity_or_none(rig.friction)  # None: the law has no peak
        if threshold is not None:
            stats = detect_stick(relative_velocity, dt, threshold)
            values.update(
                stick_threshold_m_s=stats.threshold_m_s,
                stick_share=stats.share,
                stick_episodes=stats.episodes,
                longest_stick_s=stats.longest_s,
            )
    if fundamental_hz is not None:
        warn, k, text = resonance_check(fundamental_hz, f0, resonance_margin)
        values.update(resonance=warn, resonance_harmonic=k, resonance_detail=text)
    return StabilityFlags(**values)
