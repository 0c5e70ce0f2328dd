"""The study's statements (model doc, section 8) as data, and the scorecard that checks them.

`STATEMENTS` lists every statement of section 8 with its explicit criterion; `scorecard` evaluates
them all for one velocity coupling from the metrics (study/runs.py) of the ten cases and the
stick-slip run. The same functions serve the named conventions and the coupling scan
(s = γ · A / A_default), so a statement means the same thing everywhere.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..core.params import RigParameters
from . import checks as check
from .runs import GONE_FRACTION, GONE_FRACTIONS, REALISTIC_ZETA, Metrics, rig_with_coupling


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
    #: For a criterion with a stated choice (C2a's tolerance, C9b/C10b's reference level): whether
    #: it holds for some and for every value of the choice's reasonable range; None otherwise.
    span: tuple[bool, bool] | None = None

    @property
    def marginal(self) -> bool:
        """The verdict flips within the reasonable range of the criterion's choice."""
        return self.span is not None and self.span[0] != self.span[1]


STATEMENTS: tuple[Statement, ...] = (
    Statement(
        "F1",
        "friction curve",
        "static-like friction around 0.1 below 4.1e-12 m/s (peak)",
        "peak at 4.1e-12 m/s ± 5 %, μ 0.1 … 0.17",
        check.friction_curve_peak,
    ),
    Statement(
        "F2",
        "friction curve",
        "decreasing until 1.35e-7 m/s",
        "minimum at 1.35e-7 m/s ± 3 %",
        check.friction_curve_minimum,
    ),
    Statement(
        "F3",
        "friction curve",
        "viscous and rising above: μ 6.5e-3 … 6.6e-3 over 1e-7 … 2e-7, ~10e-3 at 1e-6",
        "μ(1e-7), μ(2e-7) in [6.48e-3, 6.6e-3]; μ(1e-6) in [8e-3, 10.5e-3]",
        check.friction_curve_viscous,
    ),
    Statement(
        "S1",
        "stability",
        "naturally stable where dμ/dv > 0 (below 4e-12, above 1.35e-7 up to 1e-4 m/s)",
        "ζ_crit = 0 there",
        check.zones_stable,
    ),
    Statement(
        "S2",
        "stability",
        "unstable whatever the damping between 4e-12 and 3e-8 m/s; edge at 3e-8",
        f"ζ_crit ≥ {REALISTIC_ZETA:g} (realistic damping) over 4.2e-12 … 2.5e-8 m/s, and the unstable "
        f"interval at ζ = {REALISTIC_ZETA:g} ends at 3e-8 to the printed digit ([2.5e-8, 3.5e-8))",
        check.unstable_any_damping,
    ),
    Statement(
        "S3",
        "stability",
        "stabilizable by enough damping between 3e-8 and 1.35e-7 m/s",
        f"0 < ζ_crit ≤ {1.2 * REALISTIC_ZETA:g} over 3.05e-8 … 1.34e-7 m/s",
        check.stabilizable,
    ),
    Statement(
        "S4",
        "stick-slip",
        "constant band velocity 2e-8 m/s gives stick-slip (Fig. 6)",
        "stick fraction > 0.3 and μ max > 0.155 over the second half (μ between samples)",
        check.stickslip,
    ),
    Statement(
        "C1a",
        "case 1",
        "amplitude grows, then stationary",
        "band-period p-p: first < stationary (last quarter); 3rd/4th quarter drift < 10 %",
        check.case_grows(1),
    ),
    Statement(
        "C1b",
        "case 1",
        "overshoot in the transient between 0.5 and 1.5 s",
        "largest band-period p-p before 5 s centred in 0.5 … 1.5 s and > 1.05 × stationary",
        check.case1_overshoot,
    ),
    Statement(
        "C1c",
        "case 1",
        "4.76 Hz and 9.52 Hz (2nd harmonic)",
        "two strongest peaks = 1st and 2nd harmonic of 4.76 Hz",
        check.harmonic_set(1, [1, 2], 2),
    ),
    Statement(
        "C2a",
        "case 2",
        "like case 1, identical amplitude levels",
        f"grows then stationary; p-p case 2 / case 1 in [1/(1 + t), 1 + t], t = {check.SAME_TOLERANCE:.0%} "
        f"(verdict shown over t = {check.SAME_TOLERANCES[0]:.0%} … {check.SAME_TOLERANCES[1]:.0%})",
        lambda m, r: (
            check.case_grows(2)(m, r)[0] and check.case2_same_amplitude(m, r)[0],
            check.case2_same_amplitude(m, r)[1] + "; " + check.amplitude_text(m[2]),
        ),
    ),
    Statement(
        "C2b",
        "case 2",
        "3.33, 6.66 and 9.99 Hz",
        "three strongest peaks = harmonics 1, 2, 3 of 3.33 Hz",
        check.harmonic_set(2, [1, 2, 3], 3),
    ),
    Statement(
        "C3a",
        "case 3",
        "grows on the V1 = 1e-7 plateau (unstable), decays on V2 = 2e-7 (stable)",
        "median envelope rate > 0 on V1 plateaus and < 0 on V2 plateaus (second half)",
        check.case3_plateaus(3),
    ),
    Statement(
        "C3b",
        "case 3",
        "multiple frequencies in 1–10 Hz, predominant 10 Hz (12th harmonic)",
        "strongest peak 10 Hz; ≥ 4 of the strongest peaks in 0.8–10.5 Hz",
        check.case3_spectrum,
    ),
    Statement(
        "C4a",
        "case 4",
        "like case 1 apart from transient and amplitude",
        "stationary: 3rd/4th quarter drift of the band-period p-p < 10 % (the transient is excepted)",
        check.case_stationary(4),
    ),
    Statement(
        "C4b",
        "case 4",
        "predominant 4.76 Hz, small 9.52 and 14.28 Hz",
        "strongest peak 4.76 Hz; 2nd and 3rd harmonics among the next four",
        check.case4_spectrum,
    ),
    Statement(
        "C5a",
        "case 5",
        "grows like case 2, larger amplitudes",
        "grows then stationary; p-p > case 2",
        check.case5_larger,
    ),
    Statement(
        "C5b",
        "case 5",
        "predominant 3.33 Hz and 9.99 Hz (3rd harmonic)",
        "two strongest peaks = 1st and 3rd harmonic of 3.33 Hz",
        check.harmonic_set(5, [1, 3], 2),
    ),
    Statement(
        "C6a",
        "case 6",
        "two limit cycles clearly separated in the phase plot",
        "orbits on V1 and V2 plateaus in (x, ẋ/ω0): centre distance > r1 + r2 (95 % radii)",
        check.case6_separated,
    ),
    Statement(
        "C6b",
        "case 6",
        "a vibration grows on one limit cycle and decays on the other",
        "median envelope rate > 0 on V1 plateaus and < 0 on V2 plateaus",
        check.case3_plateaus(6),
    ),
    Statement("C6c", "case 6", "larger amplitude (than case 3)", "p-p case 6 > case 3", check.case6_larger),
    Statement(
        "C6d",
        "case 6",
        "very rich content between 0.8 and 10 Hz",
        "≥ 5 of the 8 strongest peaks in 0.8–10.5 Hz",
        check.case6_rich,
    ),
    Statement(
        "C7a", "case 7", "the displacement grows until periodic", "grows then stationary", check.case_grows(7)
    ),
    Statement(
        "C7b",
        "case 7",
        "mono-harmonic at 10 Hz",
        "strongest peak 10 Hz, second < 10 % of it",
        check.case7_mono,
    ),
    Statement(
        "C7c",
        "case 7",
        "magnitudes eight times those of case 5",
        "p-p case 7 / case 5 in [6, 10]",
        check.case7_ratio,
    ),
    Statement(
        "C8a",
        "case 8",
        "stationary quasi-periodic vibration governed by stick-slip",
        "stick fraction ≥ 0.05 (second half); drift < 25 %",
        check.case8_stickslip,
    ),
    Statement(
        "C8b",
        "case 8",
        "two predominant frequencies, 10 Hz and 20 Hz",
        "two strongest peaks 10 and 20 Hz",
        check.case8_frequencies,
    ),
    Statement(
        "C8c",
        "case 8",
        "μ fluctuates strongly between 6.5e-3 and 0.16",
        "μ min in [5e-3, 7.5e-3], μ max in [0.1, 0.17], between samples (the study's curve is "
        "continuous; core/dense.py)",
        check.case8_mu,
    ),
    Statement(
        "C9a",
        "case 9",
        "very fast decrease of the transient, small residual (compare case 2)",
        "first band-period p-p > 2 × stationary, settled by 3 s, p-p < 0.5 × case 2",
        check.fast_decay(9, 2),
    ),
    Statement(
        "C9b",
        "case 9",
        "the 10 Hz component disappears after about 10 s",
        f"10 Hz amplitude below {GONE_FRACTION:g} × early level from a time in "
        f"{check.about_text(check.GONE_AFTER_S[9])} "
        f"(verdict shown for levels {GONE_FRACTIONS[0]:g} … {GONE_FRACTIONS[-1]:g})",
        check.gone(9),
    ),
    Statement(
        "C9c",
        "case 9",
        "only 33 Hz remains",
        "strongest 33.3 Hz, every other peak < 30 % of it",
        check.case9_only33,
    ),
    Statement(
        "C10a",
        "case 10",
        "very fast decrease of the transient, small residual (compare case 5)",
        "first band-period p-p > 2 × stationary, settled by 3 s, p-p < 0.5 × case 5",
        check.fast_decay(10, 5),
    ),
    Statement(
        "C10b",
        "case 10",
        "the 10 Hz component disappears after about 5 s",
        f"10 Hz amplitude below {GONE_FRACTION:g} × early level from a time in "
        f"{check.about_text(check.GONE_AFTER_S[10])} "
        f"(verdict shown for levels {GONE_FRACTIONS[0]:g} … {GONE_FRACTIONS[-1]:g})",
        check.gone(10),
    ),
    Statement(
        "C10c",
        "case 10",
        "33 Hz and 66 Hz remain",
        "two strongest peaks 33.3 and 66.7 Hz",
        check.case10_33_66,
    ),
    Statement(
        "M1",
        "μ over time",
        "within [6.5e-3, 6.6e-3] for cases 1, 2, 3, 9",
        "μ in [6.48e-3, 6.6e-3] over the second half, between samples (6.486e-3 is the curve's minimum)",
        check.mu_range((1, 2, 3, 9), 6.48e-3, 6.6e-3),
    ),
    Statement(
        "M2",
        "μ over time",
        "within [6e-3, 10e-3] for cases 4–7 and 10",
        "μ in [6e-3, 10e-3], between samples",
        check.mu_range((4, 5, 6, 7, 10), 6e-3, 10e-3),
    ),
    Statement(
        "M3",
        "μ over time",
        "μ mainly follows the band velocity for cases 4–7, 9, 10",
        "μ(v_band) explains ≥ 90 % of μ's variance (R² ≥ 0.9)",
        check.mu_follows((4, 5, 6, 7, 9, 10), True),
    ),
    Statement(
        "M4",
        "μ over time",
        "for cases 1–3 μ also follows the mass velocity",
        "R² of μ by μ(v_band) < 0.9",
        check.mu_follows((1, 2, 3), False),
    ),
)


