"""Study-style wavelet figure: time history above its wavelet power spectrum.

The spectrum is drawn over time and frequency (Hz, log axis) with the cone of influence hatched
and the 95 % significance level as a black contour, in the perceptually uniform POWER_CMAP of
figures/style.py. The frequency axis runs from the lowest analysed frequency to one octave above
the highest frequency the run needs (f0, the band fundamental and its harmonics up to the 3rd, the
dominant components), not to the analysis' fmax (rate / 4). Marks that would print on top of each
other (case 7: f0 = band fundamental = 10 Hz) share one label. Built without pyplot.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter

from ..app.analysis.policy import WaveletAnalysis
from ..core.wavelet import WaveletResult
from . import style

#: Columns drawn at most (the power is strided in time beyond that; it is smooth at those scales).
MAX_COLUMNS = 2000
#: Decades of power shown below the maximum.
POWER_DECADES = 4.0
#: Band harmonics marked (and kept inside the frequency axis): k · f_band for k ≤ this.
BAND_HARMONICS = 3
#: Smallest vertical distance of two mark labels, as a fraction of the spectrum's height; closer
#: marks share one label (an 8 pt label is about 0.04 of the panel).
LABEL_GAP = 0.06
#: Components weaker than this fraction of the strongest do not widen the frequency axis.
AXIS_COMPONENT_POWER = 0.01


def _hz(value: float, _position: object = None) -> str:
    return f"{value:g}"


def _hz_minor(value: float, _position: object = None) -> str:
    """Minor ticks of the log frequency axis: only 2 and 5 × 10^n are labelled."""
    if value <= 0:
        return ""
    leading = round(value / 10.0 ** np.floor(np.log10(value)), 6)
    return f"{value:g}" if leading in (2.0, 5.0) else ""


def frequency_limits(freqs: np.ndarray, needed_hz: list[float]) -> tuple[float, float]:
    """(lowest, highest) frequency shown: the analysed range cut one octave above what is needed."""
    low, high = float(freqs.min()), float(freqs.max())
    inside = [f for f in needed_hz if f and low <= f <= high]
    if not inside:
        return low, high
    return low, min(high, 2.0 * max(inside))


def _place_marks(marks_hz: dict[str, float], low: float, high: float) -> list[tuple[float, list[str], float]]:
    """Group marks whose labels would overlap: [(y axes fraction, names, frequency)], low to high."""
    span = np.log(high / low)
    placed: list[tuple[float, list[str], float]] = []
    for name, value in sorted(marks_hz.items(), key=lambda item: item[1]):
        if not value or not low <= value <= high:
            continue
        y = float(np.log(value / low) / span)
        if placed and y - placed[-1][0] < LABEL_GAP:
            placed[-1][1].append(name)
            continue
        placed.append((y, [name], value))
    return placed


def _mark_label(names: list[str], frequencies: dict[str, float]) -> str:
    values = [frequencies[n] for n in names]
    if max(values) <= 1.001 * min(values):  # the same frequency: one number
        return " = ".join(names) + f" {values[0]:.3g} Hz"
    return ", ".join(f"{n} {v:.3g} Hz" for n, v in zip(names, values, strict=True))


def wavelet_figure(
    result: WaveletResult,
    signal: np.ndarray,
    signal_label: str = "displacement x − mean (nm)",
    title: str | None = None,
    marks_hz: dict[str, float] | None = None,
    needed_hz: list[float] | None = None,
    signal_scale: float = 1e9,
) -> Figure:
    """Time history (top) and normalized wavelet power with COI and significance (bottom).

    signal is the analysed series on result.time (m; drawn × signal_scale, nm by default);
    marks_hz draws labelled horizontal lines, e.g. {"f0": 10.0, "f_band": 3.33}; the frequency
    axis ends one octave above the highest of marks_hz and needed_hz (frequency_limits).
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

    ax_t.plot(t, np.asarray(signal) * signal_scale, lw=0.6, color=style.COLOURS["displacement"])
    ax_t.set_ylabel(signal_label)
    ax_t.grid(alpha=0.3)
    if title:
        ax_t.set_title(title, fontsize=style.TITLE_SIZE)

    top = float(power.max()) if power.size and power.max() > 0 else 1.0
    norm = LogNorm(vmin=top * 10.0**-POWER_DECADES, vmax=top)
    mesh = ax_w.pcolormesh(
        ts, freqs, np.clip(power, norm.vmin, None), norm=norm, cmap=style.POWER_CMAP, shading="nearest"
    )
    if np.any(ratio >= 1.0) and np.any(ratio < 1.0):
        ax_w.contour(ts, freqs, ratio, levels=[1.0], colors="k", linewidths=0.8)
    coi_freq = 1.0 / np.maximum(result.coi[::stride], 1e-12)
    ax_w.fill_between(ts, coi_freq, freqs.min(), color="white", alpha=0.45, hatch="xx", edgecolor="0.4", lw=0)
    marks = {k: float(v) for k, v in (marks_hz or {}).items() if v}
    low, high = frequency_limits(freqs, [*marks.values(), *(needed_hz or [])])
    for y, names, _value in _place_marks(marks, low, high):
        for name in names:
            ax_w.axhline(marks[name], color="w", ls="--" if name in ("f0", "f_band") else ":", lw=0.8)
        top = y > 1.0 - LABEL_GAP
        ax_w.text(
            0.01,
            y,
            _mark_label(names, marks),
            transform=ax_w.transAxes,
            color="w",
            va="top" if top else "bottom",
            ha="left",
            fontsize=style.MARK_SIZE,
            bbox={"facecolor": "black", "alpha": 0.45, "pad": 1.0, "lw": 0},
        )
    ax_w.set_yscale("log")
    ax_w.yaxis.set_major_formatter(FuncFormatter(_hz))
    ax_w.yaxis.set_minor_formatter(FuncFormatter(_hz_minor))
    ax_w.set_ylim(low, high)
    ax_w.set_xlim(t[0], t[-1])
    ax_w.set_xlabel(style.TIME)
    ax_w.set_ylabel(style.FREQUENCY)
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
    """wavelet_figure of an app.analysis.policy result: f0, the band fundamental and its harmonics marked.

    The frequency axis keeps the dominant components of at least AXIS_COMPONENT_POWER of the
    strongest (frequency_limits).
    """
    marks: dict[str, float] = {}
    if natural_frequency_hz:
        marks["f0"] = float(natural_frequency_hz)
    band = analysis.fundamental_hz
    if band:
        marks["f_band"] = float(band)
        for k in range(2, BAND_HARMONICS + 1):
            marks[f"{k} f_band"] = k * float(band)
    strongest = max((c.power for c in analysis.components), default=0.0)
    needed = [c.frequency_hz for c in analysis.components if c.power >= AXIS_COMPONENT_POWER * strongest]
    return wavelet_figure(analysis.wavelet, analysis.signal, title=title, marks_hz=marks, needed_hz=needed)
