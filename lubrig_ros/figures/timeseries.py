"""Figures of one run: time history, phase plot, friction and velocities, μ against v_rel.

Built without pyplot (no global state, no display) and returned, so callers save them and tests
inspect axes and data. Colours, labels and titles come from figures/style.py. Every figure takes
(trajectory, name, convention, rig=None): `name` is the run's name (case07 → "case 7" in the
title), `convention` the velocity-coupling convention's name or label; with `rig` the title
states γ and the μ–v figure draws that rig's friction law (else the default law).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import LogLocator, NullFormatter, NullLocator

from ..core.friction import friction_coefficient, friction_landmarks
from ..core.params import CONVENTIONS, RigParameters
from ..core.trajectory import Trajectory
from . import style

#: Points of the trajectory drawn at most in the μ–v figure (evenly strided beyond).
MAX_POINTS = 20_000
#: Decades of v_rel shown on each side of the trajectory's range in the μ–v figure.
PAD_FACTOR = 4.0

FigureMaker = Callable[..., Figure]


def _title(name: str, convention: str, rig: RigParameters | None, what: str = "") -> str:
    return style.run_title(name, rig if rig is not None else convention, what)


def time_history_figure(
    trajectory: Trajectory, name: str, convention: str, rig: RigParameters | None = None
) -> Figure:
    """Displacement x(t) in nm above the mass velocity ẋ and the band velocity v_band in m/s."""
    fig = Figure(figsize=style.WIDE, constrained_layout=True)
    ax_x, ax_v = fig.subplots(2, 1, sharex=True)
    ax_x.plot(trajectory.time, trajectory.displacement * 1e9, lw=0.8, color=style.COLOURS["displacement"])
    ax_x.set_ylabel("displacement x (nm)")
    ax_x.set_title(_title(name, convention, rig, "Time history"), fontsize=style.TITLE_SIZE)
    ax_x.grid(alpha=0.3)
    ax_v.plot(
        trajectory.time, trajectory.velocity, lw=0.8, color=style.COLOURS["velocity"], label="mass velocity ẋ"
    )
    ax_v.plot(trajectory.time, trajectory.band_velocity, label="band velocity v_band", **style.BAND_STYLE)
    ax_v.set_ylabel("velocity (m/s)")
    ax_v.set_xlabel(style.TIME)
    ax_v.legend(loc="upper right", fontsize=style.LEGEND_SIZE)
    ax_v.grid(alpha=0.3)
    return fig


def phase_figure(
    trajectory: Trajectory, name: str, convention: str, rig: RigParameters | None = None
) -> Figure:
    """Phase plot (x, ẋ), the second half of the run drawn darker (stationary part)."""
    fig = Figure(figsize=style.SQUARE, constrained_layout=True)
    ax = fig.subplots()
    half = trajectory.time >= trajectory.time[-1] / 2.0
    ax.plot(
        trajectory.displacement[~half] * 1e9,
        trajectory.velocity[~half],
        lw=0.5,
        color=style.COLOURS["transient"],
        label="first half (transient)",
    )
    ax.plot(
        trajectory.displacement[half] * 1e9,
        trajectory.velocity[half],
        lw=0.7,
        color=style.COLOURS["displacement"],
        label="second half (stationary)",
    )
    ax.set_xlabel("displacement x (nm)")
    ax.set_ylabel("velocity ẋ (m/s)")
    ax.set_title(_title(name, convention, rig, "Phase plot"), fontsize=style.TITLE_SIZE)
    ax.legend(loc="best", fontsize=style.LEGEND_SIZE)
    ax.grid(alpha=0.3)
    return fig


def friction_velocity_figure(
    trajectory: Trajectory, name: str, convention: str, rig: RigParameters | None = None
) -> Figure:
    """μ(t) above v_rel with v_band drawn dashed on top of it, above the mass velocity ẋ(t)."""
    fig = Figure(figsize=(9.0, 7.5), constrained_layout=True)
    ax_mu, ax_v, ax_m = fig.subplots(3, 1, sharex=True)
    ax_mu.plot(
        trajectory.time, trajectory.friction_coefficient, lw=0.8, color=style.COLOURS["friction_coefficient"]
    )
    ax_mu.set_ylabel(style.MU_SIGNED)
    ax_mu.set_title(_title(name, convention, rig, "Friction and velocities"), fontsize=style.TITLE_SIZE)
    ax_mu.grid(alpha=0.3)
    if np.any(trajectory.friction_coefficient < 0):
        ax_mu.axhline(0.0, color="0.3", lw=0.6)
    ax_v.plot(
        trajectory.time,
        trajectory.relative_velocity,
        lw=2.0,
        color=style.COLOURS["relative_velocity"],
        alpha=0.8,
        label="relative v_rel = v_band − γ ẋ",
    )
    ax_v.plot(
        trajectory.time, trajectory.band_velocity, label="band v_band (dashed, on top)", **style.BAND_STYLE
    )
    band_top = float(np.max(np.abs(trajectory.band_velocity)))
    if band_top > 0 and float(np.max(np.abs(trajectory.relative_velocity))) > 20.0 * band_top:
        # slips far faster than the band (stick-slip): a symmetric log axis keeps v_band visible
        ax_v.set_yscale("symlog", linthresh=0.1 * band_top)
        ax_v.set_ylabel("velocity (m/s), symlog")
    else:
        ax_v.set_ylabel("velocity (m/s)")
    ax_v.legend(loc="upper right", fontsize=style.LEGEND_SIZE)
    ax_v.grid(alpha=0.3)
    ax_m.plot(trajectory.time, trajectory.velocity, lw=0.7, color=style.COLOURS["velocity"], label="mass ẋ")
    ax_m.set_ylabel("mass velocity ẋ (m/s)")
    ax_m.set_xlabel(style.TIME)
    ax_m.grid(alpha=0.3)
    return fig


def _velocity_grid(lo: float, hi: float, linthresh: float | None) -> np.ndarray:
    """Velocities (m/s) on which the friction curve is drawn: log-spaced, both signs for symlog."""
    if linthresh is None:
        return np.logspace(np.log10(lo), np.log10(hi), 600)
    side = np.logspace(np.log10(linthresh), np.log10(max(abs(lo), abs(hi))), 400)
    core = np.linspace(-linthresh, linthresh, 201)
    return np.unique(np.concatenate([-side[::-1], core, side]))


def _symlog_ticks(lo: float, hi: float, linthresh: float) -> list[float]:
    """0 and whole decades beyond linthresh on each side, every second one past six decades."""
    first = int(np.ceil(np.log10(linthresh * 1.5)))
    sides = []
    for reach in (-lo, hi):
        last = int(np.floor(np.log10(reach))) if reach > linthresh else first - 1
        sides.append(list(range(first, last + 1)))
    step = 2 if max(len(d) for d in sides) > 6 else 1
    negative = [-(10.0**k) for k in sides[0][::-1] if (sides[0][-1] - k) % step == 0]
    positive = [10.0**k for k in sides[1] if (sides[1][-1] - k) % step == 0]
    return [*negative, 0.0, *positive]


def _zones(rig: RigParameters) -> list[tuple[int, float, float]]:
    """[(zone, |v| from, |v| to)] of the law (empty when it has no peak)."""
    peak, minimum = friction_landmarks(rig.friction)
    if peak is None:
        return []
    zones = [(1, 0.0, peak.velocity)]
    if minimum is None:
        return [*zones, (2, peak.velocity, np.inf)]
    return [*zones, (2, peak.velocity, minimum.velocity), (3, minimum.velocity, np.inf)]


def mu_velocity_figure(
    trajectory: Trajectory, name: str, convention: str, rig: RigParameters | None = None
) -> Figure:
    """The operating point (v_rel(t), μ(t)) over the friction curve μ(v_rel), zones 1/2/3 shaded.

    The x axis spans the trajectory's v_rel range widened by PAD_FACTOR each way: logarithmic when
    v_rel stays positive, symmetric-logarithmic (linear inside the stick velocity, the friction
    peak) when it reverses, so that negative μ (backward sliding) is on the curve too. Points are
    coloured by time (TIME_CMAP).
    """
    if rig is None:
        rig = RigParameters(convention=convention) if convention in CONVENTIONS else RigParameters()
    v, mu, t = trajectory.relative_velocity, trajectory.friction_coefficient, trajectory.time
    stride = max(1, v.size // MAX_POINTS)
    v, mu, t = v[::stride], mu[::stride], t[::stride]
    peak = friction_landmarks(rig.friction)[0]
    reverses = bool(np.any(v <= 0.0))
    fig = Figure(figsize=(8.0, 5.5), constrained_layout=True)
    ax = fig.subplots()
    if reverses:
        reach = PAD_FACTOR * float(np.max(np.abs(v)))
        if reach == 0.0:  # v_rel ≡ 0 (band and mass at rest): show the curve around the stick velocity
            reach = PAD_FACTOR * (peak.velocity if peak is not None else 1.0)
        linthresh = peak.velocity if peak is not None and peak.velocity < reach else reach * 1e-3
        # each side padded from its own extreme (at least to the stick velocity)
        lo = -max(PAD_FACTOR * float(max(-v.min(), 0.0)), 2.0 * linthresh)
        hi = max(PAD_FACTOR * float(max(v.max(), 0.0)), 2.0 * linthresh)
        ax.set_xscale("symlog", linthresh=linthresh, linscale=1.0)
        ax.set_xticks(_symlog_ticks(lo, hi, linthresh))
        ax.xaxis.set_minor_locator(NullLocator())
        grid = _velocity_grid(lo, hi, linthresh)
    else:
        lo, hi = float(v.min()) / PAD_FACTOR, float(v.max()) * PAD_FACTOR
        ax.set_xscale("log")
        if np.log10(hi / lo) < 3.0:  # few decades: label 1, 2, 5 × 10^n, no minor labels
            ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_minor_formatter(NullFormatter())
        grid = _velocity_grid(lo, hi, None)
    handles = []
    for zone, a, b in _zones(rig):
        spans = [(a, b)] + ([(-b, -a)] if reverses else [])
        shown = False
        for left, right in spans:
            left, right = max(left, lo), min(right, hi)
            if left < right:
                ax.axvspan(left, right, color=style.ZONE_COLOURS[zone], lw=0, zorder=0)
                shown = True
        if shown:
            label = style.ZONE_LABELS[zone].replace("\n", " ", 1).replace("\n", " ")
            handles.append(Patch(color=style.ZONE_COLOURS[zone], label=label))
    curve = friction_coefficient(grid, rig.friction)
    (line,) = ax.plot(
        grid, curve, color=style.COLOURS["curve"], lw=1.2, zorder=2, label="friction law μ(v_rel)"
    )
    points = ax.scatter(
        v, mu, c=t, cmap=style.TIME_CMAP, s=4, lw=0, zorder=3, label="operating point (v_rel(t), μ(t))"
    )
    if reverses:
        ax.axhline(0.0, color="0.3", lw=0.6, zorder=1)
        ax.axvline(0.0, color="0.3", lw=0.6, zorder=1)
    ax.set_xlim(lo, hi)
    low = min(float(np.min(curve)), float(np.min(mu)))
    high = max(float(np.max(curve)), float(np.max(mu)))
    pad = 0.08 * (high - low) if high > low else 0.1 * abs(high) + 1e-6
    ax.set_ylim(low - pad, high + pad)
    ax.set_xlabel(style.V_REL + (" — symmetric log axis" if reverses else ""))
    ax.set_ylabel(style.MU_SIGNED)
    title = _title(name, convention, rig, "Operating point on the friction curve")
    ax.set_title(title, fontsize=style.TITLE_SIZE)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(handles=[line, points, *handles], loc="best", fontsize=style.LEGEND_SIZE, framealpha=0.9)
    fig.colorbar(points, ax=ax, label=style.TIME)
    return fig


FIGURES: dict[str, FigureMaker] = {
    "time_history.png": time_history_figure,
    "phase.png": phase_figure,
    "friction_velocity.png": friction_velocity_figure,
    "mu_velocity.png": mu_velocity_figure,
}


def write_run_figures(
    out: Path, trajectory: Trajectory, name: str, convention: str, rig: RigParameters | None = None
) -> list[Path]:
    """Save every figure of FIGURES into out (style.DPI); return the paths."""
    paths = []
    for filename, make in FIGURES.items():
        make(trajectory, name, convention, rig).savefig(Path(out) / filename, dpi=style.DPI)
        paths.append(Path(out) / filename)
    return paths
