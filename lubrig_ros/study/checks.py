"""The criteria of the study's statements: one function per check, (metrics, rig) -> (agrees, measured).

Each check reads the metrics of study/runs.py (`Metrics`: run key -> numbers) and, for the
friction-curve and stability statements, the rig with its velocity coupling; it returns whether
the statement holds and what was measured, in words. study/statements.py pairs them with the study's
words in `STATEMENTS`.
"""

# ruff: noqa: D103  (each check is described by its statement's criterion in study/statements.py STATEMENTS)
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core import criteria
from ..core.friction import friction_coefficient, friction_minimum, friction_peak
from ..core.params import RigParameters
from ..core.stability import critical_damping_ratio, unstable_intervals
from .runs import GONE_FRACTION, GONE_FRACTIONS, REALISTIC_ZETA, STICKSLIP, Metrics

#: "Identical amplitude levels" (C2a): the ratio within [1/(1 + t), 1 + t]; chosen t and the
#: reasonable range of t over which the page shows the verdict.
SAME_TOLERANCE, SAME_TOLERANCES = 0.25, (0.2, 0.3)
#: "Disappears after about N s" (C9b, C10b): N of each case, and the window [0.5 N, 2 N] a
#: disappearance time must fall in to count as "about N s".
GONE_AFTER_S: dict[int, float] = {9: 10.0, 10: 5.0}
ABOUT_WINDOW = (0.5, 2.0)


def about(time: float | None, when: float) -> bool:
    """Whether a time (s) is "about `when`" (ABOUT_WINDOW)."""
    return (
        time is not None and math.isfinite(time) and ABOUT_WINDOW[0] * when <= time <= ABOUT_WINDOW[1] * when
    )


def about_text(when: float) -> str:
    """The ABOUT_WINDOW around `when` as text: "2.5 … 10 s"."""
    return f"{ABOUT_WINDOW[0] * when:g} … {ABOUT_WINDOW[1] * when:g} s"


def _g(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}g}"


def _peaks_text(m: dict[str, Any], k: int = 3) -> str:
    return ", ".join(f"{f:.3g}" for f in m["peak_frequencies_hz"][:k]) + " Hz"


def _top(m: dict[str, Any], k: int) -> list[float]:
    return list(m["peak_frequencies_hz"][:k])


def _grows_then_stationary(m: dict[str, Any]) -> bool:
    return m["first_amplitude"] < m["stationary_amplitude"] and (m["drift"] or math.inf) < 0.1


def amplitude_text(m: dict[str, Any]) -> str:
    return (
        f"p-p first band period {_g(m['first_amplitude'])} m → stationary "
        f"{_g(m['stationary_amplitude'])} m (drift {_g(m['drift'], 2)})"
    )


def mu_bounds(m: dict[str, Any]) -> tuple[float, float]:
    """μ's extremes over the second half between samples (core/dense.py), else the sampled ones."""
    low, high = m.get("mu_min_dense"), m.get("mu_max_dense")
    return (m["mu_min"] if low is None else low, m["mu_max"] if high is None else high)


def _mu_within(m: dict[str, Any], low: float, high: float) -> bool:
    lo, hi = mu_bounds(m)
    return lo >= low and hi <= high


def mu_text(m: dict[str, Any]) -> str:
    lo, hi = mu_bounds(m)
    dense = m.get("mu_max_dense") is not None
    head = f"μ {lo:.3g} … {hi:.3g}" + (" between samples" if dense else " (sampled)")
    return head + (f" (sampled at 1 kHz {m['mu_min']:.3g} … {m['mu_max']:.3g})" if dense else "")


# --- statement checks -------------------------------------------------------------------------


