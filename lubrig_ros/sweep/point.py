"""One sweep point: a full core simulation, its summary, wavelet components and linear verdict.

run_point is a plain top-level function of a picklable Point, so it runs unchanged in this process,
in a local Dask worker process or on a remote Dask worker. It never raises: a failure becomes a
record with status "error" and the error text, so one bad point does not stop the sweep.
"""

from __future__ import annotations

import math
import os
import socket
import time
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np

from ..app.analysis.policy import DEFAULT_POLICY, AnalysisError, analyze_displacement
from ..core.presets import RunConfig, from_mapping
from ..core.run import simulate, summarize
from ..core.stability import linear_stability
from ..core.trajectory import Trajectory
from .spec import Point

#: summarize() keys copied into the table unchanged (so a sweep point equals a direct run exactly).
SUMMARY_KEYS = (
    "x_peak_to_peak",
    "mu_min",
    "mu_max",
    "stick_fraction",
    "stick_threshold_m_s",
    "band_fundamental_hz",
    "natural_frequency_hz",
    "samples",
    "convention",
    "dominant_frequencies_hz",
    "spectral_amplitudes",
)
#: Stationary windows with peak-to-peak <= this x max|x| are steady sliding (no frequency).
STEADY_RELATIVE_PTP = 1e-12
#: Wavelet components kept per point (the strongest of app/analysis/policy.py's list).
WAVELET_COMPONENTS = 3


def wavelet_columns(config: RunConfig, trajectory: Trajectory | None) -> dict[str, Any]:
    """Wavelet dominant components of the stationary half (app/analysis/policy.py's one policy)."""
    empty: dict[str, Any] = {
        "wavelet_frequency_hz": None,
        "wavelet_power": None,
        "wavelet_label": None,
        "wavelet_harmonic": None,
        "wavelet_frequencies_hz": [],
        "wavelet_error": None,
    }
    if trajectory is None:
        return empty
    try:
        analysis = analyze_displacement(
            trajectory.time,
            trajectory.displacement,
            config.sample_rate,
            config.band.fundamental_hz,
            DEFAULT_POLICY,
        )
    except AnalysisError as exc:  # record too short for the transform: keep the point, say why
        return {**empty, "wavelet_error": str(exc)}
    components = analysis.components[:WAVELET_COMPONENTS]
    if not components:
        return empty
    first = components[0]
    return {
        "wavelet_frequency_hz": first.frequency_hz,
        "wavelet_power": first.power,
        "wavelet_label": first.label,
        "wavelet_harmonic": first.harmonic,
        "wavelet_frequencies_hz": [c.frequency_hz for c in components],
        "wavelet_error": None,
    }


def linear_columns(config: RunConfig) -> dict[str, Any]:
    """Routh–Hurwitz verdict at the band's lowest steady velocity (cycle: V1, and V2 must agree).

    Constant band: its velocity (0 raises: no sliding equilibrium). Cycle: stable only if both
    plateaus are; ζ_crit is the larger. Sine: its mean velocity. Table: the lowest table velocity
    > 0 (a profile starting from rest has 0 among them). A cycle, sine or table with no velocity
    > 0 has no sliding equilibrium to judge: the linear columns are null.
    """
    velocities = list(config.band.verdict_velocities())  # each profile kind says which (core.profiles)
    if not velocities:
        return dict.fromkeys(
            ("linear_velocity_m_s", "linear_zone", "linear_stable", "critical_damping_ratio")
        )
    verdicts = [linear_stability(v, config.rig) for v in velocities]
    worst = max(verdicts, key=lambda s: (not s.stable, s.critical_damping_ratio))
    return {
        "linear_velocity_m_s": worst.band_velocity,
        "linear_zone": worst.zone,
        "linear_stable": all(s.stable for s in verdicts),
        "critical_damping_ratio": max(s.critical_damping_ratio for s in verdicts),
    }


def _measure(point: Point) -> dict[str, Any]:
    """Every result column of one point (raises on failure)."""
    clock = time.perf_counter()
    config = from_mapping(point.config)
    trajectory = simulate(config)
    simulated = time.perf_counter()
    summary = summarize(trajectory, config)
    out: dict[str, Any] = {key: summary[key] for key in SUMMARY_KEYS}
    window = trajectory.displacement[trajectory.time >= trajectory.time[-1] / 2.0]
    # a window constant to rounding (steady sliding) has no dominant frequency: the spectra of
    # its mean-subtracted rounding residue show spurious peaks, so none is reported
    steady = summary["x_peak_to_peak"] <= STEADY_RELATIVE_PTP * float(np.max(np.abs(window)))
    peaks = summary["dominant_frequencies_hz"]
    out["dominant_frequency_hz"] = peaks[0] if peaks and not steady else None
    out["mu_range"] = summary["mu_max"] - summary["mu_min"]
    if point.wavelet and steady:
        out.update(wavelet_columns(config, None))
        out["wavelet_error"] = (
            f"displacement constant in the window (peak-to-peak {summary['x_peak_to_peak']:g} m)"
        )
    elif point.wavelet:
        out.update(wavelet_columns(config, trajectory))
    frequency = out.get("wavelet_frequency_hz") or out["dominant_frequency_hz"]
    fundamental = summary["band_fundamental_hz"]
    out["frequency_ratio"] = frequency / fundamental if frequency is not None and fundamental else None
    out.update(linear_columns(config))
    out["simulate_seconds"] = simulated - clock
    return out


def point_record(point: Point, measure: Callable[[Point], dict[str, Any]]) -> dict[str, Any]:
    """Run `measure` on one point and wrap its results in the store's record (never raises).

    A failed point is data (status "error", its message and traceback, no partial results), not a
    crash of the sweep; non-finite floats become null (JSON and Parquet agree on null, not on NaN).
    """
    clock = time.perf_counter()
    record: dict[str, Any] = {
        "point_id": point.point_id,
        "index": point.index,
        "values": point.values,
        "status": "ok",
        "error": None,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
        "started_at": time.time(),
    }
    try:
        record.update(measure(point))
    except Exception as exc:
        record["status"] = "error"
        record["error"] = f"{type(exc).__name__}: {exc}"
        record["traceback"] = traceback.format_exc(limit=5)
    record["point_seconds"] = time.perf_counter() - clock
    record["finished_at"] = time.time()
    for key, value in list(record.items()):
        if isinstance(value, float) and not math.isfinite(value):
            record[key] = None
    return record


def run_point(point: Point) -> dict[str, Any]:
    """Simulate and summarize one point; return its record (never raises)."""
    return point_record(point, _measure)


def warm_up() -> float:
    """Load (or compile) the numba kernels in this process; return the seconds it took.

    Each Dask worker process pays this once; running it before the sweep keeps it out of the
    first point's time and out of the progress estimate.
    """
    clock = time.perf_counter()
    config = from_mapping({"simulation": {"duration": 0.02}})
    summarize(simulate(config), config)
    return time.perf_counter() - clock
