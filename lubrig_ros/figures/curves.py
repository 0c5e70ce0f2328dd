"""Friction curve (study's Fig. 4) and linear stability map (study's Fig. 5), plus curve tables.

The plotting functions build a matplotlib Figure without pyplot (no global state, no display
backend) and return it, so that callers can save it and tests can inspect axes and data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from lubrig_ros.core.errors import InputError

from ..core.friction import friction_coefficient, friction_minimum, friction_peak, friction_slope
from ..core.params import FrictionParameters, RigParameters
from ..core.stability import critical_damping_ratio
from . import style

#: Velocity range (m/s) of the tabulated curve: u = v0/v spans 1e3 … 1e-10 over it.
CURVE_V_MIN = 1e-15
CURVE_V_MAX = 1e-2
CSV_HEADER = "velocity_m_s,friction_coefficient,dmu_dv_s_per_m"

_ZONE_COLOURS = style.ZONE_COLOURS
_ZONE_LABELS = style.ZONE_LABELS


def friction_curve_table(
    params: FrictionParameters | None = None,
    v_min: float = CURVE_V_MIN,
    v_max: float = CURVE_V_MAX,
    points_per_decade: int = 50,
) -> np.ndarray:
    """Columns v (m/s), μ, dμ/dv (s/m) on a log-spaced grid; what the CSV and Fig. 4 show."""
    if not (0.0 < v_min < v_max) or not np.isfinite(v_max):
        raise InputError(f"velocity range [{v_min!r}, {v_max!r}] must satisfy 0 < v_min < v_max")
    decades = np.log10(v_max) - np.log10(v_min)
    v = np.logspace(np.log10(v_min), np.log10(v_max), round(float(decades) * points_per_decade) + 1)
    return np.column_stack([v, friction_coefficient(v, params), friction_slope(v, params)])


def write_friction_csv(path: str | Path, params: FrictionParameters | None = None) -> Path:
    """Write the curve table as CSV with header velocity_m_s,friction_coefficient,dmu_dv_s_per_m."""
    path = Path(path)
    table = friction_curve_table(params)
    np.savetxt(path, table, delimiter=",", header=CSV_HEADER, comments="", fmt="%.12e")
    return path


def _shade_zones(ax: Any, peak_v: float, min_v: float, lo: float, hi: float) -> None:
    """Shade and label zones 1/2/3 between the x limits lo and hi (log axis)."""
    edges = {1: (lo, peak_v), 2: (peak_v, min_v), 3: (min_v, hi)}
    for zone, (a, b) in edges.items():
        ax.axvspan(a, b, color=_ZONE_COLOURS[zone], zorder=0, lw=0)
        ax.text(
            np.sqrt(a * b),
            0.97,
            _ZONE_LABELS[zone],
            transform=ax.get_xaxis_transform(),
            ha="center",
            va="top",
            fontsize=9,
        )
    for edge in (peak_v, min_v):
        ax.axvline(edge, color="0.4", lw=0.8, ls="--", zorder=1)


def plot_friction_curve(
    params: FrictionParameters | None = None,
    v_min: float = CURVE_V_MIN,
    v_max: float = CURVE_V_MAX,
) -> Figure:
    """μ against log sliding velocity with zones, peak and minimum marked (study's Fig. 4)."""
    params = params or FrictionParameters()
    table = friction_curve_table(params, v_min, v_max, points_per_decade=100)
    peak, minimum = friction_peak(params), friction_minimum(params)
    fig = Figure(figsize=(8.0, 5.0), dpi=120, layout="constrained")
    ax = fig.add_subplot()
    _shade_zones(ax, peak.velocity, minimum.velocity, v_min, v_max)
    ax.plot(table[:, 0], table[:, 1], color="black", lw=1.6, label="μ(v)", zorder=3)
    ax.plot(
        peak.velocity,
        peak.mu,
        "o",
        color="tab:red",
        zorder=4,
        label=f"peak μ = {peak.mu:.3g} at {peak.velocity:.3g} m/s",
    )
    ax.plot(
        minimum.velocity,
        minimum.mu,
        "s",
        color="tab:blue",
        zorder=4,
        label=f"minimum μ = {minimum.mu:.4g} at {minimum.velocity:.3g} m/s",
    )
    ax.set_xscale("log")
    ax.set_xlim(v_min, v_max)
    ax.set_ylim(0.0, 1.15 * max(peak.mu, float(table[:, 1].max())))  # whole curve, room for labels
    ax.set_xlabel("sliding velocity v (m/s)")
    ax.set_ylabel("friction coefficient μ (–); odd: μ(−v) = −μ(v)")
    ax.set_title(
        f"Friction law of the lubricated interface (A = {params.contact_area:.3g} m²)",
        fontsize=style.TITLE_SIZE,
    )
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="center right", fontsize=9, framealpha=0.9)
    return fig


def plot_stability_map(
    rig: RigParameters | None = None,
    v_min: float = 1e-14,
    v_max: float = 1e-4,
    zeta_min: float = 1e-4,
    zeta_max: float | None = None,
) -> Figure:
    """Band velocity (log) × damping ratio (log): unstable region, ζ_crit(v) and zones (Fig. 5)."""
    rig = rig or RigParameters()
    peak, minimum = friction_peak(rig.friction), friction_minimum(rig.friction)
    decades = np.log10(v_max) - np.log10(v_min)
    v = np.logspace(np.log10(v_min), np.log10(v_max), int(decades * 200) + 1)
    # include the exact zone edges so the shaded region closes on them
    v = np.unique(np.concatenate([v, [peak.velocity, minimum.velocity]]))
    zeta_crit = critical_damping_ratio(v, rig)
    if zeta_max is None:  # leave ~2.5 decades above the ζ_crit maximum for the zone labels
        zeta_max = 10.0 ** np.ceil(np.log10(max(zeta_crit.max(), zeta_min)) + 2.5)
    fig = Figure(figsize=(8.0, 5.0), dpi=120, layout="constrained")
    ax = fig.add_subplot()
    _shade_zones(ax, peak.velocity, minimum.velocity, v_min, v_max)
    ax.fill_between(
        v,
        zeta_min,
        np.clip(zeta_crit, zeta_min, None),
        where=zeta_crit > zeta_min,
        color="tab:red",
        alpha=0.45,
        lw=0,
        zorder=2,
        label="unstable (ζ < ζ_crit)",
    )
    ax.plot(
        v,
        np.where(zeta_crit > 0, zeta_crit, np.nan),
        color="darkred",
        lw=1.6,
        zorder=3,
        label="ζ_crit(v) = −ω0 γ N μ′(v) / (2k)",
    )
    ax.axhline(
        rig.damping_ratio,
        color="black",
        lw=1.0,
        ls=":",
        zorder=3,
        label=f"rig damping ζ = {rig.damping_ratio:g}",
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(v_min, v_max)
    ax.set_ylim(zeta_min, zeta_max)
    ax.set_xlabel("band velocity v_band (m/s)")
    ax.set_ylabel("damping ratio ζ (–)")
    ax.set_title(
        f"Linear stability of steady sliding — {rig.coupling_label}, v_rel = v_band − γ ẋ",
        fontsize=style.TITLE_SIZE,
    )
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="lower right", fontsize=9, framealpha=0.9)
    return fig


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save a figure as PNG (report resolution) and return the path."""
    path = Path(path)
    fig.savefig(path, dpi=150)
    return path
