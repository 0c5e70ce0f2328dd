"""The realtime timing figure of a recorded run: lateness distribution, lateness over time, gaps.

Drawn from one app.recording.lateness.RigTiming, so the figure states the numbers of the report's timing
section. Three panels:

1. the lateness distribution: a histogram with a log count axis (a handful of late samples among
   10^5 stays visible) over log-spaced lateness bins (the body, tens of µs, and the tail, tens of
   ms, both resolved), the deadline (one sample period after the due time) dashed, the sample
   count, p50, p99, max and the share later than the deadline written above it;
2. lateness over rig time, i.e. the lag of rig time behind wall time, on a log axis, with the
   deadline and the plant's max_lag bound marked (the bound stated in the recording, else the
   plant's default, and the label says which); long runs are drawn as the maximum and the median
   per time bin, so no spike is thinned away;
3. the declared gaps on the same rig-time axis: one stem per gap, its height the samples the
   plant skipped there, the largest gaps labelled with their counts.

Built without pyplot; colours, sizes and the title wording from figures/style.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator, NullFormatter

from ..app.recording.lateness import RigTiming
from . import style

TIMING_FIGURE = "timing.png"
#: Samples drawn one by one in the lateness-over-time panel; beyond, TIME_BINS bins (max, median).
MAX_POINTS = 4000
TIME_BINS = 1500
#: Bins of the lateness histogram.
HISTOGRAM_BINS = 60
#: Lateness below this (s) is drawn at it on the log axis (a sample exactly on time has 0).
LATENESS_FLOOR = 1e-6
#: Gaps labelled with their counts at most, largest first; a label is left out when it would
#: come closer to a placed one than these shares of the panel's width and height.
MAX_GAP_LABELS = 12
GAP_LABEL_SPACING = (0.03, 0.18)
RIG_TIME = "rig time t (s)"


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3g} ms"


def _plain_log(axis: Axis) -> None:
    """Decade ticks of a log axis written 0.01, 0.1, 1, 10 (not 10^n); no minor labels."""
    axis.set_major_formatter(FuncFormatter(lambda value, _pos: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def _binned(t: np.ndarray, y: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bin centres, max, median) of y over equal bins of t (ascending); NaN in empty bins."""
    edges = np.linspace(t[0], t[-1], bins + 1)
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, bins - 1)
    starts = np.flatnonzero(np.r_[True, np.diff(which) != 0])
    top = np.full(bins, np.nan)
    middle = np.full(bins, np.nan)
    top[which[starts]] = np.maximum.reduceat(y, starts)
    middle[which[starts]] = [float(np.median(part)) for part in np.split(y, starts[1:])]
    return 0.5 * (edges[:-1] + edges[1:]), top, middle


def _distribution(ax: Axes, timing: RigTiming) -> None:
    late_ms = np.maximum(timing.lateness, LATENESS_FLOOR) * 1e3
    period_ms = timing.sample_period * 1e3
    low = max(LATENESS_FLOOR * 1e3, float(late_ms.min()) / 1.5)
    top = max(float(late_ms.max()), period_ms) * 1.5
    edges = np.geomspace(low, top, HISTOGRAM_BINS + 1)
    counts, _ = np.histogram(late_ms, bins=edges)
    ax.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color=style.COLOURS["lateness"], lw=0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    _plain_log(ax.xaxis)
    ax.set_ylim(0.7, max(float(counts.max()), 1.0) * 3.0)
    ax.set_xlim(low, top)
    ax.axvline(period_ms, color=style.COLOURS["deadline"], ls="--", lw=1.2)
    share = timing.late_samples / timing.samples
    ax.set_title(
        f"{timing.samples:,} samples: p50 {_ms(timing.quantile(0.5))}, "
        f"p99 {_ms(timing.quantile(0.99))}, max {_ms(float(timing.lateness.max()))}\n"
        f"later than the deadline (dashed: one period, {_ms(timing.sample_period)}): "
        f"{timing.late_samples:,} ({100.0 * share:.3g} %)",
        fontsize=style.LEGEND_SIZE + 1,
        loc="right",
    )
    ax.set_xlabel("lateness: time from a sample's due time to its computation (ms, log)")
    ax.set_ylabel("samples (log)")
    ax.set_title("Lateness distribution", fontsize=style.TITLE_SIZE, loc="left")
    ax.grid(alpha=0.3, which="major")


