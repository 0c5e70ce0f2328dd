"""The run directory: one home for what `lubrig simulate`, `lubrig analyze` and reports write.

Layout (docs/simulate.md):

- timeseries.csv — header CSV_HEADER, one row per sample; the columns are core's
  Trajectory.COLUMNS (field → column name with its SI unit), so the schema has one source;
- config.yaml — the full RunConfig (feed it back with --config to repeat the run);
- summary.json — stationary measures (core.run.summarize) plus optional sections such as
  "wavelet" (app/analysis/policy.py); written atomically;
- figures (*.png) — drawn by the callers (figures/), not here: this layer has no matplotlib.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import LubrigError
from ..core.presets import RunConfig
from ..core.trajectory import Trajectory
from .fileio import write_text_atomic

TIMESERIES = "timeseries.csv"
CONFIG = "config.yaml"
SUMMARY = "summary.json"
#: CSV column names in file order, derived from the Trajectory (name with unit, e.g. time_s).
CSV_COLUMNS: tuple[str, ...] = tuple(column for _, column in Trajectory.COLUMNS)
CSV_HEADER = ",".join(CSV_COLUMNS)
#: Number format of the CSV: every float64 written so that it reads back bit for bit.
CSV_FORMAT = "%.17g"


class RunDirError(LubrigError, ValueError):
    """A run directory is missing, incomplete or unreadable; the message is one user-facing line."""


def check_output_dir(out: Path, option: str = "--out") -> Path:
    """Refuse an output path that exists and is not a directory (before any work)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunDirError(f"{option} {str(out)!r} exists and is not a directory")
    return out


def prepare_output_dir(
    out: Path, force: bool = False, option: str = "--out", owned: Sequence[str] = ()
) -> Path:
    """Refuse an existing non-empty output directory unless force; with force clear what is owned.

    `owned` names the files and folders the command writes (e.g. timeseries.csv, the figures,
    runs/): with force those that exist are removed first, so no stale output of an earlier run
    (another case's wavelet.png) is left beside the new one; anything else in the folder is kept.
    Returns out (not created here). RunDirError names the folder, a few of its entries and --force.
    """
    import shutil

    out = check_output_dir(Path(out), option)
    if not out.is_dir():
        return out
    entries = sorted(p.name for p in out.iterdir())
    if entries and not force:
        shown = ", ".join(entries[:3]) + (", …" if len(entries) > 3 else "")
        raise RunDirError(
            f"{option} {str(out)!r} exists and is not empty ({len(entries)} entries: {shown}); "
            "pass --force to replace its contents, or choose a new folder"
        )
    for name in owned:
        path = out / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()
    return out


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON atomically (temporary file, then rename) so a reader never sees half a file."""
    write_text_atomic(Path(path), json.dumps(data, indent=2) + "\n")


def write_timeseries(path: Path, trajectory: Trajectory) -> None:
    """timeseries.csv of a trajectory (columns CSV_COLUMNS, full float64 precision)."""
    columns = np.column_stack(list(trajectory.as_columns().values()))
    np.savetxt(path, columns, delimiter=",", header=CSV_HEADER, comments="", fmt=CSV_FORMAT)


def write_run(out: Path, config: RunConfig, trajectory: Trajectory, summary: dict[str, Any]) -> Path:
    """Write timeseries.csv, config.yaml and summary.json into out (created); return out."""
    out = check_output_dir(Path(out))
    out.mkdir(parents=True, exist_ok=True)
    write_timeseries(out / TIMESERIES, trajectory)
    write_text_atomic(out / CONFIG, config.to_yaml())
    write_json(out / SUMMARY, summary)
    return out


def _require(directory: Path, names: Sequence[str]) -> None:
    if not directory.is_dir():
        raise RunDirError(f"{directory}: no such directory (expected `lubrig simulate` output)")
    for name in names:
        path = directory / name
        if not path.is_file():
            raise RunDirError(f"{path}: missing (expected `lubrig simulate` output)")


def read_summary(directory: Path) -> dict[str, Any]:
    """summary.json of a run directory as a dict."""
    directory = Path(directory)
    _require(directory, (SUMMARY,))
    path = directory / SUMMARY
    try:
        summary = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise RunDirError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(summary, dict):
        raise RunDirError(f"{path}: expected a JSON object")
    return summary


def read_timeseries(directory: Path, columns: Sequence[str] = CSV_COLUMNS) -> dict[str, np.ndarray]:
    """The named columns of timeseries.csv (by header name, any order in the file)."""
    directory = Path(directory)
    _require(directory, (TIMESERIES,))
    path = directory / TIMESERIES
    with path.open() as handle:
        header = [name.strip() for name in handle.readline().split(",")]
    missing = [name for name in columns if name not in header]
    if missing:
        raise RunDirError(f"{path}: header lacks {missing}; expected columns {list(CSV_COLUMNS)}")
    try:
        data = np.loadtxt(
            path, delimiter=",", skiprows=1, usecols=[header.index(c) for c in columns], ndmin=2
        )
    except ValueError as exc:
        raise RunDirError(f"{path}: unreadable numbers ({exc})") from None
    return {name: data[:, i] for i, name in enumerate(columns)}


def update_summary(directory: Path, key: str, section: Any) -> dict[str, Any]:
    """Set summary[key] = section in summary.json (other keys kept); return the new summary."""
    summary = read_summary(directory)
    summary[key] = section
    write_json(Path(directory) / SUMMARY, summary)
    return summary