def friction_curve_peak(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    peak = friction_peak(rig.friction)
    return (
        abs(peak.velocity / 4.1e-12 - 1) < 0.05 and 0.1 <= peak.mu <= 0.17,
        f"peak μ = {peak.mu:.3f} at {peak.velocity:.3g} m/s",
    )


def friction_curve_minimum(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    minimum = friction_minimum(rig.friction)
    return abs(minimum.velocity / 1.35e-7 - 1) < 0.03, f"μ = {minimum.mu:.4g} at {minimum.velocity:.3g} m/s"


def friction_curve_viscous(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    mu = [float(friction_coefficient(v, rig.friction)) for v in (1e-7, 2e-7, 1e-6)]
    ok = 6.48e-3 <= mu[0] <= 6.6e-3 and 6.48e-3 <= mu[1] <= 6.6e-3 and 8e-3 <= mu[2] <= 10.5e-3
    return ok, f"μ(1e-7, 2e-7, 1e-6 m/s) = {mu[0]:.4g}, {mu[1]:.4g}, {mu[2]:.3g}"


def zones_stable(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    v = np.concatenate([np.logspace(-15, np.log10(4.0e-12), 30), np.logspace(np.log10(1.36e-7), -4, 60)])
    worst = float(np.max(critical_damping_ratio(v, rig)))
    return worst == 0.0, f"max ζ_crit below 4e-12 and above 1.35e-7 m/s = {worst:g}"


def unstable_any_damping(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    inner = np.logspace(np.log10(4.2e-12), np.log10(2.5e-8), 200)
    low = float(np.min(critical_damping_ratio(inner, rig)))
    intervals = unstable_intervals(REALISTIC_ZETA, rig)
    edge = intervals[0][1] if intervals else math.nan
    ok = low >= REALISTIC_ZETA and 2.5e-8 <= edge < 3.5e-8
    return ok, (
        f"ζ_crit ≥ {low:.3g} over 4.2e-12 … 2.5e-8 m/s; at ζ = {REALISTIC_ZETA:g} unstable up to "
        f"{edge:.3g} m/s"
    )


def stabilizable(_: Metrics, rig: RigParameters) -> tuple[bool, str]:
    v = np.logspace(np.log10(3.05e-8), np.log10(1.34e-7), 100)
    zc = critical_damping_ratio(v, rig)
    ok = bool(zc.min() > 0 and zc.max() <= 1.2 * REALISTIC_ZETA)
    at = float(critical_damping_ratio(1e-7, rig))
    return ok, f"ζ_crit {zc.min():.3g} … {zc.max():.3g} over 3e-8 … 1.35e-7 m/s; at V1 = 1e-7: {at:.3g}"


def stickslip(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[STICKSLIP]
    high = mu_bounds(m)[1]
    return (
        m["stick_fraction"] > 0.3 and high > 0.155,
        f"stick fraction {m['stick_fraction']:.2f}, μ max {high:.3f} (sampled {m['mu_max']:.3f}), "
        f"p-p {_g(m['x_peak_to_peak'])} m",
    )


def case_grows(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        return _grows_then_stationary(m), amplitude_text(m)

    return check


def case_stationary(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        return (m["drift"] or math.inf) < 0.1, amplitude_text(m)

    return check


def case1_overshoot(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[1]
    ok = 0.5 <= m["overshoot_time"] <= 1.5 and (m["overshoot"] or 0) > 1.05
    return (
        ok,
        f"largest band-period p-p before 5 s at {m['overshoot_time']:.2f} s, "
        f"×{_g(m['overshoot'])} stationary",
    )


def harmonic_set(n: int, wanted: list[int], k: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        f1 = FUNDAMENTALS[n]
        return criteria.matches(_top(m, k), [h * f1 for h in wanted]), "strongest " + _peaks_text(m, k)

    return check


def case2_same_amplitude(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[2]["x_peak_to_peak"] / metrics[1]["x_peak_to_peak"]
    needed = max(ratio, 1.0 / ratio) - 1.0  # the smallest tolerance t for which it holds
    lo, hi = SAME_TOLERANCES
    if needed <= lo:
        over = f"holds over the whole reasonable range t = {lo:.0%} … {hi:.0%}"
    elif needed > hi:
        over = f"differs over the whole reasonable range t = {lo:.0%} … {hi:.0%}"
    else:
        over = f"holds for t ≥ {needed:.2%} only, within the reasonable {lo:.0%} … {hi:.0%}: marginal"
    return needed <= SAME_TOLERANCE, f"p-p case 2 / case 1 = {ratio:.4f} ({over})"


def case3_plateaus(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        g1, g2 = m["growth_v1"], m["growth_v2"]
        ok = g1 is not None and g2 is not None and g1 > 0 > g2
        return ok, f"envelope rate on V1 plateaus {_g(g1)} /s, on V2 plateaus {_g(g2)} /s"

    return check


def case3_spectrum(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[3]
    inside = [f for f in m["peak_frequencies_hz"] if 0.8 <= f <= 10.5]
    ok = (
        bool(m["peak_frequencies_hz"])
        and criteria.near(m["peak_frequencies_hz"][0], 10.0)
        and len(inside) >= 4
    )
    return ok, f"strongest {_peaks_text(m, 4)}; {len(inside)} peaks in 0.8–10.5 Hz"


def case4_spectrum(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[4]
    f1 = FUNDAMENTALS[4]
    top = m["peak_frequencies_hz"]
    ok = (
        bool(top)
        and criteria.near(top[0], f1)
        and all(any(criteria.near(f, h * f1) for f in top[1:5]) for h in (2, 3))
    )
    return ok, f"strongest {_peaks_text(m, 4)}"


def case5_larger(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m5, m2 = metrics[5], metrics[2]
    ok = _grows_then_stationary(m5) and m5["x_peak_to_peak"] > m2["x_peak_to_peak"]
    return (
        ok,
        f"{amplitude_text(m5)}; p-p case 5 / case 2 = {m5['x_peak_to_peak'] / m2['x_peak_to_peak']:.2f}",
    )


def case6_separated(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    sep = metrics[6]["separation"]
    return sep is not None and sep > 1.0, f"V1/V2-plateau orbits: centre distance / (r1 + r2) = {_g(sep)}"


def case6_larger(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[6]["x_peak_to_peak"] / metrics[3]["x_peak_to_peak"]
    return ratio > 1.0, f"p-p case 6 / case 3 = {ratio:.2f}"


def case6_rich(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[6]
    inside = [f for f in m["peak_frequencies_hz"] if 0.8 <= f <= 10.5]
    return len(
        inside
    ) >= 5, f"{len(inside)} of the {len(m['peak_frequencies_hz'])} strongest peaks in 0.8–10.5 Hz"


def case7_mono(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[7]
    f, a = m["peak_frequencies_hz"], m["peak_amplitudes"]
    second = a[1] / a[0] if len(a) > 1 else 0.0
    ok = bool(f) and criteria.near(f[0], 10.0) and second < 0.1
    return ok, f"strongest {_peaks_text(m, 2)}; second/first amplitude {second:.2g}"


def case7_ratio(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    ratio = metrics[7]["x_peak_to_peak"] / metrics[5]["x_peak_to_peak"]
    return 6.0 <= ratio <= 10.0, f"p-p case 7 / case 5 = {ratio:.3g}"


def case8_stickslip(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    ok = m["stick_fraction"] >= 0.05 and (m["drift"] or math.inf) < 0.25
    return ok, f"stick fraction {m['stick_fraction']:.2f}; drift {_g(m['drift'], 2)}"


def case8_frequencies(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    return criteria.matches(_top(m, 2), [10.0, 20.0]), "strongest " + _peaks_text(m, 3)


def case8_mu(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[8]
    lo, hi = mu_bounds(m)
    ok = 5e-3 <= lo <= 7.5e-3 and 0.1 <= hi <= 0.17
    return ok, mu_text(m)


def fast_decay(n: int, compare: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
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


def gone(n: int) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    when = GONE_AFTER_S[n]

    def inside(time: float | None) -> bool:
        return about(time, when)

    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        m = metrics[n]
        gone = m["f0_gone_time"]
        text = f"10 Hz amplitude below {GONE_FRACTION:g} × its early level from {_g(gone)} s"
        times = m.get("f0_gone_times")
        if times:
            holds = [f for f, time in zip(GONE_FRACTIONS, times, strict=True) if inside(time)]
            each = ", ".join(f"{f:g}: {_g(time)} s" for f, time in zip(GONE_FRACTIONS, times, strict=True))
            verdict = (
                "holds at every reference level"
                if len(holds) == len(GONE_FRACTIONS)
                else "holds at none"
                if not holds
                else "holds at " + ", ".join(f"{f:g}" for f in holds) + " only"
            )
            text += (
                f"; per reference level {each} ({verdict} of {GONE_FRACTIONS[0]:g} … {GONE_FRACTIONS[-1]:g})"
            )
        return inside(gone), text

    return check


def case9_only33(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[9]
    f, a = m["peak_frequencies_hz"], m["peak_amplitudes"]
    ok = bool(f) and criteria.near(f[0], FUNDAMENTALS[9]) and all(x < 0.3 * a[0] for x in a[1:])
    second = a[1] / a[0] if len(a) > 1 else 0.0
    return ok, f"strongest {_peaks_text(m, 3)}; second/first amplitude {second:.2g}"


def case10_33_66(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
    m = metrics[10]
    f1 = FUNDAMENTALS[10]
    return criteria.matches(_top(m, 2), [f1, 2 * f1]), "strongest " + _peaks_text(m, 3)


def mu_range(
    cases: tuple[int, ...], low: float, high: float
) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
    def check(metrics: Metrics, _: RigParameters) -> tuple[bool, str]:
        bad = [n for n in cases if not _mu_within(metrics[n], low, high)]
        lo = min(mu_bounds(metrics[n])[0] for n in cases)
        hi = max(mu_bounds(metrics[n])[1] for n in cases)
        sampled = (min(metrics[n]["mu_min"] for n in cases), max(metrics[n]["mu_max"] for n in cases))
        return not bad, (
            f"μ over cases {lo:.4g} … {hi:.4g} between samples (sampled {sampled[0]:.4g} … {sampled[1]:.4g})"
            + (f"; outside: cases {bad}" if bad else "")
        )

    return check


def mu_follows(cases: tuple[int, ...], band: bool) -> Callable[[Metrics, RigParameters], tuple[bool, str]]:
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


# --- how a verdict moves across the reasonable range of a criterion's stated choice -----------


def same_amplitude_span(metrics: Metrics) -> tuple[bool, bool]:
    """C2a over t in SAME_TOLERANCES: (holds for some t, holds for every t)."""
    grows = _grows_then_stationary(metrics[2])
    ratio = metrics[2]["x_peak_to_peak"] / metrics[1]["x_peak_to_peak"]
    needed = max(ratio, 1.0 / ratio) - 1.0
    return grows and needed <= SAME_TOLERANCES[1], grows and needed <= SAME_TOLERANCES[0]


def gone_span(n: int) -> Callable[[Metrics], tuple[bool, bool] | None]:
    """C9b/C10b over the reference levels GONE_FRACTIONS: (holds at some, holds at every level)."""

    def span(metrics: Metrics) -> tuple[bool, bool] | None:
        times = metrics[n].get("f0_gone_times")
        if not times:
            return None
        inside = [about(t, GONE_AFTER_S[n]) for t in times]
        return any(inside), all(inside)

    return span
