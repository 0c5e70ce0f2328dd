"""The one wavelet-analysis policy and the one analysis function of a run's displacement.

Policy (WaveletPolicy, defaults in one place; docs/wavelets.md):

- signal: the displacement minus its mean over the analysed window;
- window: from `start_s` (s after the first sample) to the end; None = the stationary second
  half of the run, exactly the window of core.run.summarize (t >= t_end / 2; sweeps, `lubrig
  paper`); `lubrig analyze` and reports pass 0 (the whole record);
- scales: s0 2^(j dj), dj = 1/12, from fmax (default rate/4) down to fmin (default 3 / window
  length: at least three periods in the window);
- memory cap: scales × samples ≤ max_power_points (3·10⁷). With the default fmax the window
  is decimated (FIR anti-aliasing, zero phase) by the factor q the cap needs and fmax lowered
  to 0.8 × the decimated Nyquist frequency (0.4 / (q dt)); an explicit fmax is honoured: the
  window is decimated as far as it allows and, if that is not enough, only its last part kept;
- components: peaks of the time-mean power outside the cone of influence, strongest first,
  `n_components` of them, those below `min_relative_power` × the strongest dropped, labelled
  against the band fundamental.

analyze_displacement returns a WaveletAnalysis (transform, analysed series, components, what
was done and why); `.summary_section()` is the "wavelet" section of summary.json.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.signal import decimate

from ...core.errors import LubrigError
from ...core.wavelet import DEFAULT_DJ, MIN_SAMPLES, WaveletResult, cwt, fourier_factor
from ...core.wavelet_components import Component, dominant_components

#: Largest scales × samples computed; longer windows are decimated (anti-aliased) to fit.
MAX_POWER_POINTS = 30_000_000
#: Default highest frequency as a fraction of the sample rate (rate / 4).
FMAX_FRACTION = 0.25
#: Default lowest frequency: this many periods fit in the analysed window.
FMIN_PERIODS = 3.0
#: Decimation keeps fmax ≤ this fraction of the decimated sample rate (0.8 × Nyquist).
DECIMATED_FMAX_FRACTION = 0.4
SIGNAL = "displacement_m minus its mean"
POWER = "|W|^2 / variance (Torrence & Compo), time mean outside the cone of influence"


class AnalysisError(LubrigError, ValueError):
    """The window cannot be analysed (too short, constant, bad options); one user-facing line."""


@dataclass(frozen=True)
class WaveletPolicy:
    """How a displacement record is analysed; every default of the analysis is here."""

    start_s: float | None = None  # None: the second half, t >= t_end / 2 (summarize's window)
    dj: float = DEFAULT_DJ  # octaves between scales
    fmin_hz: float | None = None  # None: FMIN_PERIODS / window length
    fmax_hz: float | None = None  # None: FMAX_FRACTION × rate, lowered by decimation
    n_components: int = 5
    min_relative_power: float = 1e-4
    max_power_points: int = MAX_POWER_POINTS

    def __post_init__(self) -> None:
        def bad(name: str, value: object, what: str) -> AnalysisError:
            return AnalysisError(f"{name}={value!r} is not valid; expected {what}")

        if self.start_s is not None and not (math.isfinite(self.start_s) and self.start_s >= 0):
            raise bad("start", self.start_s, "a time >= 0 s")
        if not (math.isfinite(self.dj) and self.dj > 0):
            raise bad("dj", self.dj, "a scale step > 0 octaves")
        for name in ("fmin_hz", "fmax_hz"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise bad(name, value, "a frequency > 0 Hz")
        if (
            isinstance(self.n_components, bool)
            or int(self.n_components) != self.n_components
            or (self.n_components < 1)
        ):
            raise bad("n_components", self.n_components, "an integer >= 1")
        if not 0.0 <= self.min_relative_power < 1.0:
            raise bad("min_relative_power", self.min_relative_power, "a fraction in [0, 1)")
        if self.max_power_points < 1:
            raise bad("max_power_points", self.max_power_points, "at least 1 point")

    def start_for(self, duration_s: float) -> float:
        """The window start in s for a record of this duration."""
        return duration_s / 2.0 if self.start_s is None else float(self.start_s)


DEFAULT_POLICY = WaveletPolicy()


@dataclass(frozen=True)
class WaveletAnalysis:
    """Result of analyze_displacement: the transform, its components and what was done."""

    wavelet: WaveletResult  # transform of the analysed (demeaned, maybe decimated) window
    signal: np.ndarray  # that series, on wavelet.time (s, same clock as the input time)
    components: list[Component]  # strongest first
    policy: WaveletPolicy
    start_s: float  # requested window start after the first sample, s
    analysed_from_s: float  # where the analysed part begins after the first sample, s
    decimation: int  # factor q (1: none)
    note: str  # what the memory cap did, in words
    fundamental_hz: float | None
    flags: dict[str, bool] = field(default_factory=dict)  # decimated, shortened, significant

    def global_peak(self) -> tuple[float, float]:
        """(frequency Hz, power) of the global wavelet spectrum's maximum."""
        return self.wavelet.global_peak()

    def summary_section(self) -> dict[str, Any]:
        """The "wavelet" section of summary.json (JSON-ready)."""
        f_peak, p_peak = self.global_peak()
        return {
            "signal": SIGNAL,
            "start_s": self.start_s,
            "analysed_from_s": self.analysed_from_s,
            "dj": self.policy.dj,
            "fmin_hz": float(self.wavelet.frequencies.min()),
            "fmax_hz": float(self.wavelet.frequencies.max()),
            "decimation": self.decimation,
            "decimation_note": self.note,
            "min_relative_power": self.policy.min_relative_power,
            "lag1": self.wavelet.lag1,
            "power": POWER,
            "dominant_frequencies": [
                {
                    "frequency_hz": c.frequency_hz,
                    "power": c.power,
                    "label": c.label,
                    "harmonic": c.harmonic,
                    "amplitude_m": c.amplitude,
                    "significant": c.significant,
                }
                for c in self.components
            ],
            "global_peak": {"frequency_hz": f_peak, "power": p_peak},
            "flags": dict(self.flags),
        }


