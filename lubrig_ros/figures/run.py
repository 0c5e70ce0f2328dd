"""A run directory with its figures: app/rundir.py's files plus the PNGs (simulate, report, paper)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..app import rundir
from ..app.analysis import WaveletAnalysis
from ..core.integrator import Trajectory
from ..core.presets import RunConfig
from .timeseries import write_run_figures
from .wavelet import analysis_figure

WAVELET_FIGURE = "wavelet.png"


def write_run_directory(
    out: Path,
    config: RunConfig,
    trajectory: Trajectory,
    summary: dict[str, Any],
    analysis: WaveletAnalysis | None = None,
) -> dict[str, Any]:
    """Write timeseries.csv, config.yaml, summary.json and the figures once; return the summary.

    With an analysis its section is stored as summary["wavelet"] and wavelet.png is drawn.
    """
    out = Path(out)
    if analysis is not None:
        summary = dict(summary, wavelet=dict(analysis.summary_section(), figure=WAVELET_FIGURE))
    rundir.write_run(out, config, trajectory, summary)
    write_run_figures(out, trajectory, config.name, config.rig.convention)
    if analysis is not None:
        title = f"{out.name}: displacement and its wavelet power"
        fig = analysis_figure(analysis, title, config.rig.natural_frequency)
        fig.savefig(out / WAVELET_FIGURE, dpi=120)
    return summary
