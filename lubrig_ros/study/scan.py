"""The coupling scan on the sweep engine: the study's runs over s = γ · A / A_default.

One sweep point per (coupling s, study run): the ten Table 1 cases and the 2e-8 m/s stick-slip
run (case 0), each simulated with γ = s (default contact area) and measured by
study.runs.case_metrics. Points run serially or on Dask like any sweep (resumable, one JSON file
per point); `run_scan` refines around every transition of the scorecard by adding the geometric
midpoints of neighbouring couplings whose verdicts differ.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..core.presets import from_mapping
from ..core.run import simulate
from ..sweep.engine import SERIAL, run_sweep
from ..sweep.point import point_record
from ..sweep.spec import Axis, Point, SweepSpec
from .runs import CASES, STICKSLIP, Metrics, case_metrics, study_configs
from .statements import transitions

#: Default scan: 1e-3 … 1, 25 log-spaced values, then refined three times around every transition.
SCAN_START, SCAN_STOP, SCAN_POINTS, SCAN_REFINE = 1e-3, 1.0, 25, 3


def scan_spec(couplings: list[float], duration: float, name: str = "coupling-scan") -> SweepSpec:
    """A sweep spec with one point per (s, run) for these couplings."""
    couplings = [float(s) for s in couplings]
    runs = (STICKSLIP, *CASES)
    points: list[Point] = []
    for s in couplings:
        configs = study_configs(s, duration)
        for run in runs:
            full = configs[run].to_dict()
            full.pop("lubrig_ros_version", None)
            digest = hashlib.sha256(json.dumps(full, sort_keys=True).encode()).hexdigest()[:8]
            index = len(points)
            points.append(Point(index, f"p{index:06d}-{digest}", {"s": s, "case": run}, full, False))
    source = {"name": name, "s": couplings, "cases": list(runs), "duration": duration}
    axes = (Axis("s", "values", values=tuple(couplings)), Axis("case", "values", values=runs))
    return SweepSpec(
        name, "scorecard metrics over the velocity coupling", "grid", axes, tuple(points), source
    )


def _study_metrics(point: Point) -> dict[str, Any]:
    config = from_mapping(point.config)
    return {"metrics": case_metrics(config, simulate(config))}


def run_study_point(point: Point) -> dict[str, Any]:
    """Simulate one study run and measure it (record for the sweep store; never raises)."""
    return point_record(point, _study_metrics)


def _collect(directory: Path, spec: SweepSpec, scan: dict[float, Metrics]) -> None:
    from ..sweep.store import SweepStore

    for record in SweepStore(directory, spec).finished().values():
        if record.get("status") != "ok":
            raise RuntimeError(f"scan point {record['values']} failed: {record.get('error')}")
        scan.setdefault(float(record["values"]["s"]), {})[int(record["values"]["case"])] = record["metrics"]


def run_scan(
    out: str | Path,
    duration: float = 20.0,
    couplings: list[float] | None = None,
    refine: int = SCAN_REFINE,
    scheduler: str = SERIAL,
    workers: int | None = None,
) -> dict[float, Metrics]:
    """Run the scan (coarse grid, then `refine` rounds around transitions) in out/level<k>/."""
    out = Path(out)
    grid = couplings or [float(s) for s in np.geomspace(SCAN_START, SCAN_STOP, SCAN_POINTS)]
    scan: dict[float, Metrics] = {}
    for level in range(refine + 1):
        spec = scan_spec(grid, duration, name=f"coupling-scan-{level}")
        directory = out / f"level{level}"
        run_sweep(
            spec,
            directory,
            scheduler=scheduler,
            workers=workers,
            figures=False,
            progress=None,
            point_function=run_study_point,
        )
        _collect(directory, spec, scan)
        if level == refine:
            break
        grid = [math.sqrt(lo * hi) for lo, hi in transitions(scan)]
        if not grid:
            break
    return scan
