"""Study-style wavelet figure: time history above its wavelet power spectrum.

The spectrum is drawn over time and frequency (Hz, log axis) with the cone of influence hatched
and the 95 % significance level as a black contour. Built on a matplotlib Figure without pyplot.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from ..app.analysis import WaveletAnalysis
from ..core.wavelet import WaveletResult

#: Columns drawn at most (the power is strided in time beyond that; it is smooth at those scales).
MAX_COLUMNS = 2000
#: Decades of power shown below the maximum.
POWER_DECADES = 4.0


def wavelet_figure(
    result: WaveletResult,
    signal: np.ndarray,
    signal_label: str = "displacement − mean (m)",
    title: str | None = None,
    marks_hz: dict[str, float] | None = None,
) -> Figure:
    """Time history (top) and normalized wavelet power with COI and significance (bottom).

    signal is the analysed series on result.time; marks_hz draws labelled horizontal lines,
    e.g. {"f0": 10.0, "band": 3.33}.
    """
    t = result.time
    stride = max(1, t.size // MAX_COLUMNS)
    ts = t[::stride]
    power = result.power[:, ::stride]
    ratio = result.significance_ratio[:, ::stride]
    freqs = result.frequencies

    fig = Figure(figsize=(9.0, 6.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=(1, 2.2), width_ratios=(40, 1))
    ax_t = fig.add_subplot(grid[0, 0])
    ax_w = fig.add_subplot(grid[1, 0], sharex=ax_t)
    ax_c = fig.add_subplot(grid[1, 1])

    ax_t.plot(t, signal, lw=0.6, color="k")
    ax_t.set_ylabel(signal_label)
    ax_t.grid(alpha=0.3)
    if title:
        ax_t.set_title(title)

    top = float(power.max()) if power.size and power.max() > 0 else 1.0
    norm = LogNorm(vmin=top * 10.0**-POWER_DECADES, vmax=top)
    mesh = ax_w.pcolormesh(
        ts, freqs, np.clip(power, norm.vmin, None), norm=norm, cmap="jet", shading="nearest"
    )
    if np.any(ratio >= 1.0) and np.any(ratio < 1.0):
        ax_w.contour(ts, freqs, ratio, levels=[1.0], colors="k", linewidths=0.8)
    coi_freq = 1.0 / np.maximum(result.coi[::stride], 1e-12)
    ax_w.fill_between(ts, coi_freq, freqs.min(), color="white", alpha=0.45, hatch="xx", edgecolor="0.4", lw=0)
    for name, value in (marks_hz or {}).items():
        if value and freqs.min() <= value <= freqs.max():
            ax_w.axhline(value, color="w", ls="--", lw=0.8)
            mid = ts[ts.size // 2]
            ax_w.text(mid, value, f"{name} {value:.3g} Hz", color="w", va="bottom", fontsize=8)
    ax_w.set_yscale("log")
    ax_w.set_ylim(freqs.min(), freqs.max())
    ax_w.set_xlim(t[0], t[-1])
    ax_w.set_xlabel("time (s)")
    ax_w.set_ylabel("frequency (Hz)")
    ax_w.set_title(
        f"wavelet power |W|²/σ² (Morlet ω0=6); black: {100 * result.level:.0f} % significance "
        f"vs AR(1) α={result.lag1:.3f}; hatched: cone of influence",
        fontsize=9,
    )
    fig.colorbar(mesh, cax=ax_c, label="normalized power |W|²/σ²")
    return fig


def analysis_figure(
    analysis: WaveletAnalysis, title: str, natural_frequency_hz: float | None = None
) -> Figure:
    """wavelet_figure of an app.analysis result, marking f0 and the band fundamental."""
    marks = {"f0": natural_frequency_hz, "band": analysis.fundamental_hz}
    return wavelet_figure(
        analysis.wavelet,
        analysis.signal,
        title=title,
        marks_hz={k: v for k, v in marks.items() if v is not None},
    )
