"""`lubrig paper`: reproduce the study offline with the core and compare it statement by statement.

Writes friction_curve.png, stability_map.png, stickslip/, cases/caseNN (paper convention, with
wavelet), cases/caseNN_physical, and comparison.md: for every statement of the model document
(landmarks, stability, section-6 case statements, physical-convention contrast) what the study
says, what lubrig_ros measured and a verdict (agree / differs, with the reason when known).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..app.analysis import DEFAULT_POLICY, WaveletAnalysis, analyze_displacement, whole_record
from ..app.rundir import check_output_dir
from ..app.selection import base_config
from ..core.friction import friction_coefficient, friction_minimum, friction_peak
from ..core.params import RigParameters
from ..core.presets import RunConfig, config_dir, load_config
from ..core.run import simulate, summarize
from ..core.stability import critical_damping_ratio, unstable_intervals
from ..core.wavelet import Component

#: Damping ratios up to this count as "realistic" in the stability statements.
REALISTIC_ZETA = 0.1
MIN_DURATION = 4.0


@dataclass
class Row:
    """One statement of the model document and its check."""

    section: str
    statement: str
    study: str
    measured: str
    agree: bool
    reason: str = ""

    @property
    def verdict(self) -> str:
        """Verdict: agree, or differs with the reason."""
        return "agree" if self.agree else "differs" + (f" — {self.reason}" if self.reason else "")


@dataclass
class CaseRun:
    """One offline run of the comparison: configuration, trajectory, summary, wavelet analysis."""

    config: RunConfig
    trajectory: Any
    summary: dict[str, Any]
    analysis: WaveletAnalysis | None = None

    @property
    def components(self) -> list[Component]:
        """Dominant components of the stationary window (app/analysis.py's one policy)."""
        if self.analysis is None:
            raise ValueError(f"{self.config.name}: run has no wavelet analysis")
        return self.analysis.components


def _g(x: float) -> str:
    return f"{x:.3g}"


def landmark_rows() -> list[Row]:
    """Section 3: friction-curve landmarks."""
    peak, minimum = friction_peak(), friction_minimum()
    mu = {v: float(friction_coefficient(v)) for v in (1e-7, 2e-7, 1e-6)}
    return [
        Row("3 landmarks", "end of zone 1 / peak of μ", "4.1e-12 m/s, μ around 0.1 (up to 0.16)",
            f"peak μ = {peak.mu:.3f} at {peak.velocity:.3g} m/s",
            abs(peak.velocity / 4.1e-12 - 1) < 0.05 and 0.1 <= peak.mu <= 0.17),
        Row("3 landmarks", "minimum of μ (end of zone 2)", "1.35e-7 m/s",
            f"μ = {minimum.mu:.4g} at {minimum.velocity:.3g} m/s",
            abs(minimum.velocity / 1.35e-7 - 1) < 0.03),
        Row("3 landmarks", "μ over band velocities 1e-7 … 2e-7 m/s", "between 6.5e-3 and 6.6e-3",
            f"{mu[1e-7]:.4g}, {mu[2e-7]:.4g}", all(6.5e-3 <= mu[v] <= 6.6e-3 for v in (1e-7, 2e-7))),
        Row("3 landmarks", "μ at 1e-6 m/s", "up to about 10e-3", f"{mu[1e-6]:.3g}",
            8e-3 <= mu[1e-6] <= 10.5e-3),
    ]


def stability_rows() -> list[Row]:
    """Section 4: linear stability (Routh–Hurwitz), both conventions."""
    paper, physical = RigParameters(convention="paper"), RigParameters(convention="physical")
    zone13 = np.array([1e-14, 1e-13, 2e-12, 2e-7, 1e-6, 1e-5, 1e-4])
    z13 = float(np.max(critical_damping_ratio(zone13, paper)))
    deep = np.logspace(np.log10(4.2e-12), np.log10(3e-8), 200)
    deep_min = float(np.min(critical_damping_ratio(deep, paper)))
    stabil = np.logspace(np.log10(3.05e-8), np.log10(1.34e-7), 100)
    zc = critical_damping_ratio(stabil, paper)
    edge_paper = unstable_intervals(REALISTIC_ZETA, paper)[0][1]
    edge_phys = unstable_intervals(REALISTIC_ZETA, physical)[0][1]
    return [
        Row("4 stability", "zones 1 and 3 stable whatever ζ", "μ' > 0: stable",
            f"max ζ_crit over zones 1, 3 = {z13:g}", z13 == 0.0),
        Row("4 stability", "unstable for any (realistic) damping between 4e-12 and 3e-8 m/s",
            "unstable", f"paper convention: ζ_crit ≥ {deep_min:.3g} there (realistic ζ ≤ {REALISTIC_ZETA:g})",
            deep_min >= 0.9 * REALISTIC_ZETA),
        Row("4 stability", "stabilizable between 3e-8 and 1.35e-7 m/s", "ζ > ζ_crit stabilizes",
            f"paper convention: ζ_crit {_g(zc.min())} … {_g(zc.max())}; unstable up to "
            f"{edge_paper:.3g} m/s at ζ = {REALISTIC_ZETA:g} "
            f"(physical convention: up to {edge_phys:.3g} m/s)",
            bool(zc.max() <= 1.2 * REALISTIC_ZETA and zc.min() > 0)),
        Row("4 stability", "stable from 1.35e-7 up to 1e-4 m/s", "stable",
            f"ζ_crit = {float(np.max(critical_damping_ratio(np.logspace(-6.86, -4, 50), paper))):g}",
            float(np.max(critical_damping_ratio(np.logspace(-6.86, -4, 50), paper))) == 0.0),
    ]


def _labels(components: list[Component], k: int) -> str:
    return ", ".join(f"{c.frequency_hz:.3g} Hz ({c.label})" for c in components[:k])


def _ten_hz_decay(run: CaseRun) -> float:
    """Wavelet power at 10 Hz late in the run / early (1–2 s): whole record, 5–60 Hz."""
    traj, config = run.trajectory, run.config
    policy = whole_record(fmin_hz=5.0, fmax_hz=60.0)
    result = analyze_displacement(traj.time, traj.displacement, config.sample_rate, None, policy).wavelet
    j = int(np.argmin(np.abs(result.frequencies - 10.0)))
    t, d = result.time, config.duration
    early = result.power[j, (t > 1.0) & (t < 2.0)].mean()
    late = result.power[j, (t > 0.75 * d) & (t < 0.9 * d)].mean()
    return float(late / early)


def _mu_in(summary: dict[str, Any], low: float, high: float) -> bool:
    return summary["mu_min"] >= low and summary["mu_max"] <= high


def case_rows(runs: dict[int, CaseRun]) -> list[Row]:
    """Section 6: the study's statements on cases 1–4, 9, 10 (paper convention)."""
    rows = []
    c1, t1, s1 = runs[1].config, runs[1].trajectory, runs[1].summary
    comp1 = runs[1].components
    t, x = t1.time, t1.displacement
    overshoot = np.ptp(x[(t > 0.5) & (t < 1.5)]) / np.ptp(x[t > c1.duration / 2])
    mu_note = "6.486e-3 is the curve's minimum; the study's 6.5e-3 is rounded"
    rows.append(Row(
        "6 case 1", "bounded, transient overshoot 0.5–1.5 s, 4.76 and 9.52 Hz, μ within 6.5e-3 … 6.6e-3",
        "as stated", f"x p-p {_g(s1['x_peak_to_peak'])} m, overshoot ×{overshoot:.2f}, {_labels(comp1, 2)}; "
        f"μ {s1['mu_min']:.4g} … {s1['mu_max']:.4g} ({mu_note})",
        {c.harmonic for c in comp1[:2]} == {1, 2} and overshoot > 1.05 and _mu_in(s1, 6.48e-3, 6.6e-3),
    ))
    s2, comp2 = runs[2].summary, runs[2].components
    ratio = s2["x_peak_to_peak"] / s1["x_peak_to_peak"]
    rows.append(Row(
        "6 case 2", "same amplitude as case 1; 3.33, 6.66, 9.99 Hz", "as stated",
        f"x p-p ratio to case 1 = {ratio:.2f}; {_labels(comp2, 3)}",
        0.5 < ratio < 2.0 and {c.harmonic for c in comp2[:3]} == {1, 2, 3},
    ))
    s3, comp3 = runs[3].summary, runs[3].components
    rows.append(Row(
        "6 case 3", "many harmonics of 0.83 Hz, dominant near 10 Hz (12th); μ within 6.5e-3 … 6.6e-3",
        "as stated", f"{_labels(comp3, 4)}; μ {s3['mu_min']:.4g} … {s3['mu_max']:.4g}",
        abs(comp3[0].frequency_hz - 10.0) < 0.5 and len(comp3) >= 4 and _mu_in(s3, 6.48e-3, 6.6e-3),
    ))
    s4, comp4 = runs[4].summary, runs[4].components
    rows.append(Row(
        "6 case 4", "dominant 4.76 Hz, small 9.52 and 14.28 Hz; μ within about 6e-3 … 10e-3", "as stated",
        f"{_labels(comp4, 3)}; μ {s4['mu_min']:.4g} … {s4['mu_max']:.4g}",
        comp4[0].harmonic == 1 and {2, 3} <= {c.harmonic for c in comp4} and _mu_in(s4, 6e-3, 10e-3),
    ))
    for number, when in ((9, "about 10 s"), (10, "about 5 s")):
        comp = runs[number].components
        decay = _ten_hz_decay(runs[number])
        extra = " (also 66 Hz)" if number == 10 else ""
        reason = "the 10 Hz power has not decayed by 1e-3 in this run length"
        note = (
            "; the model doc's independent implementation kept a small 10 Hz component to 20 s — "
            "we find it decays, like the study" if number == 9 else ""
        )
        rows.append(Row(
            f"6 case {number}", f"fast transient decay; 10 Hz gone after {when}; residual 33 Hz{extra}",
            "as stated", f"{_labels(comp, 2)}; 10 Hz power late/early = {decay:.2g}{note}",
            abs(comp[0].frequency_hz - 33.33) < 0.5 and decay < 1e-3, reason,
        ))
    return rows


def physical_rows(runs: dict[int, CaseRun]) -> list[Row]:
    """Section 6: the physical convention drives cases 1, 3, 5, 6 into large stick-slip."""
    rows = []
    for number in (1, 3, 5, 6):
        s = runs[number].summary
        rows.append(Row(
            f"5/6 physical case {number}", "large stick-slip (x p-p about 7e-7 m, μ reaching 0.16)",
            "model doc (independent implementation)",
            f"x p-p {_g(s['x_peak_to_peak'])} m, μ max {s['mu_max']:.3f}, "
            f"stick fraction {s['stick_fraction']:.2f}",
            4e-7 < s["x_peak_to_peak"] < 1e-6 and s["mu_max"] > 0.155,
        ))
    return rows


def stickslip_row(summary: dict[str, Any]) -> Row:
    """Section 4: stick-slip at a constant 2e-8 m/s."""
    return Row(
        "4 stick-slip", "constant band velocity 2e-8 m/s gives stick-slip", "stick-slip",
        f"stick fraction {summary['stick_fraction']:.2f}, μ max {summary['mu_max']:.3f}, "
        f"x p-p {_g(summary['x_peak_to_peak'])} m",
        summary["stick_fraction"] > 0.5 and summary["mu_max"] > 0.155,
    )


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def comparison_markdown(rows: list[Row], cases: list[dict[str, Any]], duration: float) -> str:
    """comparison.md text."""
    agree = sum(r.agree for r in rows)
    lines = [
        "# lubrig_ros against the study",
        "",
        f"Offline core runs, {duration:g} s of rig time per case; frequencies from the wavelet "
        "spectrum of x over the second half. Statements from "
        "../shared/model/lubricated-rig-model.md (relative to the repository). "
        f"{agree} of {len(rows)} statements agree.",
        "",
        "| section | statement | study | lubrig_ros measured | verdict |",
        "|---|---|---|---|---|",
    ]
    lines += [
        "| " + " | ".join(_cell(c) for c in (r.section, r.statement, r.study, r.measured, r.verdict)) + " |"
        for r in rows
    ]
    lines += [
        "",
        "## All ten cases, both conventions",
        "",
        "| case | convention | x p-p (m) | μ min | μ max | stick fraction | spectral peaks (Hz) | figures |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        peaks = ", ".join(f"{f:.3g}" for f in c["dominant_frequencies_hz"][:3])
        lines.append(
            f"| {c['name']} | {c['convention']} | {c['x_peak_to_peak']:.3g} | {c['mu_min']:.4g} | "
            f"{c['mu_max']:.4g} | {c['stick_fraction']:.2f} | {peaks} | [{c['dir']}]({c['dir']}/) |"
        )
    lines.append("")
    return "\n".join(lines)


def run_paper(out: str | Path, duration: float = 20.0) -> Path:
    """Write every figure and run directory plus comparison.md into out; return comparison.md.

    Each case is simulated and analysed once (app/analysis.py's policy: the stationary second
    half); its directory, figures and comparison rows all come from that one analysis.
    """
    from ..figures.curves import plot_friction_curve, plot_stability_map, save_figure
    from ..figures.run import write_run_directory

    if not (np.isfinite(duration) and duration >= MIN_DURATION):
        raise ValueError(f"--duration {duration!r} is not valid; expected at least {MIN_DURATION:g} s")
    out = check_output_dir(Path(out))
    out.mkdir(parents=True, exist_ok=True)
    save_figure(plot_friction_curve(), out / "friction_curve.png")
    save_figure(plot_stability_map(RigParameters(convention="paper")), out / "stability_map.png")

    def one(config: RunConfig, directory: Path, wavelet: bool) -> CaseRun:
        started = time.perf_counter()
        trajectory = simulate(config)
        summary = summarize(trajectory, config)
        summary["wall_time_s"] = time.perf_counter() - started
        analysis = None
        if wavelet:
            analysis = analyze_displacement(
                trajectory.time, trajectory.displacement, config.sample_rate,
                config.band.fundamental_hz, DEFAULT_POLICY,
            )
        summary = write_run_directory(directory, config, trajectory, summary, analysis)
        return CaseRun(config, trajectory, summary, analysis)

    stick = load_config(config_dir() / "stickslip.yaml").with_overrides(duration=duration)
    stick_summary = one(stick, out / "stickslip", wavelet=False).summary
    paper: dict[int, CaseRun] = {}
    physical: dict[int, CaseRun] = {}
    table = []
    for number in range(1, 11):
        base = base_config(case=number).with_overrides(duration=duration)
        name = f"case{number:02d}"
        paper[number] = one(base.with_overrides(convention="paper"), out / "cases" / name, True)
        physical[number] = one(
            base.with_overrides(convention="physical"), out / "cases" / f"{name}_physical", False
        )
        table.append(dict(paper[number].summary, dir=f"cases/{name}"))
        table.append(dict(physical[number].summary, dir=f"cases/{name}_physical"))
    rows = [
        *landmark_rows(), *stability_rows(), stickslip_row(stick_summary),
        *case_rows(paper), *physical_rows(physical),
    ]
    page = out / "comparison.md"
    page.write_text(comparison_markdown(rows, table, duration))
    return page
