"""Figures of one run: time history, phase plot, friction coefficient with velocities over time.

Built without pyplot (no global state, no display) and returned, so callers save them and tests
inspect axes and data.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..core.integrator import Trajectory


def _title(name: str, convention: str) -> str:
    return f"{name} ({convention} convention)"


def time_history_figure(trajectory: Trajectory, name: str, convention: str) -> Figure:
    """Displacement x(t) in nm above the velocities ẋ and v_band in m/s."""
    fig = Figure(figsize=(9, 6), constrained_layout=True)
    ax_x, ax_v = fig.subplots(2, 1, sharex=True)
    ax_x.plot(trajectory.time, trajectory.displacement * 1e9, lw=0.8, color="C0")
    ax_x.set_ylabel("displacement x (nm)")
    ax_x.set_title(_title(name, convention))
    ax_x.grid(alpha=0.3)
    ax_v.plot(trajectory.time, trajectory.velocity, lw=0.8, color="C1", label="mass velocity ẋ")
    ax_v.plot(trajectory.time, trajectory.band_velocity, lw=1.0, color="k", label="band velocity")
    ax_v.set_ylabel("velocity (m/s)")
    ax_v.set_xlabel("time t (s)")
    ax_v.legend(loc="upper right", fontsize=8)
    ax_v.grid(alpha=0.3)
    return fig


def phase_figure(trajectory: Trajectory, name: str, convention: str) -> Figure:
    """Phase plot (x, ẋ), the second half of the run drawn darker (stationary part)."""
    fig = Figure(figsize=(6, 5.5), constrained_layout=True)
    ax = fig.subplots()
    half = trajectory.time >= trajectory.time[-1] / 2.0
    ax.plot(
        trajectory.displacement[~half] * 1e9, trajectory.velocity[~half], lw=0.5, color="0.7",
        label="first half (transient)",
    )
    ax.plot(
        trajectory.displacement[half] * 1e9, trajectory.velocity[half], lw=0.7, color="C0",
        label="second half",
    )
    ax.set_xlabel("displacement x (nm)")
    ax.set_ylabel("velocity ẋ (m/s)")
    ax.set_title("Phase plot — " + _title(name, convention))
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return fig


def friction_velocity_figure(trajectory: Trajectory, name: str, convention: str) -> Figure:
    """Friction coefficient μ(t) above mass, band and relative velocities over time."""
    fig = Figure(figsize=(9, 6), constrained_layout=True)
    ax_mu, ax_v = fig.subplots(2, 1, sharex=True)
    ax_mu.plot(trajectory.time, trajectory.friction_coefficient, lw=0.8, color="C3")
    ax_mu.set_ylabel("friction coefficient μ (–)")
    ax_mu.set_title("Friction and velocities — " + _title(name, convention))
    ax_mu.grid(alpha=0.3)
    ax_v.plot(trajectory.time, trajectory.band_velocity, lw=1.0, color="k", label="band v_band")
    ax_v.plot(trajectory.time, trajectory.velocity, lw=0.7, color="C1", label="mass ẋ")
    ax_v.plot(
        trajectory.time, trajectory.relative_velocity, lw=0.7, color="C2", label="relative v_rel"
    )
    ax_v.set_ylabel("velocity (m/s)")
    ax_v.set_xlabel("time t (s)")
    ax_v.legend(loc="upper right", fontsize=8)
    ax_v.grid(alpha=0.3)
    return fig


FIGURES = {
    "time_history.png": time_history_figure,
    "phase.png": phase_figure,
    "friction_velocity.png": friction_velocity_figure,
}


def write_run_figures(out: Path, trajectory: Trajectory, name: str, convention: str) -> list[Path]:
    """Save every figure of FIGURES into out (110 dpi); return the paths."""
    paths = []
    for filename, make in FIGURES.items():
        make(trajectory, name, convention).savefig(Path(out) / filename, dpi=110)
        paths.append(Path(out) / filename)
    return paths


def plotted_range(fig: Figure, axis: int = 0) -> tuple[float, float]:
    """Min and max of the y data drawn on one axes (for checks of figure content)."""
    ys = np.concatenate([line.get_ydata() for line in fig.axes[axis].get_lines()])
    return float(np.min(ys)), float(np.max(ys))
