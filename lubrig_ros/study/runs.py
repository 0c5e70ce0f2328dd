"""The study's runs and what is measured of them: the ten Table 1 cases and the stick-slip run.

`case_metrics` measures one run (a Table 1 case or the constant-velocity stick-slip run) with the
criteria of core/criteria.py into the numbers the statements of study/statements.py need; `study_configs`
and `measure` make and run the study's runs for one velocity coupling; the coupling scan
(s = γ · A / A_default, one row per coupling and run) is kept as a CSV table (`write_scan_csv`,
`read_scan_csv`, committed under docs/study/).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from ..core import criteria
from ..core.dense import mu_extremes
from ..core.friction import friction_coefficient, stick_velocity
from ..core.params import RigParameters
from ..core.presets import RunConfig
from ..core.profiles import RegularCycle
from ..core.trajectory import Trajectory

#: Damping ratios up to this count as "any (realistic) damping" in the stability statements.
REALISTIC_ZETA = 0.1
#: The 10 Hz component "disappears" when its amplitude stays below this fraction of its early
#: level (wavelet power below 1 % of it).
GONE_FRACTION = 0.1
#: The reasonable range of that choice (amplitude 3 % … 30 % of the early level), measured too so
#: that the page can show over which of them C9b/C10b hold.
GONE_FRACTIONS = (0.03, 0.05, 0.1, 0.2, 0.3)
#: Spectral peaks kept per run (strongest first) and their floor relative to the strongest.
PEAKS = 8
PEAK_FLOOR = 0.01
CASES = tuple(range(1, 11))
STICKSLIP = 0  # key of the constant-velocity (2e-8 m/s) stick-slip run among the metrics


def _finite(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def case_metrics(config: RunConfig, trajectory: Trajectory) -> dict[str, Any]:
    """Every number the statements need from one run (JSON-ready; None where not defined).

    Stationary measures use the second half of the run; the windowed amplitude uses one band
    period (one natural period for a constant band).
    """
    t, x = trajectory.time, trajectory.displacement
    half = t >= t[-1] / 2.0
    rig = config.rig
    f0 = rig.natural_frequency
    fundamental = config.band.fundamental_hz
    period = 1.0 / fundamental if fundamental else 1.0 / f0
    mu = trajectory.friction_coefficient
    peaks = criteria.spectral_peaks(x[half], config.sample_rate, count=PEAKS, floor=PEAK_FLOOR)
    tr = criteria.transient(t, x, period)
    out: dict[str, Any] = {
        "velocity_coupling": rig.velocity_factor,
        "coupling_strength": rig.coupling_strength,
        "x_peak_to_peak": float(np.ptp(x[half])),
        "mu_min": float(mu[half].min()),
        "mu_max": float(mu[half].max()),
        "stick_fraction": criteria.stick_fraction(
            trajectory.relative_velocity[half], stick_velocity(rig.friction)
        ),
        "peak_frequencies_hz": [f for f, _ in peaks],
        "peak_amplitudes": [a for _, a in peaks],
        "first_amplitude": tr.first,
        "stationary_amplitude": tr.stationary,
        "overshoot": _finite(tr.overshoot),
        "overshoot_time": tr.peak_time,
        "drift": _finite(tr.drift),
        "settling_time": _finite(tr.settling_time),
        "mu_band_r2": _finite(
            criteria.explained_fraction(
                mu[half], friction_coefficient(trajectory.band_velocity[half], rig.friction)
            )
        ),
        "f0_gone_time": _finite(criteria.disappearance_time(t, x - x.mean(), f0, fraction=GONE_FRACTION)),
        "f0_gone_times": [
            criteria.disappearance_time(t, x - x.mean(), f0, fraction=f) for f in GONE_FRACTIONS
        ],
    }
    start = int(np.argmax(half))
    dense = mu_extremes(trajectory, rig, config.rtol, start)
    out.update(mu_min_dense=dense.mu_min, mu_max_dense=dense.mu_max, mu_dense_resolution=dense.resolution)
    centres, amplitude = criteria.component_amplitude(t, x - x.mean(), f0, window=1.0)
    after = centres >= 0.5
    reach = np.nonzero(after & (amplitude >= 0.3 * amplitude[after].max()))[0]
    stop = float(centres[reach[0]]) if reach.size and centres[reach[0]] > 1.5 else 5.0
    pick = after & (centres <= stop)
    out["f0_growth_rate"] = _finite(criteria.log_slope(centres[pick], amplitude[pick]))
    out["f0_amplitude_late"] = float(amplitude[centres >= t[-1] / 2.0].mean())
    band = config.band
    out.update(growth_v1=None, growth_v2=None, separation=None)
    if isinstance(band, RegularCycle):
        rates = {}
        for key, level in (("growth_v1", band.low_velocity), ("growth_v2", band.high_velocity)):
            found = criteria.plateau_growth_rates(
                t, x, trajectory.band_velocity, level, 1.0 / f0, start=t[-1] / 2.0
            )
            rates[key] = float(np.median(found)) if found else None
        out.update(rates)
        labels = np.where(
            np.isclose(trajectory.band_velocity, band.low_velocity, rtol=1e-9, atol=0.0),
            1,
            np.where(np.isclose(trajectory.band_velocity, band.high_velocity, rtol=1e-9, atol=0.0), 2, 0),
        )
        labels = np.where(half, labels, 0)
        if (labels == 1).sum() >= 4 and (labels == 2).sum() >= 4:
            out["separation"] = _finite(
                criteria.limit_cycle_separation(x, trajectory.velocity / rig.angular_frequency, labels, 1, 2)
            )
    return out


Metrics = dict[int, dict[str, Any]]


def rig_with_coupling(rig: RigParameters, coupling: str | float) -> RigParameters:
    """The rig with a named convention or an explicit γ."""
    return replace(rig, velocity_coupling=coupling)


def study_configs(coupling: str | float, duration: float = 20.0) -> dict[int, RunConfig]:
    """The ten Table 1 cases (1–10) and the 2e-8 m/s stick-slip run (key 0) with this coupling."""
    from ..core.presets import config_dir, load_case, load_config

    configs = {STICKSLIP: load_config(config_dir() / "stickslip.yaml")}
    configs.update({n: load_case(n) for n in CASES})
    return {n: c.with_overrides(velocity_coupling=coupling, duration=duration) for n, c in configs.items()}


def measure(coupling: str | float, duration: float = 20.0) -> Metrics:
    """Simulate every study run with this coupling and return their metrics."""
    from ..core.run import simulate

    return {n: case_metrics(c, simulate(c)) for n, c in study_configs(coupling, duration).items()}


# --- coupling scan table (one row per coupling s and run; committed under docs/study/) ------------

#: Metric columns of the scan table, in order; list-valued ones are written space-separated.
SCAN_LISTS = ("peak_frequencies_hz", "peak_amplitudes", "f0_gone_times")


def scan_rows(scan: dict[float, Metrics]) -> list[dict[str, Any]]:
    """Flat rows (s, case, metrics…) of a scan {s: {case: metrics}}; case 0 is the stick-slip run."""
    rows = []
    for s in sorted(scan):
        for case in sorted(scan[s]):
            rows.append({"s": s, "case": case, **scan[s][case]})
    return rows


def write_scan_csv(path: Any, scan: dict[float, Metrics]) -> None:
    """Write the scan table as CSV (repr-exact floats, empty for None, lists space-separated)."""
    import csv
    from pathlib import Path

    rows = scan_rows(scan)
    if not rows:
        raise InputError("the scan holds no rows")
    columns = list(rows[0])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in rows:
            cells = []
            for key in columns:
                value = row.get(key)
                if key in SCAN_LISTS:
                    cells.append(" ".join(repr(float(v)) for v in value or ()))
                elif value is None:
                    cells.append("")
                else:
                    cells.append(repr(value))
            writer.writerow(cells)
    tmp.replace(path)


def read_scan_csv(path: Any) -> dict[float, Metrics]:
    """Read a table written by write_scan_csv back into {s: {case: metrics}}."""
    import csv
    from pathlib import Path

    scan: dict[float, Metrics] = {}
    with Path(path).open(newline="") as handle:
        for row in csv.DictReader(handle):
            s, case = float(row.pop("s")), int(row.pop("case"))
            metrics: dict[str, Any] = {}
            for key, text in row.items():
                if key in SCAN_LISTS:
                    metrics[key] = [float(v) for v in text.split()]
                else:
                    metrics[key] = float(text) if text != "" else None
            scan.setdefault(s, {})[case] = metrics
    return scan
