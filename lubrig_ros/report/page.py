"""Write a run report from a bag: study-style figures, summary.json, report.md and report.html."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..app.analysis.policy import analyze_displacement, whole_record
from ..app.rundir import prepare_output_dir
from ..bag import Bag
from ..core.run import summarize
from .frombag import open_bag, read_run
from .html import write_html_page

PAGE = "report.md"
HTML_PAGE = "report.html"
#: Declared gaps listed one by one on the page at most (all of them are in summary.json).
LISTED_GAPS = 20


def _fmt(value: Any, spec: str = ".4g") -> str:
    return format(value, spec) if isinstance(value, (int, float)) else str(value)


def run_heading(summary: dict[str, Any]) -> str:
    """'case 7, paper convention (γ = 0.0159)' of a summary (the run's name, not a folder's)."""
    name = str(summary["name"])
    if name.startswith("case") and name[4:].isdigit():
        name = f"case {int(name[4:])}"
    gamma = summary.get("velocity_coupling")
    coupling = f"γ = {gamma:.3g}" if isinstance(gamma, (int, float)) else ""
    if summary.get("convention") != "explicit":
        coupling = f"{summary.get('convention')} convention" + (f" ({coupling})" if coupling else "")
    return f"{name}, {coupling}"


def _recording_lines(recording: dict[str, Any]) -> list[str]:
    """The page's recording section: samples per stream, and every gap marked.

    Samples the plant declared skipped (it fell behind real time by more than max_lag) are listed
    apart: missing from the bag, but never published, so not lost on the way.
    """
    streams = recording.get("streams", {})
    if not streams:
        return []
    lines = ["## Recording", ""]
    for name, s in streams.items():
        mark = "complete" if s["complete"] else "**INCOMPLETE**"
        skipped = f", {s['skipped']} skipped by the plant" if s.get("skipped") else ""
        lines.append(
            f"- `{name}`: {s['samples']} samples, {s['missing']} missing, "
            f"{s['duplicates']} duplicates, {s['out_of_order']} out of order{skipped}: {mark}"
        )
        lines += [
            f"  - **gap**: {g['count']} samples from index {g['first_index']} of segment "
            f"{g['segment']} at rig time {g['rig_time_s']:.6f} s"
            for g in s["gaps"]
        ]
        declared = s.get("declared_gaps", [])
        lines += [
            f"  - declared gap: {g['count']} samples skipped from index {g['first_index']} of "
            f"segment {g['segment']} at rig time {g['rig_time_s']:.6f} s"
            for g in declared[:LISTED_GAPS]
        ]
        if len(declared) > LISTED_GAPS:
            lines.append(
                f"  - … and {len(declared) - LISTED_GAPS} more declared gaps (summary.json lists every one)"
            )
    return [*lines, ""]


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3g} ms"


def _timing_lines(timing: dict[str, Any]) -> list[str]:
    """The page's realtime timing section (only for a bag whose samples carry their lateness)."""
    if not timing:
        return []
    period = timing["sample_period_s"]
    gaps = timing["gaps"]
    bound = (
        "stated by the plant"
        if timing["max_lag_source"] == "recording"
        else "the plant's default: the bag does not state it"
    )
    rows = [
        (f"samples with lateness (segment {timing['segment']})", f"{timing['samples']}"),
        (
            "lateness p50 / p99 / max",
            f"{_ms(timing['lateness_p50_s'])} / "
            f"{_ms(timing['lateness_p99_s'])} / {_ms(timing['lateness_max_s'])}",
        ),
        (
            f"later than one period ({_ms(period)})",
            f"{100.0 * timing['late_share']:.3g} % ({timing['late_samples']} samples)",
        ),
        (
            "skipped samples (declared gaps, listed under Recording)",
            f"{timing['skipped_samples']} in {len(gaps)} gap(s)",
        ),
        ("max_lag", f"{_ms(timing['max_lag_s'])} ({bound})"),
    ]
    lines = [
        "## Realtime timing",
        "",
        "Lateness of each sample: how long after its due time (segment start + k · sample period, "
        "wall clock) the plant computed it, i.e. the lag of rig time behind wall time. A sample "
        "later than one period missed its deadline; when the lag exceeds max_lag the plant skips "
        "samples to catch up and declares them (a declared gap, not a lost message). Percentiles "
        "are recorded values.",
        "",
        "| quantity | value |",
        "|---|---|",
        *[f"| {k} | {v} |" for k, v in rows],
        "",
    ]
    return [*lines, f"![realtime timing]({timing['figure']})", ""]


