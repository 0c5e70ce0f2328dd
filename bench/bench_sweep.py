"""Sweep engine scaling: points per second on 1 and 2 local Dask workers, and the per-point overhead.

Runs one T_ramp x T_c style sweep (study band cycle, paper convention) serially and on an embedded
LocalCluster with each worker count, each into a fresh temporary directory, and prints:
  - points/s over the compute phase (first point start to last point end, cluster start excluded),
  - per point: simulation time, summary + wavelet + verdict time, and the engine overhead
    = compute phase x workers / points - mean in-worker point time (scheduling, pickling, the
    driver's fsynced writes: what the sweep machinery costs on top of the core),
  - setup+maps: everything outside the compute phase (cluster start, numba warm-up, table, maps),
    and the warm-up alone (the slowest worker).

    .venv/bin/python bench/bench_sweep.py --points 16 --duration 20 --workers 1 2
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from lubrig_ros.sweep import parse_spec, run_sweep


def spec(points: int, duration: float, wavelet: bool) -> dict:
    """A one-axis sweep of the plateau time over the study's V1 = 1e-7, V2 = 1e-6 m/s cycle."""
    return {
        "name": "bench",
        "base_case": 4,
        "wavelet": wavelet,
        "base": {"simulation": {"duration": duration}},
        "axes": [{"parameter": "band.plateau_time", "logspace": {"start": 0.01, "stop": 1.0, "num": points}}],
    }


def measure(points: int, duration: float, scheduler: str, workers: int | None, wavelet: bool) -> dict:
    """Run the sweep once in a temporary directory; return its timings."""
    sweep = parse_spec(spec(points, duration, wavelet))
    with tempfile.TemporaryDirectory() as tmp:
        clock = time.perf_counter()
        result = run_sweep(sweep, Path(tmp) / "out", workers=workers, scheduler=scheduler, progress=None)
        total = time.perf_counter() - clock
        records = [json.loads(p.read_text()) for p in (Path(tmp) / "out" / "points").glob("*.json")]
    assert result.failed == 0 and len(records) == points
    phase = max(r["finished_at"] for r in records) - min(r["started_at"] for r in records)
    n_workers = workers or 1
    point = statistics.mean(r["point_seconds"] for r in records)
    simulate = statistics.mean(r["simulate_seconds"] for r in records)
    return {
        "label": scheduler if scheduler == "serial" else f"local x{workers}",
        "points_per_s": points / phase,
        "simulate_ms": 1e3 * simulate,
        "analysis_ms": 1e3 * (point - simulate),
        "overhead_ms": 1e3 * (phase * n_workers / points - point),
        "start_s": total - phase,
        "warm_up_s": max(result.warm_up_seconds.values()),
        "total_s": total,
    }


def validation(points: int) -> None:
    """Print how long checking a grid of about `points` points takes, per point (no run)."""
    side = max(1, round(points**0.5))
    grid = {
        "name": "validate",
        "base_case": 1,
        "axes": [
            {"parameter": "rig.damping_ratio", "linspace": {"start": 0.01, "stop": 0.5, "num": side}},
            {"parameter": "rig.natural_frequency", "linspace": {"start": 10.0, "stop": 50.0, "num": side}},
        ],
    }
    parse_spec({**grid, "axes": grid["axes"][:1]})  # first use: case file, imports
    start, cpu = time.perf_counter(), time.process_time()
    n = len(parse_spec(grid).points)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
    print(f"validation of a {n}-point grid: {elapsed:.2f} s wall, {cpu / n * 1e3:.3f} ms of CPU a point")


def main() -> None:
    """Print one line per engine configuration."""
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("--points", type=int, default=16)
    parser.add_argument("--duration", type=float, default=20.0, help="rig seconds per point")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--no-wavelet", action="store_true")
    parser.add_argument(
        "--validate", type=int, metavar="N", help="only time the checking of an N-point grid, then end"
    )
    args = parser.parse_args()
    if args.validate:
        validation(args.validate)
        return
    print(f"{args.points} points x {args.duration:g} s of rig time, wavelet {not args.no_wavelet}")
    print(
        f"{'engine':10s} {'points/s':>9s} {'simulate':>10s} {'analysis':>10s} {'overhead':>10s}"
        f" {'setup+maps':>11s} {'warm-up':>8s} {'total':>7s}"
    )
    runs = [("serial", None)] + [("local", w) for w in args.workers]
    for scheduler, workers in runs:
        r = measure(args.points, args.duration, scheduler, workers, not args.no_wavelet)
        print(
            f"{r['label']:10s} {r['points_per_s']:9.2f} {r['simulate_ms']:8.1f}ms {r['analysis_ms']:8.1f}ms"
            f" {r['overhead_ms']:8.1f}ms {r['start_s']:10.2f}s {r['warm_up_s']:7.2f}s {r['total_s']:6.2f}s"
        )


if __name__ == "__main__":
    main()