def scorecard(metrics: Metrics, rig: RigParameters) -> list[Verdict]:
    """Every statement's verdict from the metrics of cases 1–10 and the stick-slip run (key 0).

    `rig` carries the coupling for the stability statements (its damping is the study's 0.01).
    """
    verdicts = []
    for s in STATEMENTS:
        agree, measured = s.evaluate(metrics, rig)
        span = SPANS[s.key](metrics) if s.key in SPANS else None
        verdicts.append(Verdict(s.key, s.topic, s.study, s.criterion, measured, bool(agree), span))
    return verdicts


#: Criteria whose verdict is also evaluated over the reasonable range of their stated choice.
SPANS: dict[str, Callable[[Metrics], tuple[bool, bool] | None]] = {
    "C2a": check.same_amplitude_span,
    "C9b": check.gone_span(9),
    "C10b": check.gone_span(10),
}


def score_span(verdicts: list[Verdict]) -> tuple[int, int]:
    """Statements agreed when every marginal verdict goes against, and when every one goes for."""
    agreed = sum(v.agree for v in verdicts)
    return (
        agreed - sum(1 for v in verdicts if v.marginal and v.agree),
        agreed + sum(1 for v in verdicts if v.marginal and not v.agree),
    )


def transitions(scan: dict[float, Metrics]) -> list[tuple[float, float]]:
    """Neighbouring couplings (s_lo, s_hi) of the scan between which some verdict changes."""
    from ..core.params import RigParameters

    values = sorted(scan)
    agreed = [
        frozenset(v.key for v in scorecard(scan[s], rig_with_coupling(RigParameters(), s)) if v.agree)
        for s in values
    ]
    return [(values[i], values[i + 1]) for i in range(len(values) - 1) if agreed[i] != agreed[i + 1]]
