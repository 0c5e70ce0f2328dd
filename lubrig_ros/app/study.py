"""The study's statements (model doc, section 8) as data, and the scorecard that checks them.

`case_metrics` measures one run (a Table 1 case or the constant-velocity stick-slip run) with the
criteria of core/criteria.py; `STATEMENTS` lists every statement of section 8 with its explicit
criterion; `scorecard` evaluates them all for one velocity coupling from the metrics of the ten
cases and the stick-slip run. The same functions serve the named conventions and the coupling
scan (s = γ · A / A_default), so a statement means the same thing everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core import criteria
from ..core.friction import friction_coefficient, friction_minimum, friction_peak, stick_velocity
from ..core.params import RigParameters
from ..core.presets import RunConfig
from ..core.profiles import RegularCycle
from ..core.stability import critical_damping_ratio, unstable_intervals
from ..core.trajectory import Trajectory

#: Damping ratios up to this count as "any (realistic) damping" in the stability statements.
REALISTIC_ZETA = 0.1
#: The 10 Hz component "disappears" when its amplitude stays below this fraction of its early
#: level (wavelet power below 1 % of it).
GONE_FRACTION = 0.1
#: Spectral peaks kept per run (strongest first) and their floor relative to the strongest.
PEAKS = 8
PEAK_FLOOR = 0.01
CASES = tuple(range(1, 11))
STICKSLIP = 0  # key of the constant-velocity (2e-8 m/s) stick-slip run among the metrics


def _finite(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def case_metrics(config: RunConfig, trajectory: Trajectory) -> dict[str, Any]:
    """Every number the statements need from one run (JSON-ready; None where not defined).

    Stationary measures use the second half of the run; the windowed amplitude uses one band
    period (one natural period for a constant band).
    """
    t, x = trajectory.time, trajectory.displacement
    half = t >= t[-1] / 2.0
    rig = config.rig
    f0 = rig.natural_frequency
    fundamental = config.band.fundamental_hz
    period = 1.0 / fundamental if fundamental else 1.0 / f0
    mu = trajectory.friction_coefficient
    peaks = criteria.spectral_peaks(x[half], config.sample_rate, count=PEAKS, floor=PEAK_FLOOR)
    tr = criteria.transient(t, x, period)
    out: dict[str, Any] = {
        "velocity_coupling": rig.velocity_factor,
        "coupling_strength": rig.coupling_strength,
        "x_peak_to_peak": float(np.ptp(x[half])),
        "mu_min": float(mu[half].min()),
        "mu_max": float(mu[half].max()),
        "stick_fraction": criteria.stick_fraction(
            trajectory.relative_velocity[half], stick_velocity(rig.friction)
        ),
        "peak_frequencies_hz": [f for f, _ in peaks],
        "peak_amplitudes": [a for _, a in peaks],
        "first_amplitude": tr.first,
        "stationary_amplitude": tr.stationary,
        "overshoot": _finite(tr.overshoot),
        "overshoot_time": tr.peak_time,
        "drift": _finite(tr.drift),
        "settling_time": _finite(tr.settling_time),
        "mu_band_r2": _finite(
            criteria.explained_fraction(
                mu[half], friction_coefficient(trajectory.band_velocity[half], rig.friction)
            )
        ),
        "f0_gone_time": _finite(criteria.disappearance_time(t, x - x.mean(), f0, fraction=GONE_FRACTION)),
    }
    centres, amplitude = criteria.component_amplitude(t, x - x.mean(), f0, window=1.0)
    after = centres >= 0.5
    reach = np.nonzero(after & (amplitude >= 0.3 * amplitude[after].max()))[0]
    stop = float(centres[reach[0]]) if reach.size and centres[reach[0]] > 1.5 else 5.0
    pick = after & (centres <= stop)
    out["f0_growth_rate"] = _finite(criteria.log_slope(centres[pick], amplitude[pick]))
    out["f0_amplitude_late"] = float(amplitude[centres >= t[-1] / 2.0].mean())
    band = config.band
    out.update(growth_v1=None, growth_v2=None, separation=None)
    if isinstance(band, RegularCycle):
        rates = {}
        for key, level in (("growth_v1", band.low_velocity), ("growth_v2", band.high_velocity)):
            found = criteria.plateau_growth_rates(
                t, x, trajectory.band_velocity, level, 1.0 / f0, start=t[-1] / 2.0
            )
            rates[key] = float(np.median(found)) if found else None
        out.update(rates)
        labels = np.where(
            np.isclose(trajectory.band_velocity, band.low_velocity, rtol=1e-9, atol=0.0),
            1,
            np.where(np.isclose(trajectory.band_velocity, band.high_velocity, rtol=1e-9, atol=0.0), 2, 0),
        )
        labels = np.where(half, labels, 0)
        if (labels == 1).sum() >= 4 and (labels == 2).sum() >= 4:
            out["separation"] = _finite(
                criteria.limit_cycle_separation(x, trajectory.velocity / rig.angular_frequency, labels, 1, 2)
            )
    return out


Metrics = dict[int, dict[str, Any]]


@dataclass(frozen=True)
class Statement:
    """One statement of the study, its explicit criterion and how to evaluate it."""

    key: str
    topic: str
    study: str  # the study's words, condensed
    criterion: str  # what lubrig_ros checks, with its thresholds
    evaluate: Callable[[Metrics, RigParameters], tuple[bool, str]]


@dataclass(frozen=True)
class Verdict:
    """A statement's outcome for one coupling."""

    key: str
    topic: str
    study: str
    criterion: str
    measured: str
    agree: bool


