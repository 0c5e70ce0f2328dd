"""Per-update cost of the online wavelet analyzer at the analysis node's defaults, by run length.

Run: .venv/bin/python bench/bench_online_wavelet.py [--updates 300]

The analyzer is the analysis node's (app/analysis/session.AnalysisSession on study case 1: window,
scales, full analysis every window / 8 samples), fed as the node is fed in real time: one update
per state block of the plant's `output_block_length` samples (app/interface/contract.py). Each run length
(10 s, 100 s, 1000 s at 1 kHz) is first streamed through it (nothing is kept but the window), then
--updates pushes are timed: mean, p50, p99 and max ms per update, and how many of them ran the
full-window analysis. Beside it, in the same process: one whole-window transform from scratch
(wavelet.cwt on the window) and the direct kernels alone for k new columns, so the figures compare
in proportion. Numerics single-threaded as in a node (nodes/entry.py); `uptime` before and after.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from lubrig_ros.nodes.entry import single_threaded_numerics

single_threaded_numerics()  # before numpy is imported, as a node process does

import numpy as np  # noqa: E402

from lubrig_ros.app.analysis.session import AnalysisSession  # noqa: E402
from lubrig_ros.app.interface.contract import NODE_PARAMETERS  # noqa: E402
from lubrig_ros.app.selection import base_config  # noqa: E402
from lubrig_ros.core.online import DIRECT_COLUMNS_MAX, OnlineWaveletAnalyzer  # noqa: E402
from lubrig_ros.core.wavelet import cwt  # noqa: E402

RUNS_S = (10, 100, 1000)


def block_length() -> int:
    """The plant's output_block_length default: samples per state block in real time."""
    (param,) = (p for p in NODE_PARAMETERS["plant"] if p.name == "output_block_length")
    return int(param.default)  # type: ignore[arg-type]


def node_analyzer() -> OnlineWaveletAnalyzer:
    """The analysis node's analyzer for study case 1 with the node's default settings."""
    return AnalysisSession(base_config(case=1)).analyzer


def stream(analyzer: OnlineWaveletAnalyzer, seconds: float, chunk: int, seed: int = 0) -> None:
    """Push `seconds` of a noisy 10 Hz signal in pushes of `chunk` samples."""
    rng = np.random.default_rng(seed)
    n = int(seconds / analyzer.dt)
    for start in range(0, n, 4096):
        t = (start + np.arange(min(4096, n - start))) * analyzer.dt
        x = np.sin(2 * np.pi * 10 * t) + 0.2 * rng.standard_normal(t.size)
        for i in range(0, x.size, chunk):
            analyzer.push(x[i : i + chunk])


def time_updates(analyzer: OnlineWaveletAnalyzer, updates: int, chunk: int) -> tuple[np.ndarray, int]:
    """Wall ms of each of `updates` pushes of `chunk` samples, and how many ran the full analysis."""
    rng = np.random.default_rng(1)
    chunks = [rng.standard_normal(chunk) for _ in range(updates)]
    ms = np.empty(updates)
    full = 0
    for i, c in enumerate(chunks):
        start = time.perf_counter()
        update = analyzer.push(c)
        ms[i] = (time.perf_counter() - start) * 1e3
        full += update.window is not None
    return ms, full


def main() -> int:
    """Print the figures (see the module docstring)."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--updates", type=int, default=300, help="timed updates per run length (default 300)")
    args = parser.parse_args()
    if args.updates < 1:
        parser.error(f"--updates {args.updates}: expected >= 1")
    chunk = block_length()
    probe = node_analyzer()
    print(f"load average before: {os.getloadavg()}")
    print(
        f"analysis node defaults: window {probe.window} samples x {probe.scales.size} scales,"
        f" dt {probe.dt} s,"
        f" full analysis every {probe.analysis_every} samples, {chunk} samples per update (one state block);"
        f" BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}"
    )
    print(f"{'run':>8s} {'mean':>7s} {'p50':>7s} {'p99':>7s} {'max':>7s}  full analyses   (ms per update)")
    for run in RUNS_S:
        analyzer = node_analyzer()
        stream(analyzer, run, 4096)
        ms, full = time_updates(analyzer, args.updates, chunk)
        p50, p99 = np.percentile(ms, [50, 99])
        print(f"{run:>6d} s {ms.mean():7.3f} {p50:7.3f} {p99:7.3f} {ms.max():7.3f}  {full} of {args.updates}")
    x = probe.window_samples() if probe.samples_seen else None
    if x is None:
        stream(probe, 10, 4096)
        x = probe.window_samples()
    start = time.perf_counter()
    for _ in range(20):
        cwt(x, probe.dt, scales=probe.scales)
    scratch = (time.perf_counter() - start) / 20 * 1e3
    print(f"one whole-window transform from scratch (wavelet.cwt): {scratch:.3f} ms")
    xc = x - x.mean()
    for k in (1, chunk, 64, DIRECT_COLUMNS_MAX):
        start = time.perf_counter()
        for _ in range(20):
            probe._direct_columns(xc, k)
        direct = (time.perf_counter() - start) / 20 * 1e3
        print(f"direct kernels alone, {k:3d} new columns: {direct:7.3f} ms")
    print(f"memory held: window {x.nbytes} B, kernels {probe._kernel.nbytes} B (independent of run length)")
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
