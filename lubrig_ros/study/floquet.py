"""Case 8's period-doubling threshold: where the forced 20 Hz orbit's Floquet multiplier passes −1.

Case 8 drives the band at 20 Hz = 2 f0; the study's 10 Hz response needs the period-1 (20 Hz)
orbit to lose stability by period doubling. `period_doubling` computes the coupling s at which
that happens: the periodic orbit of the forced rig by shooting (Newton on the Poincaré map over one
band period, from a state settled over `settle` s of case 8 at the lowest s), its monodromy matrix
by central differences of the flow of the project's integrator, and the sign change of
det(I + M) over s by bisection, continuing the orbit from the nearest s already solved
(core/floquet.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core import floquet
from ..core.run import simulate
from .runs import study_configs

#: The case whose forced orbit is followed, and the settings of the computation.
CASE = 8
SETTLE = 4.0  # s of case 8 simulated at the lowest s for Newton's start
RTOL = 1e-13  # integrator tolerance of the flow (finite differences need it tight)
GRID_START, GRID_FACTOR, GRID_STOP = 0.02, 1.25, 0.2  # bracket search over s
S_RTOL = 1e-4  # relative width of the final bracket on s


@dataclass(frozen=True)
class PeriodDoubling:
    """The computed threshold with the multipliers on both sides."""

    threshold: float  # s where a multiplier is −1
    bracket: tuple[float, float]
    below: np.ndarray  # multipliers at bracket[0]
    above: np.ndarray  # multipliers at bracket[1]
    sampled: dict[float, np.ndarray]  # multipliers at every s solved (grid and bisection)

    def text(self) -> str:
        """One line for the page: the threshold and the multipliers bracketing it."""
        lo, hi = self.bracket
        return (
            f"s = {self.threshold:.4g} (multipliers {_pair(self.below)} at s = {lo:.5g}, "
            f"{_pair(self.above)} at s = {hi:.5g})"
        )


def _pair(values: np.ndarray) -> str:
    parts = [f"{v.real:.6f}" if abs(v.imag) < 1e-12 else f"{v:.6f}" for v in values]
    return "(" + ", ".join(parts) + ")"


class _Continuation:
    """orbit_at(s) with Newton started from the orbit of the nearest s already solved."""

    def __init__(self, settle: float, rtol: float) -> None:
        self.rtol = rtol
        self.settle = settle
        self.orbits: dict[float, floquet.Orbit] = {}

    def __call__(self, s: float) -> floquet.Orbit:
        config = study_configs(s, self.settle)[CASE]
        rig = config.rig
        fundamental = config.band.fundamental_hz
        if fundamental is None:
            raise floquet.ShootingError(f"case {CASE}'s band is not periodic")
        period = 1.0 / fundamental
        flow = floquet.rig_period_map(rig, config.band, period, config.sample_rate, self.rtol)
        if self.orbits:
            nearest = min(self.orbits, key=lambda known: abs(math.log(known / s)))
            start = self.orbits[nearest].state
        else:
            trajectory = simulate(config)  # the study's start, settled (ends on a period boundary)
            start = np.array([trajectory.displacement[-1], trajectory.velocity[-1]])
        orbit = floquet.periodic_orbit(flow, start, floquet.rig_scale(rig))
        self.orbits[s] = orbit
        return orbit


def period_doubling(settle: float = SETTLE, rtol: float = RTOL, s_rtol: float = S_RTOL) -> PeriodDoubling:
    """The coupling s where case 8's forced orbit period-doubles (see the module docstring)."""
    orbit_at = _Continuation(settle, rtol)
    s, previous = GRID_START, None
    while s <= GRID_STOP:
        if orbit_at(s).doubling_margin < 0.0:
            break
        previous, s = s, s * GRID_FACTOR
    else:
        raise floquet.ShootingError(
            f"no multiplier of case {CASE}'s orbit crosses −1 up to s = {GRID_STOP:g}"
        )
    if previous is None:
        raise floquet.ShootingError(f"case {CASE}'s orbit is already period-doubled at s = {GRID_START:g}")
    found = floquet.period_doubling_threshold(orbit_at, previous, s, rtol=s_rtol)
    return PeriodDoubling(
        found.parameter,
        found.bracket,
        found.below.multipliers,
        found.above.multipliers,
        {key: orbit.multipliers for key, orbit in sorted(orbit_at.orbits.items())},
    )
