"""Write a run report from a bag: study-style figures, summary.json and report.md."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..core.run import summarize
from .frombag import trajectory_from_bag

FIGURE_FILES = ("wavelet.png", "time_history.png", "phase.png", "friction_velocity.png")


def _fmt(value: Any, spec: str = ".4g") -> str:
    return format(value, spec) if isinstance(value, (int, float)) else str(value)


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
    lines = [
        f"# Run report: {summary['name']}",
        "",
        f"Recorded bag: `{bag}`. Rebuilt from the plant topics (/lubrig/state, "
        "/lubrig/friction_coefficient, /lubrig/band_velocity) and the run configuration stored "
        "in the bag (`config.yaml`). Numbers as `lubrig simulate` reports them (`summary.json`).",
        "",
        "| quantity | value |",
        "|---|---|",
        *[f"| {k} | {v} |" for k, v in rows],
        "",
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
        "## Friction coefficient with mass and band velocities",
        "",
        "![friction and velocities](friction_velocity.png)",
        "",
    ]
    return "\n".join(lines)


def write_report(bag: str | Path, out: str | Path) -> Path:
    """Write figures, timeseries.csv, config.yaml, summary.json and report.md; return report.md."""
    from ..cli.analyze import analyze_run
    from ..cli.simulate import write_run

    bag, out = Path(bag), Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a directory")
    config, trajectory = trajectory_from_bag(bag)
    summary = summarize(trajectory, config)
    summary["source_bag"] = str(bag.resolve())
    write_run(out, config, trajectory, summary)
    analyze_run(out)
    summary = json.loads((out / "summary.json").read_text())
    page = out / "report.md"
    page.write_text(markdown(summary, bag))
    return page
