"""Durable sweep results in DIR: one JSON file per finished point, a journal, the final table.

DIR/spec.yaml          the spec as given (plus DIR/sweep.json: fingerprint and point count)
DIR/points/<id>.json   one record per finished point, written to a temporary file, fsynced and
                       renamed: a point file is either absent or complete, whatever kills the sweep
DIR/journal.jsonl      append-only, fsynced: one line per run start and per point written, with the
                       run id, so it shows which run computed which point (and that none twice)
DIR/results.parquet    the table of every point, with the spec in its metadata

Only the driver process writes here (workers return records), so a remote Dask cluster needs no
shared filesystem.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from lubrig_ros.core.errors import InputError

from ..app.fileio import write_text_atomic
from .spec import SweepSpec

SPEC_FILE = "spec.yaml"
STATE_FILE = "sweep.json"
POINTS_DIR = "points"
JOURNAL_FILE = "journal.jsonl"
TABLE_FILE = "results.parquet"
#: Parquet key/value metadata holding the spec YAML, the axes and the fingerprint.
METADATA_SPEC = b"lubrig_sweep_spec"
METADATA_AXES = b"lubrig_sweep_axes"
METADATA_FINGERPRINT = b"lubrig_sweep_fingerprint"


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write_atomic(path: Path, text: str) -> None:
    write_text_atomic(path, text, durable=True)
    _fsync_dir(path.parent)


class SweepStore:
    """The results directory of one sweep (see the module docstring for its layout)."""

    def __init__(self, directory: str | Path, spec: SweepSpec) -> None:
        self.directory = Path(directory)
        self.spec = spec
        self.points_dir = self.directory / POINTS_DIR

    def check(self) -> None:
        """Refuse a directory holding something else, or a different sweep (no writes)."""
        d = self.directory
        if d.exists() and not d.is_dir():
            raise InputError(f"--out {str(d)!r} exists and is not a directory")
        if not d.is_dir() or not any(d.iterdir()):
            return
        state_path = d / STATE_FILE
        if not state_path.is_file():
            raise InputError(
                f"--out {str(d)!r} is a non-empty directory without {STATE_FILE}; "
                "choose a new directory or an earlier sweep's directory to resume"
            )
        try:
            state = json.loads(state_path.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"{state_path}: not valid JSON ({exc})") from None
        if state.get("fingerprint") != self.spec.fingerprint:
            raise InputError(
                f"--out {str(d)!r} holds a different sweep (fingerprint {state.get('fingerprint')!r}, "
                f"this spec {self.spec.fingerprint!r}); use a new directory"
            )

    def open(self) -> None:
        """Create the directory and record the spec (idempotent on resume)."""
        self.points_dir.mkdir(parents=True, exist_ok=True)
        _write_atomic(self.directory / SPEC_FILE, self.spec.to_yaml())
        state = {"fingerprint": self.spec.fingerprint, "points": len(self.spec.points)}
        _write_atomic(self.directory / STATE_FILE, json.dumps(state, indent=2) + "\n")

    def finished(self) -> dict[str, dict[str, Any]]:
        """Records already on disk, by point id (only ids of this spec count)."""
        ids = {p.point_id for p in self.spec.points}
        records: dict[str, dict[str, Any]] = {}
        if not self.points_dir.is_dir():
            return records
        for path in self.points_dir.glob("*.json"):
            if path.stem in ids:
                records[path.stem] = json.loads(path.read_text())
        return records

    def write(self, record: dict[str, Any], run_id: str) -> None:
        """Make one point's record durable, then journal it."""
        _write_atomic(self.points_dir / f"{record['point_id']}.json", json.dumps(record) + "\n")
        self.journal({"event": "point", "point_id": record["point_id"], "status": record["status"]}, run_id)

    def journal(self, entry: dict[str, Any], run_id: str) -> None:
        """Append one fsynced line to DIR/journal.jsonl."""
        line = json.dumps({"time": time.time(), "run": run_id, **entry}) + "\n"
        with (self.directory / JOURNAL_FILE).open("a") as handle:
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())

    def write_table(self, records: list[dict[str, Any]]) -> Path:
        """Write DIR/results.parquet from the records (sorted by point index)."""
        table = records_table(records, self.spec)
        path = self.directory / TABLE_FILE
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, path)
        return path


#: Column order of the table after the point id, index and axis columns.
COLUMNS = (
    "status",
    "error",
    "x_peak_to_peak",
    "mu_min",
    "mu_max",
    "mu_range",
    "stick_fraction",
    "stick_threshold_m_s",
    "dominant_frequency_hz",
    "dominant_frequencies_hz",
    "spectral_amplitudes",
    "wavelet_frequency_hz",
    "wavelet_power",
    "wavelet_label",
    "wavelet_harmonic",
    "wavelet_frequencies_hz",
    "wavelet_error",
    "band_fundamental_hz",
    "frequency_ratio",
    "natural_frequency_hz",
    "convention",
    "samples",
    "linear_velocity_m_s",
    "linear_zone",
    "linear_stable",
    "critical_damping_ratio",
    "simulate_seconds",
    "point_seconds",
    "worker",
    "started_at",
    "finished_at",
)
TYPES: dict[str, pa.DataType] = {
    "status": pa.string(),
    "error": pa.string(),
    "dominant_frequencies_hz": pa.list_(pa.float64()),
    "spectral_amplitudes": pa.list_(pa.float64()),
    "wavelet_frequencies_hz": pa.list_(pa.float64()),
    "wavelet_label": pa.string(),
    "wavelet_error": pa.string(),
    "wavelet_harmonic": pa.int64(),
    "convention": pa.string(),
    "samples": pa.int64(),
    "linear_zone": pa.int64(),
    "linear_stable": pa.bool_(),
    "worker": pa.string(),
}


def records_table(records: list[dict[str, Any]], spec: SweepSpec) -> pa.Table:
    """One row per point: id, index, one column per axis (dotted name), then COLUMNS."""
    rows = sorted(records, key=lambda r: r["index"])
    arrays: dict[str, pa.Array] = {
        "point_id": pa.array([r["point_id"] for r in rows], pa.string()),
        "index": pa.array([r["index"] for r in rows], pa.int64()),
    }
    for axis in spec.axes:
        values = [r["values"][axis.parameter] for r in rows]
        arrays[axis.parameter] = pa.array(values)
    for column in COLUMNS:
        arrays[column] = pa.array([r.get(column) for r in rows], TYPES.get(column, pa.float64()))
    metadata = {
        METADATA_SPEC: spec.to_yaml().encode(),
        METADATA_AXES: json.dumps(spec.axes_metadata()).encode(),
        METADATA_FINGERPRINT: spec.fingerprint.encode(),
    }
    return pa.table(arrays).replace_schema_metadata(metadata)