def _g(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}g}"


def _harmonics(m: dict[str, Any], fundamental: float, k: int) -> list[float]:
    return [f / fundamental for f in m["peak_frequencies_hz"][:k]]


def _peaks_text(m: dict[str, Any], k: int = 3) -> str:
    return ", ".join(f"{f:.3g}" for f in m["peak_frequencies_hz"][:k]) + " Hz"


def _top(m: dict[str, Any], k: int) -> list[float]:
    return list(m["peak_frequencies_hz"][:k])


def _grows_then_stationary(m: dict[str, Any]) -> bool:
    return m["first_amplitude"] < m["stationary_amplitude"] and (m["drift"] or math.inf) < 0.1


def _amplitude_text(m: dict[str, Any]) -> str:
    return (
        f"p-p first band period {_g(m['first_amplitude'])} m → stationary "
        f"{_g(m['stationary_amplitude'])} m (drift {_g(m['drift'], 2)})"
    )


def _mu_within(m: dict[str, Any], low: float, high: float) -> bool:
    return m["mu_min"] >= low and m["mu_max"] <= high


# --- statement checks -------------------------------------------------------------------------


def _friction_peak(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    peak = friction_peak(rig.friction)
    return (
        abs(peak.velocity / 4.1e-12 - 1) < 0.05 and 0.1 <= peak.mu <= 0.17,
        f"peak μ = {peak.mu:.3f} at {peak.velocity:.3g} m/s",
    )


def _friction_minimum(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    minimum = friction_minimum(rig.friction)
    return abs(minimum.velocity / 1.35e-7 - 1) < 0.03, f"μ = {minimum.mu:.4g} at {minimum.velocity:.3g} m/s"


def _friction_viscous(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    mu = [float(friction_coefficient(v, rig.friction)) for v in (1e-7, 2e-7, 1e-6)]
    ok = 6.48e-3 <= mu[0] <= 6.6e-3 and 6.48e-3 <= mu[1] <= 6.6e-3 and 8e-3 <= mu[2] <= 10.5e-3
    return ok, f"μ(1e-7, 2e-7, 1e-6 m/s) = {mu[0]:.4g}, {mu[1]:.4g}, {mu[2]:.3g}"


def _zones_stable(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    v = np.concatenate([np.logspace(-15, np.log10(4.0e-12), 30), np.logspace(np.log10(1.36e-7), -4, 60)])
    worst = float(np.max(critical_damping_ratio(v, rig)))
    return worst == 0.0, f"max ζ_crit below 4e-12 and above 1.35e-7 m/s = {worst:g}"


def _unstable_any_damping(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    inner = np.logspace(np.log10(4.2e-12), np.log10(2.5e-8), 200)
    low = float(np.min(critical_damping_ratio(inner, rig)))
    intervals = unstable_intervals(REALISTIC_ZETA, rig)
    edge = intervals[0][1] if intervals else math.nan
    ok = low >= REALISTIC_ZETA and 2.5e-8 <= edge < 3.5e-8
    return ok, (
        f"ζ_crit ≥ {low:.3g} over 4.2e-12 … 2.5e-8 m/s; at ζ = {REALISTIC_ZETA:g} unstable up to "
        f"{edge:.3g} m/s"
    )


def _stabilizable(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    v = np.logspace(np.log10(3.05e-8), np.log10(1.34e-7), 100)
    zc = critical_damping_ratio(v, rig)
    ok = bool(zc.min() > 0 and zc.max() <= 1.2 * REALISTIC_ZETA)
    at = float(critical_damping_ratio(1e-7, rig))
    return ok, f"ζ_crit {zc.min():.3g} … {zc.max():.3g} over 3e-8 … 1.35e-7 m/s; at V1 = 1e-7: {at:.3g}"


def _stickslip(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[STICKSLIP]
    return (
        m["stick_fraction"] > 0.3 and m["mu_max"] > 0.155,
        f"stick fraction {m['stick_fraction']:.2f}, μ max {m['mu_max']:.3f}, p-p {_g(m['x_peak_to_peak'])} m",
    )


def _case_grows(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        return _grows_then_stationary(m), _amplitude_text(m)

    return check


def _case_stationary(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        return (m["drift"] or math.inf) < 0.1, _amplitude_text(m)

    return check


def _case1_overshoot(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[1]
    ok = 0.5 <= m["overshoot_time"] <= 1.5 and (m["overshoot"] or 0) > 1.05
    return (
        ok,
        f"largest band-period p-p before 5 s at {m['overshoot_time']:.2f} s, "
        f"×{_g(m['overshoot'])} stationary",
    )


def _harmonic_set(n: int, wanted: list[int], k: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        f1 = FUNDAMENTALS[n]
        return criteria.matches(_top(m, k), [h * f1 for h in wanted]), "strongest " + _peaks_text(m, k)

    return check


def _case2_same_amplitude(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[2]["x_peak_to_peak"] / metrics[1]["x_peak_to_peak"]
    return 0.8 <= ratio <= 1.25, f"p-p case 2 / case 1 = {ratio:.2f}"


def _case3_plateaus(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        g1, g2 = m["growth_v1"], m["growth_v2"]
        ok = g1 is not None and g2 is not None and g1 > 0 > g2
        return ok, f"envelope rate on V1 plateaus {_g(g1)} /s, on V2 plateaus {_g(g2)} /s"

    return check


def _case3_spectrum(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[3]
    inside = [f for f in m["peak_frequencies_hz"] if 0.8 <= f <= 10.5]
    ok = (
        bool(m["peak_frequencies_hz"])
        and criteria.near(m["peak_frequencies_hz"][0], 10.0)
        and len(inside) >= 4
    )
    return ok, f"strongest {_peaks_text(m, 4)}; {len(inside)} peaks in 0.8–10.5 Hz"


def _case4_spectrum(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[4]
    f1 = FUNDAMENTALS[4]
    top = m["peak_frequencies_hz"]
    ok = (
        bool(top)
        and criteria.near(top[0], f1)
        and all(any(criteria.near(f, h * f1) for f in top[1:5]) for h in (2, 3))
    )
    return ok, f"strongest {_peaks_text(m, 4)}"


def _case5_larger(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m5, m2 = metrics[5], metrics[2]
    ok = _grows_then_stationary(m5) and m5["x_peak_to_peak"] > m2["x_peak_to_peak"]
    return (
        ok,
        f"{_amplitude_text(m5)}; p-p case 5 / case 2 = {m5['x_peak_to_peak'] / m2['x_peak_to_peak']:.2f}",
    )


def _case6_separated(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    sep = metrics[6]["separation"]
    return sep is not None and sep > 1.0, f"V1/V2-plateau orbits: centre distance / (r1 + r2) = {_g(sep)}"


def _case6_larger(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[6]["x_peak_to_peak"] / metrics[3]["x_peak_to_peak"]
    return ratio > 1.0, f"p-p case 6 / case 3 = {ratio:.2f}"


def _case6_rich(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[6]
    inside = [f for f in m["peak_frequencies_hz"] if 0.8 <= f <= 10.5]
    return len(
        inside
    ) >= 5, f"{len(inside)} of the {len(m['peak_frequencies_hz'])} strongest peaks in 0.8–10.5 Hz"


def _case7_mono(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[7]
    f, a = m["peak_frequencies_hz"], m["peak_amplitudes"]
    second = a[1] / a[0] if len(a) > 1 else 0.0
    ok = bool(f) and criteria.near(f[0], 10.0) and second < 0.1
    return ok, f"strongest {_peaks_text(m, 2)}; second/first amplitude {second:.2g}"


def _case7_ratio(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[7]["x_peak_to_peak"] / metrics[5]["x_peak_to_peak"]
    return 6.0 <= ratio <= 10.0, f"p-p case 7 / case 5 = {ratio:.3g}"


def _case8_stickslip(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    ok = m["stick_fraction"] >= 0.05 and (m["drift"] or math.inf) < 0.25
    return ok, f"stick fraction {m['stick_fraction']:.2f}; drift {_g(m['drift'], 2)}"


def _case8_frequencies(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    return criteria.matches(_top(m, 2), [10.0, 20.0]), "strongest " + _peaks_text(m, 3)


def _case8_mu(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    ok = 5e-3 <= m["mu_min"] <= 7.5e-3 and 0.1 <= m["mu_max"] <= 0.17
    return ok, f"μ {m['mu_min']:.3g} … {m['mu_max']:.3g}"


def _fast_decay(n: int, compare: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m, c = metrics[n], metrics[compare]
        decreases = m["first_amplitude"] > 2.0 * m["stationary_amplitude"]
        settle = m["settling_time"]
        ratio = m["x_peak_to_peak"] / c["x_peak_to_peak"]
        ok = decreases and settle is not None and settle <= 3.0 and ratio < 0.5
        return ok, (
            f"first band period p-p / stationary = {m['first_amplitude'] / m['stationary_amplitude']:.3g}, "
            f"settled (within ×2 of stationary) at {_g(settle)} s; p-p / case {compare} = {ratio:.2g}"
        )

    return check


def _gone(n: int, when: float) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        gone = metrics[n]["f0_gone_time"]
        ok = gone is not None and 0.5 * when <= gone <= 2.0 * when
        return ok, f"10 Hz amplitude below {GONE_FRACTION:g} × its early level from {_g(gone)} s"

    return check


def _case9_only33(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[9]
    f, a = m["peak_frequencies_hz"], m["peak_amplitudes"]
    ok = bool(f) and criteria.near(f[0], FUNDAMENTALS[9]) and all(x < 0.3 * a[0] for x in a[1:])
    second = a[1] / a[0] if len(a) > 1 else 0.0
    return ok, f"strongest {_peaks_text(m, 3)}; second/first amplitude {second:.2g}"


def _case10_33_66(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[10]
    f1 = FUNDAMENTALS[10]
    return criteria.matches(_top(m, 2), [f1, 2 * f1]), "strongest " + _peaks_text(m, 3)


def _mu_range(
    cases: tuple[int, ...], low: float, high: float
) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        bad = [n for n in cases if not _mu_within(metrics[n], low, high)]
        lo = min(metrics[n]["mu_min"] for n in cases)
        hi = max(metrics[n]["mu_max"] for n in cases)
        return not bad, f"μ over cases {lo:.4g} … {hi:.4g}" + (f"; outside: cases {bad}" if bad else "")

    return check


def _mu_follows(cases: tuple[int, ...], band: bool) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        r2 = {n: metrics[n]["mu_band_r2"] for n in cases}
        bad = [n for n, r in r2.items() if r is None or ((r >= 0.9) != band)]
        text = ", ".join(f"{n}: {_g(r, 2)}" for n, r in r2.items())
        return not bad, f"R² of μ by μ(v_band): {text}"

    return check


FUNDAMENTALS = {
    1: 1 / 0.21,
    2: 1 / 0.3,
    3: 1 / 1.2,
    4: 1 / 0.21,
    5: 1 / 0.3,
    6: 1 / 1.2,
    7: 10.0,
    8: 20.0,
    9: 1 / 0.03,
    10: 1 / 0.03,
}

STATEMENTS: tuple[Statement, ...] = (
    Statement(
        "F1",
        "friction curve",
        "static-like friction around 0.1 below 4.1e-12 m/s (peak)",
        "peak at 4.1e-12 m/s ± 5 %, μ 0.1 … 0.17",
        _friction_peak,
    ),
    Statement(
        "F2",
        "friction curve",
        "decreasing until 1.35e-7 m/s",
        "minimum at 1.35e-7 m/s ± 3 %",
        _friction_minimum,
    ),
    Statement(
        "F3",
        "friction curve",
        "viscous and rising above: μ 6.5e-3 … 6.6e-3 over 1e-7 … 2e-7, ~10e-3 at 1e-6",
        "μ(1e-7), μ(2e-7) in [6.48e-3, 6.6e-3]; μ(1e-6) in [8e-3, 10.5e-3]",
        _friction_viscous,
    ),
    Statement(
        "S1",
        "stability",
        "naturally stable where dμ/dv > 0 (below 4e-12, above 1.35e-7 up to 1e-4 m/s)",
        "ζ_crit = 0 there",
        _zones_stable,
    ),
    Statement(
        "S2",
        "stability",
        "unstable whatever the damping between 4e-12 and 3e-8 m/s; edge at 3e-8",
        f"ζ_crit ≥ {REALISTIC_ZETA:g} (realistic damping) over 4.2e-12 … 2.5e-8 m/s, and the unstable "
        f"interval at ζ = {REALISTIC_ZETA:g} ends at 3e-8 to the printed digit ([2.5e-8, 3.5e-8))",
        _unstable_any_damping,
    ),
    Statement(
        "S3",
        "stability",
        "stabilizable by enough damping between 3e-8 and 1.35e-7 m/s",
        f"0 < ζ_crit ≤ {1.2 * REALISTIC_ZETA:g} over 3.05e-8 … 1.34e-7 m/s",
        _stabilizable,
    ),
    Statement(
        "S4",
        "stick-slip",
        "constant band velocity 2e-8 m/s gives stick-slip (Fig. 6)",
        "stick fraction > 0.3 and μ max > 0.155 over the second half",
        _stickslip,
    ),
    Statement(
        "C1a",
        "case 1",
        "amplitude grows, then stationary",
        "band-period p-p: first < stationary (last quarter); 3rd/4th quarter drift < 10 %",
        _case_grows(1),
    ),
    Statement(
        "C1b",
        "case 1",
        "overshoot in the transient between 0.5 and 1.5 s",
        "largest band-period p-p before 5 s centred in 0.5 … 1.5 s and > 1.05 × stationary",
        _case1_overshoot,
    ),
    Statement(
        "C1c",
        "case 1",
        "4.76 Hz and 9.52 Hz (2nd harmonic)",
        "two strongest peaks = 1st and 2nd harmonic of 4.76 Hz",
        _harmonic_set(1, [1, 2], 2),
    ),
    Statement(
        "C2a",
        "case 2",
        "like case 1, identical amplitude levels",
        "grows then stationary; p-p case 2 / case 1 in [0.8, 1.25]",
        lambda m, r: (
            _case_grows(2)(m, r)[0] and _case2_same_amplitude(m, r)[0],
            _case2_same_amplitude(m, r)[1] + "; " + _amplitude_text(m[2]),
        ),
    ),
    Statement(
        "C2b",
        "case 2",
        "3.33, 6.66 and 9.99 Hz",
        "three strongest peaks = harmonics 1, 2, 3 of 3.33 Hz",
        _harmonic_set(2, [1, 2, 3], 3),
    ),
    Statement(
        "C3a",
        "case 3",
        "grows on the V1 = 1e-7 plateau (unstable), decays on V2 = 2e-7 (stable)",
        "median envelope rate > 0 on V1 plateaus and < 0 on V2 plateaus (second half)",
        _case3_plateaus(3),
    ),
    Statement(
        "C3b",
        "case 3",
        "multiple frequencies in 1–10 Hz, predominant 10 Hz (12th harmonic)",
        "strongest peak 10 Hz; ≥ 4 of the strongest peaks in 0.8–10.5 Hz",
        _case3_spectrum,
    ),
    Statement(
        "C4a",
        "case 4",
        "like case 1 apart from transient and amplitude",
        "stationary: 3rd/4th quarter drift of the band-period p-p < 10 % (the transient is excepted)",
        _case_stationary(4),
    ),
    Statement(
        "C4b",
        "case 4",
        "predominant 4.76 Hz, small 9.52 and 14.28 Hz",
        "strongest peak 4.76 Hz; 2nd and 3rd harmonics among the next four",
        _case4_spectrum,
    ),
    Statement(
        "C5a",
        "case 5",
        "grows like case 2, larger amplitudes",
        "grows then stationary; p-p > case 2",
        _case5_larger,
    ),
    Statement(
        "C5b",
        "case 5",
        "predominant 3.33 Hz and 9.99 Hz (3rd harmonic)",
        "two strongest peaks = 1st and 3rd harmonic of 3.33 Hz",
        _harmonic_set(5, [1, 3], 2),
    ),
    Statement(
        "C6a",
        "case 6",
        "two limit cycles clearly separated in the phase plot",
        "orbits on V1 and V2 plateaus in (x, ẋ/ω0): centre distance > r1 + r2 (95 % radii)",
        _case6_separated,
    ),
    Statement(
        "C6b",
        "case 6",
        "a vibration grows on one limit cycle and decays on the other",
        "median envelope rate > 0 on V1 plateaus and < 0 on V2 plateaus",
        _case3_plateaus(6),
    ),
    Statement("C6c", "case 6", "larger amplitude (than case 3)", "p-p case 6 > case 3", _case6_larger),
    Statement(
        "C6d",
        "case 6",
        "very rich content between 0.8 and 10 Hz",
        "≥ 5 of the 8 strongest peaks in 0.8–10.5 Hz",
        _case6_rich,
    ),
    Statement(
        "C7a", "case 7", "the displacement grows until periodic", "grows then stationary", _case_grows(7)
    ),
    Statement(
        "C7b", "case 7", "mono-harmonic at 10 Hz", "strongest peak 10 Hz, second < 10 % of it", _case7_mono
    ),
    Statement(
        "C7c",
        "case 7",
        "magnitudes eight times those of case 5",
        "p-p case 7 / case 5 in [6, 10]",
        _case7_ratio,
    ),
    Statement(
        "C8a",
        "case 8",
        "stationary quasi-periodic vibration governed by stick-slip",
        "stick fraction ≥ 0.05 (second half); drift < 25 %",
        _case8_stickslip,
    ),
    Statement(
        "C8b",
        "case 8",
        "two predominant frequencies, 10 Hz and 20 Hz",
        "two strongest peaks 10 and 20 Hz",
        _case8_frequencies,
    ),
    Statement(
        "C8c",
        "case 8",
        "μ fluctuates strongly between 6.5e-3 and 0.16",
        "μ min in [5e-3, 7.5e-3], μ max in [0.1, 0.17]",
        _case8_mu,
    ),
    Statement(
        "C9a",
        "case 9",
        "very fast decrease of the transient, small residual (compare case 2)",
        "first band-period p-p > 2 × stationary, settled by 3 s, p-p < 0.5 × case 2",
        _fast_decay(9, 2),
    ),
    Statement(
        "C9b",
        "case 9",
        "the 10 Hz component disappears after about 10 s",
        f"10 Hz amplitude below {GONE_FRACTION:g} × early level from a time in 5 … 20 s",
        _gone(9, 10.0),
    ),
    Statement(
        "C9c",
        "case 9",
        "only 33 Hz remains",
        "strongest 33.3 Hz, every other peak < 30 % of it",
        _case9_only33,
    ),
    Statement(
        "C10a",
        "case 10",
        "very fast decrease of the transient, small residual (compare case 5)",
        "first band-period p-p > 2 × stationary, settled by 3 s, p-p < 0.5 × case 5",
        _fast_decay(10, 5),
    ),
    Statement(
        "C10b",
        "case 10",
        "the 10 Hz component disappears after about 5 s",
        f"10 Hz amplitude below {GONE_FRACTION:g} × early level from a time in 2.5 … 10 s",
        _gone(10, 5.0),
    ),
    Statement(
        "C10c", "case 10", "33 Hz and 66 Hz remain", "two strongest peaks 33.3 and 66.7 Hz", _case10_33_66
    ),
    Statement(
        "M1",
        "μ over time",
        "within [6.5e-3, 6.6e-3] for cases 1, 2, 3, 9",
        "μ in [6.48e-3, 6.6e-3] over the second half (6.486e-3 is the curve's minimum)",
        _mu_range((1, 2, 3, 9), 6.48e-3, 6.6e-3),
    ),
    Statement(
        "M2",
        "μ over time",
        "within [6e-3, 10e-3] for cases 4–7 and 10",
        "μ in [6e-3, 10e-3]",
        _mu_range((4, 5, 6, 7, 10), 6e-3, 10e-3),
    ),
    Statement(
        "M3",
        "μ over time",
        "μ mainly follows the band velocity for cases 4–7, 9, 10",
        "μ(v_band) explains ≥ 90 % of μ's variance (R² ≥ 0.9)",
        _mu_follows((4, 5, 6, 7, 9, 10), True),
    ),
    Statement(
        "M4",
        "μ over time",
        "for cases 1–3 μ also follows the mass velocity",
        "R² of μ by μ(v_band) < 0.9",
        _mu_follows((1, 2, 3), False),
    ),
)


def scorecard(metrics: Metrics, rig: RigParameters) -> list[Verdict]:
    """Every statement's verdict from the metrics of cases 1–10 and the stick-slip run (key 0).

    `rig` carries the coupling for the stability statements (its damping is the study's 0.01).
    """
    verdicts = []
    for s in STATEMENTS:
        agree, measured = s.evaluate(metrics, rig)
        verdicts.append(Verdict(s.key, s.topic, s.study, s.criterion, measured, bool(agree)))
    return verdicts


def rig_with_coupling(rig: RigParameters, coupling: str | float) -> RigParameters:
    """The rig with a named convention or an explicit γ."""
    return replace(rig, velocity_coupling=coupling)


def study_configs(coupling: str | float, duration: float = 20.0) -> dict[int, RunConfig]:
    """The ten Table 1 cases (1–10) and the 2e-8 m/s stick-slip run (key 0) with this coupling."""
    from ..core.presets import config_dir, load_case, load_config

    configs = {STICKSLIP: load_config(config_dir() / "stickslip.yaml")}
    configs.update({n: load_case(n) for n in CASES})
    return {n: c.with_overrides(velocity_coupling=coupling, duration=duration) for n, c in configs.items()}


def measure(coupling: str | float, duration: float = 20.0) -> Metrics:
    """Simulate every study run with this coupling and return their metrics."""
    from ..core.run import simulate

    return {n: case_metrics(c, simulate(c)) for n, c in study_configs(coupling, duration).items()}


# --- coupling scan table (one row per coupling s and run; committed under docs/study/) ------------

#: Metric columns of the scan table, in order; list-valued ones are written space-separated.
SCAN_LISTS = ("peak_frequencies_hz", "peak_amplitudes")


def scan_rows(scan: dict[float, Metrics]) -> list[dict[str, Any]]:
    """Flat rows (s, case, metrics…) of a scan {s: {case: metrics}}; case 0 is the stick-slip run."""
    rows = []
    for s in sorted(scan):
        for case in sorted(scan[s]):
            rows.append({"s": s, "case": case, **scan[s][case]})
    return rows


def write_scan_csv(path: Any, scan: dict[float, Metrics]) -> None:
    """Write the scan table as CSV (repr-exact floats, empty for None, lists space-separated)."""
    import csv
    from pathlib import Path

    rows = scan_rows(scan)
    if not rows:
        raise ValueError("the scan holds no rows")
    columns = list(rows[0])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in rows:
            cells = []
            for key in columns:
                value = row.get(key)
                if key in SCAN_LISTS:
                    cells.append(" ".join(repr(float(v)) for v in value or ()))
                elif value is None:
                    cells.append("")
                else:
                    cells.append(repr(value))
            writer.writerow(cells)
    tmp.replace(path)


def read_scan_csv(path: Any) -> dict[float, Metrics]:
    """Read a table written by write_scan_csv back into {s: {case: metrics}}."""
    import csv
    from pathlib import Path

    scan: dict[float, Metrics] = {}
    with Path(path).open(newline="") as handle:
        for row in csv.DictReader(handle):
            s, case = float(row.pop("s")), int(row.pop("case"))
            metrics: dict[str, Any] = {}
            for key, text in row.items():
                if key in SCAN_LISTS:
                    metrics[key] = [float(v) for v in text.split()]
                else:
                    metrics[key] = float(text) if text != "" else None
            scan.setdefault(s, {})[case] = metrics
    return scan


def transitions(scan: dict[float, Metrics]) -> list[tuple[float, float]]:
    """Neighbouring couplings (s_lo, s_hi) of the scan between which some verdict changes."""
    from ..core.params import RigParameters

    values = sorted(scan)
    agreed = [
        frozenset(v.key for v in scorecard(scan[s], rig_with_coupling(RigParameters(), s)) if v.agree)
        for s in values
    ]
    return [(values[i], values[i + 1]) for i in range(len(values) - 1) if agreed[i] != agreed[i + 1]]
