"""`lubrig simulate`: integrate one run offline and write time series, figures and a summary.

Output directory layout (documented in docs/simulate.md):
- timeseries.csv: header `time_s,displacement_m,velocity_m_s,friction_coefficient,
  band_velocity_m_s,relative_velocity_m_s`, one row per sample, uniform sampling from t = 0;
- config.yaml: the full run configuration (feed it back with --config to repeat the run);
- summary.json: stationary measures of the second half of the run;
- time_history.png, phase.png, friction_velocity.png, mu_velocity.png (figures/timeseries.py).

An existing non-empty --out is refused unless --force (which replaces these files there).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..app import rundir
from ..app.selection import RunSelection
from ..core.presets import RunConfig
from ..core.run import simulate, summarize
from .common import add_force, add_run_selection, check_fits_in_memory, selection_from_args


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The run configuration selected and overridden by the command-line options."""
    selection: RunSelection = selection_from_args(args)
    config = selection.resolve()
    check_fits_in_memory(config.samples, config.sample_rate)
    return config


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig simulate`."""
    config = config_from_args(args)  # bad input refused before the figure modules load (seconds)
    from ..figures.run import RUN_FILES  # matplotlib, scipy.signal: only for a run that goes ahead

    out = rundir.prepare_output_dir(Path(args.out), args.force, "--out", RUN_FILES)
    started = time.perf_counter()
    trajectory = simulate(config)
    elapsed = time.perf_counter() - started
    summary = summarize(trajectory, config)
    summary["wall_time_s"] = elapsed
    from ..figures.run import write_run_directory  # matplotlib only when drawing

    write_run_directory(out, config, trajectory, summary)
    print(
        f"{config.name}: {config.duration:g} s of rig time in {elapsed:.3f} s "
        f"({config.rig.coupling_label}); x peak-to-peak {summary['x_peak_to_peak']:.3e} m, "
        f"μ {summary['mu_min']:.4g}…{summary['mu_max']:.4g}, stick fraction {summary['stick_fraction']:.2f}; "
        f"results in {out}/",
        file=sys.stdout,
    )
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig simulate`."""
    parser = subparsers.add_parser(
        "simulate",
        help="integrate one run offline (time series, figures, summary.json)",
        description="Integrate the rig offline and write timeseries.csv, config.yaml, summary.json "
        "and figures to --out (refused when --out exists and is not empty, unless --force).",
    )
    add_run_selection(parser)
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    add_force(parser)
    parser.set_defaults(func=run)
