"""A run directory with its figures: app/rundir.py's files plus the PNGs (simulate, report, paper)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..app import rundir
from ..app.analysis.policy import WaveletAnalysis
from ..core.presets import RunConfig
from ..core.trajectory import Trajectory
from . import style
from .timeseries import FIGURES, write_run_figures
from .wavelet import analysis_figure

WAVELET_FIGURE = "wavelet.png"
#: Every figure a run directory may hold (the report pages show them in this order).
RUN_FIGURES = (WAVELET_FIGURE, *FIGURES)
#: Every file write_run_directory may write (what --force clears before a new run).
RUN_FILES = (rundir.TIMESERIES, rundir.CONFIG, rundir.SUMMARY, *RUN_FIGURES)


def wavelet_title(config: RunConfig) -> str:
    """Title of a run's wavelet figure: the run's name and its velocity coupling."""
    return style.run_title(config.name, config.rig, "Displacement and its wavelet power")


def write_wavelet_figure(out: Path, config: RunConfig, analysis: WaveletAnalysis) -> Path:
    """Draw wavelet.png of an analysis into out."""
    fig = analysis_figure(analysis, wavelet_title(config), config.rig.natural_frequency)
    fig.savefig(Path(out) / WAVELET_FIGURE, dpi=style.DPI)
    return Path(out) / WAVELET_FIGURE


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
    write_run_figures(out, trajectory, config.name, config.rig.convention, config.rig)
    if analysis is not None:
        write_wavelet_figure(out, config, analysis)
    return summary
