"""Per-update cost of the online wavelet analyzer after runs of 10 s, 100 s and 1000 s at 1 kHz.

Run: .venv/bin/python bench/bench_online_wavelet.py
Each run length is first streamed through the analyzer in 4096-sample pushes (the state after
the run is what matters: nothing is kept but the window), then UPDATES pushes of CHUNK samples
are timed. Modes: full analysis on every update (single and double precision FFTs), and newest
columns only (direct kernels, full analysis never due).
"""

import time

import numpy as np

from lubrig_ros.core.online import OnlineWaveletAnalyzer

DT = 1e-3
WINDOW = 4096
N_SCALES = 64
CHUNK = 10  # samples per update: 100 updates/s at 1 kHz
UPDATES = 200
RUNS_S = (10, 100, 1000)
MODES = {
    "full analysis, single": {"precision": "single", "analysis_every": 1},
    "full analysis, double": {"precision": "double", "analysis_every": 1},
    "newest columns only": {"precision": "single", "analysis_every": 10**12},
}


def stream(seconds: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = int(seconds / DT)
    for start in range(0, n, WINDOW):
        t = (start + np.arange(min(WINDOW, n - start))) * DT
        yield np.sin(2 * np.pi * 10 * t) + 0.2 * rng.standard_normal(t.size)


def time_updates(analyzer: OnlineWaveletAnalyzer) -> float:
    rng = np.random.default_rng(1)
    chunks = [rng.standard_normal(CHUNK) for _ in range(UPDATES)]
    start = time.perf_counter()
    for c in chunks:
        analyzer.push(c)
    return (time.perf_counter() - start) / UPDATES * 1e3


def main() -> None:
    print(f"window {WINDOW} samples x {N_SCALES} scales, dt {DT} s, {CHUNK} samples per update")
    print(f"{'mode':24s} " + " ".join(f"{f'{r} s run':>12s}" for r in RUNS_S) + "   (ms/update)")
    for name, kwargs in MODES.items():
        row = []
        for run in RUNS_S:
            a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=N_SCALES, **kwargs)
            for chunk in stream(run):
                a.push(chunk)
            row.append(time_updates(a))
        print(f"{name:24s} " + " ".join(f"{v:12.2f}" for v in row))
    # newest-columns methods compared: direct kernels vs one full FFT transform
    a = OnlineWaveletAnalyzer(DT, window=WINDOW, n_scales=N_SCALES, analysis_every=10**12)
    for chunk in stream(10):
        a.push(chunk)
    x = a.window_samples()
    for k in (1, 4, 16, 64):
        start = time.perf_counter()
        for _ in range(20):
            a._direct_columns(x, float(x.mean()), k)
        direct = (time.perf_counter() - start) / 20 * 1e3
        print(f"direct kernels, {k:3d} new columns: {direct:6.2f} ms")
    print(
        f"memory held: window {a.window_samples().nbytes} B, kernels "
        f"{a._k_re.nbytes + a._k_im.nbytes + a._cs_re.nbytes + a._cs_im.nbytes} B "
        f"(independent of run length)"
    )


if __name__ == "__main__":
    main()