def _over_time(ax: Axes, timing: RigTiming) -> None:
    t = timing.rig_time
    late = np.maximum(timing.lateness, LATENESS_FLOOR) * 1e3
    colour = style.COLOURS["lateness"]
    if late.size <= MAX_POINTS:
        breaks = np.flatnonzero(np.diff(timing.sample_index) > 1) + 1  # not drawn across a gap
        ax.plot(
            np.insert(t, breaks, np.nan),
            np.insert(late, breaks, np.nan),
            lw=0.7,
            color=colour,
            label="lateness of each sample",
        )
    else:
        centre, top, middle = _binned(t, late, TIME_BINS)
        width = _ms((t[-1] - t[0]) / TIME_BINS)
        ax.plot(centre, top, lw=0.8, color=colour, label=f"max per {width} bin")
        ax.plot(centre, middle, lw=1.0, color=colour, alpha=0.45, label="median per bin")
    ax.axhline(
        timing.sample_period * 1e3,
        color=style.COLOURS["deadline"],
        ls="--",
        lw=1.2,
        label=f"deadline: one period, {_ms(timing.sample_period)}",
    )
    bound = "the plant's" if timing.max_lag_stated else "default, not stated in the bag"
    ax.axhline(
        timing.max_lag * 1e3,
        color=style.COLOURS["max_lag"],
        lw=1.4,
        label=f"max_lag {_ms(timing.max_lag)} ({bound})",
    )
    for i, gap in enumerate(timing.gaps):
        ax.axvline(
            gap.rig_time_s,
            color=style.COLOURS["skipped"],
            lw=0.9,
            alpha=0.7,
            zorder=0,
            label="declared gap (below)" if i == 0 else None,
        )
    ax.set_yscale("log")
    _plain_log(ax.yaxis)
    low = max(LATENESS_FLOOR * 1e3, 0.5 * float(late.min()))
    high = max(float(late.max()), timing.max_lag * 1e3, timing.sample_period * 1e3)
    ax.set_ylim(low, high * (high / low) ** 0.25)  # the top fifth or so for the legend
    ax.set_ylabel("lateness (ms, log)\n= lag of rig time behind wall time")
    ax.set_title("Lateness over rig time", fontsize=style.TITLE_SIZE, loc="left")
    ax.legend(loc="upper left", fontsize=style.LEGEND_SIZE, framealpha=0.9, ncols=3)
    ax.grid(alpha=0.3, which="major")
    ax.tick_params(labelbottom=False)


def _gaps(ax: Axes, timing: RigTiming, t_end: float) -> None:
    colour = style.COLOURS["skipped"]
    ax.set_xlabel(f"{RIG_TIME}, segment {timing.segment}")
    ax.set_ylabel("skipped samples")
    if not timing.gaps:
        ax.text(
            0.5,
            0.5,
            "no declared gaps: the plant skipped no sample",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=style.LEGEND_SIZE + 1,
        )
        ax.set_yticks([])
        ax.set_title("Declared gaps", fontsize=style.TITLE_SIZE, loc="left")
        return
    x = np.array([g.rig_time_s for g in timing.gaps])
    counts = np.array([g.count for g in timing.gaps], dtype=float)
    ax.vlines(x, 0.0, counts, color=colour, lw=1.6)
    ax.plot(x, counts, "o", color=colour, ms=4)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True, nbins=4))
    top = float(counts.max()) * 1.45
    ax.set_ylim(0.0, top)
    labelled: list[tuple[float, float]] = []
    dx, dy = GAP_LABEL_SPACING[0] * t_end, GAP_LABEL_SPACING[1] * top
    for i in np.argsort(-counts, kind="stable")[:MAX_GAP_LABELS].tolist():
        if all(abs(x[i] - u) > dx or abs(counts[i] - v) > dy for u, v in labelled):
            labelled.append((float(x[i]), float(counts[i])))
            ax.annotate(
                f"{int(counts[i])}",
                (x[i], counts[i]),
                xytext=(0, 3),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=style.LEGEND_SIZE,
                color="0.15",
            )
    ax.set_title(
        f"Declared gaps: {len(timing.gaps)}, {timing.skipped:,} samples skipped "
        "(the plant's lag exceeded max_lag; counts on the stems)",
        fontsize=style.TITLE_SIZE,
        loc="left",
    )
    ax.grid(alpha=0.3, axis="x")


def timing_figure(timing: RigTiming, title: str) -> Figure:
    """The three timing panels (module docstring) under `title` (the run's, style.run_title)."""
    fig = Figure(figsize=(9.0, 9.0), constrained_layout=True)
    grid = fig.add_gridspec(3, 1, height_ratios=(3.0, 3.2, 1.6))
    ax_dist = fig.add_subplot(grid[0])
    ax_time = fig.add_subplot(grid[1])
    ax_gaps = fig.add_subplot(grid[2], sharex=ax_time)
    fig.suptitle(title, fontsize=style.TITLE_SIZE)
    _distribution(ax_dist, timing)
    t = timing.rig_time
    ends = [float(t[-1])] + [g.rig_time_s + g.count * timing.sample_period for g in timing.gaps]
    t_end = max(max(ends), timing.sample_period)
    _over_time(ax_time, timing)
    _gaps(ax_gaps, timing, t_end)
    ax_time.set_xlim(0.0, t_end)
    return fig


def write_timing_figure(out: Path, timing: RigTiming, title: str) -> Path:
    """Draw TIMING_FIGURE of a run's timing into out (style.DPI); return its path."""
    path = Path(out) / TIMING_FIGURE
    timing_figure(timing, title).savefig(path, dpi=style.DPI)
    return path
