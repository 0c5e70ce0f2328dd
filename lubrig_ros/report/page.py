"""Write a run report from a bag: study-style figures, summary.json, report.md and report.html."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..app.analysis import analyze_displacement, whole_record
from ..app.rundir import prepare_output_dir
from ..core.run import summarize
from .frombag import recording_summary, trajectory_from_bag
from .html import write_html_page

FIGURE_FILES = ("wavelet.png", "time_history.png", "phase.png", "friction_velocity.png", "mu_velocity.png")
PAGE = "report.md"
HTML_PAGE = "report.html"


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
    """The page's recording section: samples per stream, and every gap marked (issue 12)."""
    streams = recording.get("streams", {})
    if not streams:
        return []
    lines = ["## Recording", ""]
    for name, s in streams.items():
        mark = "complete" if s["complete"] else "**INCOMPLETE**"
        lines.append(f"- `{name}`: {s['samples']} samples, {s['missing']} missing, "
                     f"{s['duplicates']} duplicates, {s['out_of_order']} out of order: {mark}")
        lines += [f"  - **gap**: {g['count']} samples from index {g['first_index']} of segment "
                  f"{g['segment']} at rig time {g['rig_time_s']:.6f} s" for g in s["gaps"]]
    return [*lines, ""]


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


def write_report(bag: str | Path, out: str | Path, force: bool = False) -> Path:
    """Write figures, timeseries.csv, config.yaml, summary.json, report.md and report.html.

    Returns report.md. The wavelet section is that of `lubrig analyze` with its defaults (whole
    record), computed on the trajectory in memory; every file is written once. An existing
    non-empty `out` is refused unless force (then the report's own files are replaced).
    """
    from ..figures.run import RUN_FILES, write_run_directory  # matplotlib only when drawing

    bag = Path(bag)
    out = prepare_output_dir(Path(out), force, "--out", (*RUN_FILES, PAGE, HTML_PAGE))
    config, trajectory = trajectory_from_bag(bag)
    summary = summarize(trajectory, config)
    summary["source_bag"] = str(bag.resolve())
    summary["recording"] = recording_summary(bag)  # gaps found from the samples' indices
    analysis = analyze_displacement(
        trajectory.time, trajectory.displacement, config.sample_rate, config.band.fundamental_hz,
        whole_record(),
    )
    summary = write_run_directory(out, config, trajectory, summary, analysis)
    page = out / PAGE
    page.write_text(markdown(summary, bag))
    write_html_page(page, f"Run report: {run_heading(summary)}")
    return page
