"""Figures of the coupling scan: the scorecard and the key measures against s = γ · A / A_default."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure

from ..figures import style

#: Named readings drawn as vertical markers: {label: s}.
Readings = dict[str, float]


def _mark(ax: Any, readings: Readings) -> None:
    for name, s in readings.items():
        ax.axvline(s, color="grey", ls=":", lw=1.0)
        ax.text(
            s,
            1.0,
            f" {name}",
            rotation=90,
            va="top",
            ha="left",
            fontsize=8,
            transform=ax.get_xaxis_transform(),
        )


def agreed_figure(s: np.ndarray, agreed: np.ndarray, total: int, readings: Readings) -> Figure:
    """Statements agreed against s."""
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    ax.plot(s, agreed, "o-", ms=3)
    ax.set_xscale("log")
    ax.set_ylim(0, total + 1)
    ax.axhline(total, color="black", lw=0.8, ls="--")
    ax.set_xlabel("coupling s = γ · A / A_default")
    ax.set_ylabel(f"statements agreed (of {total})")
    ax.set_title("Scorecard of the study's statements over the velocity coupling")
    ax.grid(True, which="both", alpha=0.3)
    _mark(ax, readings)
    fig.tight_layout()
    return fig


def measures_figure(
    s: np.ndarray, series: dict[str, tuple[np.ndarray, str, tuple[float, float] | None]], readings: Readings
) -> Figure:
    """One panel per measure against s: {title: (values, y label, study's band or None)}."""
    fig = Figure(figsize=(8, 2.6 * len(series)))
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (title, (values, label, band)) in zip(axes, series.items(), strict=True):
        ax.plot(s, values, "o-", ms=3)
        if band is not None:
            ax.axhspan(band[0], band[1], color="tab:green", alpha=0.15, label="study's statement")
            ax.legend(loc="best", fontsize=8)
        ax.set_ylabel(label)
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        _mark(ax, readings)
    axes[-1].set_xscale("log")
    axes[-1].set_xlabel("coupling s = γ · A / A_default")
    fig.tight_layout()
    return fig


def verdict_map_figure(s: np.ndarray, keys: list[str], agree: np.ndarray, readings: Readings) -> Figure:
    """Which statement agrees at which s (rows: statements, columns: scanned couplings)."""
    fig = Figure(figsize=(9, 0.22 * len(keys) + 1.6))
    ax = fig.add_subplot()
    edges = np.sqrt(s[1:] * s[:-1])
    x = np.concatenate([[s[0] ** 2 / edges[0]], edges, [s[-1] ** 2 / edges[-1]]])
    y = np.arange(len(keys) + 1) - 0.5
    binary = ListedColormap(list(style.BINARY_COLOURS), name="lubrig_binary")
    ax.pcolormesh(x, y, agree.astype(float), cmap=binary, vmin=0, vmax=1, shading="flat")
    ax.set_xscale("log")
    ax.set_yticks(range(len(keys)), keys, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("coupling s = γ · A / A_default (yellow: agrees, dark blue: differs)")
    ax.set_title("Verdict of every statement over the coupling scan")
    _mark(ax, readings)
    fig.tight_layout()
    return fig


def save(fig: Figure, path: Any, dpi: int = 100) -> Any:
    """Save a figure as PNG and return the path."""
    fig.savefig(path, dpi=dpi)
    return path