def _window(time: np.ndarray, x: np.ndarray, start: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    keep = time >= time[0] + start - 0.5 * dt if time.size else np.zeros(0, bool)
    return time[keep], x[keep]


def analyze_displacement(
    time: Any,
    displacement: Any,
    sample_rate: float,
    fundamental_hz: float | None = None,
    policy: WaveletPolicy = DEFAULT_POLICY,
) -> WaveletAnalysis:
    """Analyse displacement(time) (uniform at sample_rate) under the policy; see the module doc."""
    if not (isinstance(sample_rate, int | float) and math.isfinite(sample_rate) and sample_rate > 0):
        raise AnalysisError(f"sample_rate_hz={sample_rate!r} is not a rate > 0 Hz")
    time = np.asarray(time, dtype=float)
    displacement = np.asarray(displacement, dtype=float)
    if time.shape != displacement.shape or time.ndim != 1:
        raise AnalysisError(
            f"time {time.shape} and displacement {displacement.shape} must be 1-D of equal length"
        )
    dt = 1.0 / float(sample_rate)
    if policy.start_s is None and time.size:  # exactly summarize()'s stationary window
        keep = time >= time[-1] / 2.0
        t, x = time[keep], displacement[keep]
        start = float(time[-1] / 2.0 - time[0])
    else:
        start = policy.start_for(float(time[-1] - time[0]) if time.size else 0.0)
        t, x = _window(time, displacement, start, dt)
    if x.size < MIN_SAMPLES:
        raise AnalysisError(f"{x.size} samples after --start {start:g} s; at least {MIN_SAMPLES} are needed")
    if not np.isfinite(x).all():
        raise AnalysisError("displacement holds non-finite values in the analysed window")
    dj = policy.dj
    default_fmin, default_fmax = policy.fmin_hz is None, policy.fmax_hz is None
    fmax = FMAX_FRACTION / dt if policy.fmax_hz is None else policy.fmax_hz
    fmin = FMIN_PERIODS / (x.size * dt) if policy.fmin_hz is None else policy.fmin_hz
    if not 0 < fmin < fmax:
        raise AnalysisError(f"--fmin {fmin:g} Hz must be below --fmax {fmax:g} Hz")
    cap = policy.max_power_points
    n_scales = math.floor(math.log2(fmax / fmin) / dj) + 1
    factor = max(1, math.ceil(x.size * n_scales / cap))
    shortened = False
    if default_fmax:  # the cap chooses the decimation, fmax follows it down
        fmax = min(fmax, DECIMATED_FMAX_FRACTION / (dt * factor))
        note = f"scales × samples ≤ {cap} without decimation"
        if factor > 1:
            note = (
                f"decimated by {factor} to keep scales × samples ≤ {cap}; "
                f"fmax lowered to {fmax:g} Hz (0.8 × the decimated Nyquist frequency)"
            )
    else:  # an explicit fmax is honoured: decimate as far as it allows, then shorten
        allowed = max(1, int(DECIMATED_FMAX_FRACTION / (dt * fmax)))
        factor = min(factor, allowed)
        note = f"decimated by {factor} (--fmax {fmax:g} Hz allows at most {allowed})"
        limit = (cap // n_scales) * factor
        if x.size > limit:
            shortened = True
            left_out = float(t[x.size - limit] - t[0])
            t, x = t[-limit:], x[-limit:]
            if default_fmin:
                fmin = FMIN_PERIODS / (x.size * dt)
            note += (
                f"; only the last {x.size * dt:g} s analysed (the first {left_out:g} s after --start "
                f"left out) to keep scales × samples ≤ {cap}"
            )
        else:
            note += f"; scales × samples ≤ {cap}"
    if not 0 < fmin < fmax:
        raise AnalysisError(f"--fmin {fmin:g} Hz must be below fmax {fmax:g} Hz ({note})")
    n_scales = math.floor(math.log2(fmax / fmin) / dj) + 1
    x = x - x.mean()
    if not np.any(x):
        raise AnalysisError(
            "displacement is constant in the analysed window (variance 0); its normalized wavelet "
            "power is undefined"
        )
    if factor > 1:
        x, t = decimate(x, factor, ftype="fir", zero_phase=True), t[::factor]
    s0 = 1.0 / (fmax * fourier_factor())
    try:
        result = cwt(x, dt * factor, dj=dj, s0=s0, n_scales=n_scales, t0=float(t[0]))
    except ValueError as exc:
        raise AnalysisError(str(exc)) from None
    components = dominant_components(
        result, fundamental_hz, policy.n_components, min_relative_power=policy.min_relative_power
    )
    return WaveletAnalysis(
        wavelet=result,
        signal=x,
        components=components,
        policy=policy,
        start_s=start,
        analysed_from_s=float(t[0] - time[0]),
        decimation=factor,
        note=note,
        fundamental_hz=fundamental_hz,
        flags={
            "decimated": factor > 1,
            "shortened": shortened,
            "significant": any(c.significant for c in components),
        },
    )


def whole_record(policy: WaveletPolicy = DEFAULT_POLICY, **changes: Any) -> WaveletPolicy:
    """The policy with the window starting at the first sample (or at changes['start_s'])."""
    return replace(policy, **{"start_s": 0.0, **changes})