def markdown(summary: dict[str, Any], bag: Path) -> str:
    """The report page (Markdown) for a summary with its "wavelet" section."""
    wav = summary.get("wavelet", {})
    samples = f"{summary['samples']} ({summary['duration']:g} s at {summary['sample_rate_hz']:g} Hz)"
    peaks = ", ".join(f"{f:.3g} Hz" for f in summary["dominant_frequencies_hz"]) or "none"
    rows = [
        ("run", summary["name"]),
        ("convention", summary["convention"]),
        ("samples (rig time)", samples),
        ("natural frequency f0", f"{_fmt(summary['natural_frequency_hz'])} Hz"),
        ("band fundamental", f"{_fmt(summary['band_fundamental_hz'])} Hz"),
        ("x peak-to-peak (2nd half)", f"{_fmt(summary['x_peak_to_peak'])} m"),
        ("μ range (2nd half)", f"{_fmt(summary['mu_min'])} … {_fmt(summary['mu_max'])}"),
        ("stick fraction (2nd half)", f"{summary['stick_fraction']:.3f}"),
        ("spectral peaks (2nd half)", peaks),
    ]
    streams = ", ".join(summary.get("recording", {}).get("streams", {})) or "the plant topics"
    lines = [
        f"# Run report: {run_heading(summary)}",
        "",
        f"Recorded bag: `{bag}`. Rebuilt from the plant's sample stream ({streams}) and the run "
        "configuration stored in the bag (`config.yaml`). Numbers as `lubrig simulate` reports "
        "them (`summary.json`).",
        "",
        "| quantity | value |",
        "|---|---|",
        *[f"| {k} | {v} |" for k, v in rows],
        "",
        *_recording_lines(summary.get("recording", {})),
        *_timing_lines(summary.get("timing", {})),
        "## Wavelet power spectrum",
        "",
        "Morlet (ω0 = 6) power of x − mean, cone of influence hatched, 95 % significance against "
        "AR(1) red noise contoured.",
        "",
        "![wavelet](wavelet.png)",
        "",
    ]
    if wav.get("dominant_frequencies"):
        lines += ["| frequency (Hz) | power | label | significant |", "|---|---|---|---|"]
        lines += [
            f"| {c['frequency_hz']:.4g} | {c['power']:.3g} | {c['label']} | {c['significant']} |"
            for c in wav["dominant_frequencies"]
        ]
        lines.append("")
    lines += [
        "## Time history",
        "",
        "![time history](time_history.png)",
        "",
        "## Phase plot (x, ẋ)",
        "",
        "![phase](phase.png)",
        "",
        "## Friction coefficient with relative, band and mass velocities",
        "",
        "μ is signed: it has the sign of v_rel = v_band − γ ẋ (negative while the interface slides "
        "backwards, as in stick-slip). The band velocity is drawn dashed on top of v_rel.",
        "",
        "![friction and velocities](friction_velocity.png)",
        "",
        "## Operating point on the friction curve (μ against v_rel)",
        "",
        "(v_rel(t), μ(t)) of the run, coloured by time, over the friction law μ(v_rel) with its "
        "zones shaded (1: rising, stable; 2: falling, unstable unless damped; 3: rising, viscous).",
        "",
        "![operating point on the friction curve](mu_velocity.png)",
        "",
    ]
    return "\n".join(lines)


def write_report(bag: str | Path | Bag, out: str | Path, force: bool = False) -> Path:
    """Write figures, timeseries.csv, config.yaml, summary.json, report.md and report.html.

    Returns report.md. The bag is read once (frombag.open_bag, unless it is a Bag already read).
    The wavelet section is that of `lubrig analyze` with its defaults (whole record), computed
    on the trajectory in memory; every file is written once. A bag whose samples carry their
    realtime lateness also gets the "timing" section (app/recording/lateness.py RigTiming.summary) and
    timing.png; other bags neither.
    An existing non-empty `out` is refused unless force (then the report's own files are
    replaced).
    """
    from ..figures import style
    from ..figures.run import RUN_FILES, write_run_directory  # matplotlib only when drawing
    from ..figures.timing import TIMING_FIGURE, write_timing_figure

    out = prepare_output_dir(Path(out), force, "--out", (*RUN_FILES, TIMING_FIGURE, PAGE, HTML_PAGE))
    source = open_bag(bag)
    run = read_run(source)
    config, trajectory = run.config, run.trajectory
    summary = summarize(trajectory, config)
    summary["source_bag"] = str(source.path.resolve())
    summary["recording"] = run.recording  # gaps found from the samples' indices
    if run.timing is not None:
        summary["timing"] = dict(run.timing.summary(), figure=TIMING_FIGURE)
    analysis = analyze_displacement(
        trajectory.time,
        trajectory.displacement,
        config.sample_rate,
        config.band.fundamental_hz,
        whole_record(),
    )
    summary = write_run_directory(out, config, trajectory, summary, analysis)
    if run.timing is not None:
        title = style.run_title(config.name, config.rig, "Realtime timing")
        write_timing_figure(out, run.timing, title)
    page = out / PAGE
    page.write_text(markdown(summary, source.path))
    write_html_page(page, f"Run report: {run_heading(summary)}")
    return page
