"""Design maps of a sweep table: amplitude, μ range, stick fraction, frequency ratio, linear verdict.

Two-axis grids are drawn as maps over the axis values (log axes for log-spaced axes); one axis as a
curve; sampled designs (random, Latin hypercube) and grids with more axes as scatter plots over the
first two axes. Failed points are left blank. Built on matplotlib Figures without pyplot.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm, Normalize
from matplotlib.figure import Figure

from . import style

#: (file name, column, colour-bar label, log colour scale)
MAPS = (
    ("map_amplitude.png", "x_peak_to_peak", "stationary x peak-to-peak (m)", True),
    ("map_mu_range.png", "mu_range", "μ_max − μ_min (stationary)", True),
    ("map_stick_fraction.png", "stick_fraction", "stick fraction (stationary)", False),
    ("map_frequency.png", "frequency", "dominant frequency / band fundamental", False),
    ("map_linear.png", "linear_stable", "linear verdict (Routh–Hurwitz)", False),
)


def _edges(centers: np.ndarray, log: bool) -> np.ndarray:
    c = np.log(centers) if log else centers.astype(float)
    if c.size == 1:
        mid = np.array([c[0] - 0.5, c[0] + 0.5]) if not log else np.array([c[0] - 0.1, c[0] + 0.1])
    else:
        inner = (c[1:] + c[:-1]) / 2.0
        mid = np.concatenate(([2 * c[0] - inner[0]], inner, [2 * c[-1] - inner[-1]]))
    return np.exp(mid) if log else mid


def _numeric(values: list[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _positions(values: list[Any]) -> tuple[np.ndarray, list[str] | None]:
    """Plot coordinates of axis values, and tick labels for text values (else None).

    Numbers stay as they are; text (e.g. rig.convention) becomes the index of each distinct value
    in order of first appearance.
    """
    if _numeric(values):
        return np.asarray(values, dtype=float), None
    labels = list(dict.fromkeys(str(v) for v in values))
    return np.array([labels.index(str(v)) for v in values], dtype=float), labels


def _metric(data: dict[str, list[Any]], column: str) -> tuple[np.ndarray, str | None]:
    """Values to colour by (NaN for failed/missing) and, for the frequency map, its caption."""
    ok = np.array([s == "ok" for s in data["status"]])
    if column == "frequency":
        freq = [
            w if w is not None else d
            for w, d in zip(data["wavelet_frequency_hz"], data["dominant_frequency_hz"], strict=True)
        ]
        fund = data["band_fundamental_hz"]
        if any(f is not None for f in fund):
            values = [f / b if f is not None and b else None for f, b in zip(freq, fund, strict=True)]
            note = "dominant frequency / band fundamental"
        else:
            values = [
                f / n if f is not None else None
                for f, n in zip(freq, data["natural_frequency_hz"], strict=True)
            ]
            note = "dominant frequency / natural frequency (constant band)"
    else:
        values, note = data[column], None
    array = np.array([np.nan if v is None else float(v) for v in values])
    array[~ok] = np.nan
    return array, note


def _norm(values: np.ndarray, log: bool) -> Normalize:
    finite = values[np.isfinite(values)]
    positive = finite[finite > 0]
    if log and positive.size:
        low, high = positive.min(), positive.max()
        return LogNorm(low, high if high > low else low * 10)
    if finite.size:
        low, high = finite.min(), finite.max()
        return Normalize(low, high if high > low else low + 1)
    return Normalize(0, 1)


def map_figure(
    data: dict[str, list[Any]],
    axes: list[dict[str, Any]],
    column: str,
    label: str,
    log: bool,
    title: str,
) -> Figure:
    """One map (2-axis grid), curve (1 axis) or scatter (other designs) of `column`."""
    values, note = _metric(data, column)
    label = note or label
    fig = Figure(figsize=(6.4, 4.8), constrained_layout=True)
    ax = fig.add_subplot()
    cmap: str | ListedColormap = style.MAP_CMAP
    norm = _norm(values, log)
    if column == "linear_stable":
        cmap = ListedColormap(list(style.BINARY_COLOURS), name="lubrig_binary")
        norm = BoundaryNorm([-0.5, 0.5, 1.5], 2)
    x_axis = axes[0]
    x = data[x_axis["parameter"]]
    x_num = _numeric(x)
    grid = all(a["kind"] in ("values", "linspace", "logspace") for a in axes)
    if len(axes) == 1:
        order = np.argsort(x) if x_num else np.arange(len(x))
        xs = np.asarray(x, dtype=float)[order] if x_num else np.arange(len(x))
        ax.plot(xs, values[order], "o-")
        ax.set_ylabel(label)
        if log and np.nanmin(values, initial=np.inf) > 0:
            ax.set_yscale("log")
        if not x_num:
            ax.set_xticks(xs, [str(v) for v in np.asarray(x, dtype=object)[order]])
    elif grid and len(axes) == 2:
        (cx, x_labels), (cy, y_labels) = _positions(axes[0]["values"]), _positions(axes[1]["values"])
        matrix = np.full((cx.size, cy.size), np.nan)
        for index, value in zip(data["index"], values, strict=True):
            matrix[index // cy.size, index % cy.size] = value
        sx, sy = np.argsort(cx), np.argsort(cy)
        mesh = ax.pcolormesh(
            _edges(cx[sx], axes[0]["log"] and x_labels is None),
            _edges(cy[sy], axes[1]["log"] and y_labels is None),
            np.ma.masked_invalid(matrix[sx][:, sy].T),
            cmap=cmap,
            norm=norm,
        )
        ax.plot(*np.meshgrid(cx, cy), "k.", markersize=2)
        bar = fig.colorbar(mesh, ax=ax, label=label)
    else:
        y_axis = axes[1]
        xs, x_labels = _positions(x)
        ys, y_labels = _positions(data[y_axis["parameter"]])
        scatter = ax.scatter(xs, ys, c=values, cmap=cmap, norm=norm, edgecolors="k", linewidths=0.3)
        failed = ~np.isfinite(values)
        ax.scatter(xs[failed], ys[failed], marker="x", color="grey", label="failed / none")
        bar = fig.colorbar(scatter, ax=ax, label=label)
    if len(axes) >= 2:
        if x_labels is not None:
            ax.set_xticks(np.arange(len(x_labels)), x_labels)
        if y_labels is not None:
            ax.set_yticks(np.arange(len(y_labels)), y_labels)
        ax.set_ylabel(axes[1]["parameter"])
        if axes[1]["log"] and y_labels is None:
            ax.set_yscale("log")
        if column == "linear_stable":
            bar.set_ticks([0, 1], labels=["unstable", "stable"])
    ax.set_xlabel(x_axis["parameter"])
    if x_axis["log"] and x_num:
        ax.set_xscale("log")
    extra = f" ({len(axes) - 2} more axes overlaid)" if len(axes) > 2 else ""
    ax.set_title(f"{title}: {label}{extra}", fontsize=9)
    return fig


def write_maps(table_path: str | Path, directory: str | Path) -> list[Path]:
    """Draw every map of MAPS from a sweep's results.parquet into directory; return the paths."""
    table = pq.read_table(table_path)
    metadata = table.schema.metadata or {}
    axes = json.loads(metadata[b"lubrig_sweep_axes"])
    data = table.to_pydict()
    title = Path(directory).name
    paths = []
    for name, column, label, log in MAPS:
        fig = map_figure(data, axes, column, label, log, title)
        path = Path(directory) / name
        fig.savefig(path, dpi=110)
        paths.append(path)
    return paths
