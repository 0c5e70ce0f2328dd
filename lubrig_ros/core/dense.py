"""Extremes of μ between output samples: the stick transitions a 1 kHz record steps over.

At every stick entry the relative velocity falls through the friction peak (4.08e-12 m/s, μ = 0.161)
in well under a microsecond, so a record sampled at 1 kHz shows μ on either side of the peak and
never the peak itself. `mu_extremes` finds the true extremes of μ(v_rel(t)) over a stretch of a
run: the sample intervals where v_rel can pass an extreme of μ unseen are integrated again with the
project's integrator (core.integrator, the same law and tolerance, restarted from the sampled
state, the band linear between the two samples exactly as in the run) at `zoom` sub-samples per
interval, then `zoom` sub-samples again over the two sub-intervals around the sub-sample holding
the extreme, `levels` times or until the extreme changes by less than 1e-6 of itself (zoom 100:
1 ms → 10 µs → 200 ns → 4 ns → … → 1.6 ps at the 8th level). Zoom 100 costs a third of zoom 1000
for the same extremes (within 1e-10 on case 8 at s = 0.08).

Intervals integrated again (candidates): v_rel changes sign; |v_rel| crosses the friction peak's
velocity (a stick entry or exit); or an end of the interval lies between the peak's velocity and
`near` (1e-9 m/s: approaching stick, where the stiff friction can turn v_rel round within one
sample). Intervals with both ends stuck (|v_rel| below the peak's velocity, same sign) are not:
the mass would have to slip and stick again within one sample. Where |v_rel| crosses the velocity
of μ's minimum the minimum is taken from the curve (μ is monotone in v_rel on either side, so a
monotone crossing passes through it exactly). Everywhere else v_rel stays above `near` and
changes smoothly over a sample, so μ between samples is within the sampled range up to the
curvature of one sample interval (about 1e-7 of μ in the study's runs, measured against 1 MHz
re-integration in test/test_dense.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .friction import friction_coefficient, friction_landmarks
from .integrator import RigIntegrator
from .params import RigParameters
from .trajectory import Trajectory

#: Sub-samples per interval at each zoom level, levels at most, and the stop on the extreme's change.
ZOOM, LEVELS, CONVERGED = 100, 8, 1e-6
#: Candidate intervals: an end with |v_rel| between the friction peak's velocity and this (m/s).
NEAR = 1e-9


@dataclass(frozen=True)
class MuExtremes:
    """μ's extremes over a stretch of a run, between samples included, and how they were found."""

    mu_min: float
    mu_max: float
    time_min: float  # s
    time_max: float  # s
    sampled_min: float
    sampled_max: float
    candidates: int  # sample intervals integrated again
    resolution: float  # s: the finest sub-sample spacing used (0 when nothing was refined)

    def text(self) -> str:
        """'μ -0.1 … 0.16 (sampled 0.003 … 0.014)' for the page."""
        return (
            f"μ {self.mu_min:.3g} … {self.mu_max:.3g} between samples (sampled at 1 kHz "
            f"{self.sampled_min:.3g} … {self.sampled_max:.3g})"
        )


def _fine(
    rig: RigParameters, rtol: float, state: tuple[float, float], band: tuple[float, float], span: float
) -> Trajectory:
    """The interval of `span` s from `state` at ZOOM sub-samples, the band linear from band[0] to band[1]."""
    integrator = RigIntegrator(
        rig,
        band[0],
        sample_rate=ZOOM / span,
        rtol=rtol,
        max_step_samples=1,  # every sub-sample a step end: they are there to resolve the interval
        initial_displacement=state[0],
        initial_velocity=state[1],
    )
    samples = band[0] + (band[1] - band[0]) * np.arange(1, ZOOM + 1) / ZOOM
    head = integrator.current()
    rest = integrator.advance(samples)
    return Trajectory(
        **{name: np.concatenate([getattr(head, name), getattr(rest, name)]) for name, _ in Trajectory.COLUMNS}
    )


def _refine(
    rig: RigParameters,
    rtol: float,
    state: tuple[float, float],
    band: tuple[float, float],
    start: float,
    span: float,
    sign: float,
) -> tuple[float, float, float]:
    """Largest sign·μ over the interval by zooming: (μ, time, finest spacing)."""
    best, when, spacing = -math.inf, start, span
    for _ in range(LEVELS):
        fine = _fine(rig, rtol, state, band, span)
        values = sign * fine.friction_coefficient
        j = int(np.argmax(values))
        step = span / ZOOM
        previous, best, when, spacing = best, float(values[j]), start + j * step, step
        if abs(best - previous) <= CONVERGED * abs(best):
            break
        lo, hi = max(j - 1, 0), min(j + 1, ZOOM)
        state = (float(fine.displacement[lo]), float(fine.velocity[lo]))
        band = (float(fine.band_velocity[lo]), float(fine.band_velocity[hi]))
        start, span = start + lo * step, (hi - lo) * step
    return sign * best, when, spacing


def mu_extremes(trajectory: Trajectory, rig: RigParameters, rtol: float, start: int = 0) -> MuExtremes:
    """μ's extremes over samples start … end of `trajectory`, between samples included (see module)."""
    t = trajectory.time[start:]
    v = trajectory.relative_velocity[start:]
    mu = trajectory.friction_coefficient[start:]
    i_min, i_max = int(np.argmin(mu)), int(np.argmax(mu))
    low = (float(mu[i_min]), float(t[i_min]))
    high = (float(mu[i_max]), float(t[i_max]))
    sampled = (low[0], high[0])
    peak, minimum = friction_landmarks(rig.friction)
    a, b = np.abs(v[:-1]), np.abs(v[1:])
    flip = np.sign(v[:-1]) != np.sign(v[1:])
    candidates = flip.copy()
    if peak is not None:
        vp = peak.velocity
        candidates |= (a < vp) != (b < vp)
        candidates |= ((a >= vp) & (a < NEAR)) | ((b >= vp) & (b < NEAR))
    if minimum is not None:
        vm = minimum.velocity
        crossing = ((a < vm) != (b < vm)) & ~flip
        if crossing.any():
            value = float(friction_coefficient(vm, rig.friction))
            if value < low[0]:
                first = int(np.nonzero(crossing)[0][0])
                low = (value, float(t[first]))
    resolution = 0.0
    found = np.nonzero(candidates)[0]
    for k in found.tolist():
        state = (float(trajectory.displacement[start + k]), float(trajectory.velocity[start + k]))
        band = (float(trajectory.band_velocity[start + k]), float(trajectory.band_velocity[start + k + 1]))
        span = float(t[k + 1] - t[k])
        for sign in (1.0, -1.0):
            value, when, spacing = _refine(rig, rtol, state, band, float(t[k]), span, sign)
            resolution = spacing if resolution == 0.0 else min(resolution, spacing)
            if sign > 0 and value > high[0]:
                high = (value, when)
            if sign < 0 and value < low[0]:
                low = (value, when)
    return MuExtremes(low[0], high[0], low[1], high[1], sampled[0], sampled[1], int(found.size), resolution)
