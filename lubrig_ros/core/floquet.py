"""Periodic orbits of a periodically forced rig and their Floquet multipliers, by shooting.

The Poincaré map P over one forcing period T takes the state z = (x, ẋ) at t0 to the state at
t0 + T. A periodic orbit of period T is a fixed point P(z*) = z*, found by Newton's method from a
settled state; the monodromy matrix M = ∂P/∂z at z* gives the Floquet multipliers (eigenvalues of
M). The orbit is stable while every multiplier lies inside the unit circle; a real multiplier
passing −1 is a period doubling (the orbit of period T loses stability to one of period 2T). In
2-D a multiplier equals −1 exactly when det(I + M) = 1 + tr M + det M vanishes, so the threshold of
a parameter is a sign change of that smooth function, located by Brent's method
(`period_doubling_threshold`).

M is computed by central finite differences of the flow (`monodromy`), not by integrating the
variational equations: the flow is then the very integrator the study runs (`rig_period_map`:
core.integrator.RigIntegrator restarted from z with the band samples of one period; same band
interpolation, same compiled law, same stick safeguards), with no second right-hand side to keep
consistent with it. The price is 2n flows per matrix (four periods in 2-D) and an error of about
rtol·|z|/h (h the difference step, here 1e-5 of the state's scale): with rtol 1e-13 about 1e-6 on
a multiplier, checked against the analytic multipliers exp(λT) of a linear oscillator driven
through the same integrator (test/test_floquet.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lubrig_ros.core.errors import InputError, LubrigError

#: A flow map: state at the section → state one period later.
Flow = Callable[[np.ndarray], np.ndarray]
#: Relative finite-difference step (of the state's scale) for the monodromy matrix.
FD_STEP = 1e-5


class ShootingError(LubrigError, RuntimeError):
    """Newton's method did not find a periodic orbit from the given start."""


@dataclass(frozen=True)
class Orbit:
    """A periodic orbit: its state on the section, monodromy matrix and multipliers."""

    state: np.ndarray  # z* = (x, ẋ) at the section
    monodromy: np.ndarray  # M = ∂P/∂z at z*
    iterations: int  # Newton iterations taken
    residual: float  # max |P(z*) − z*| / scale

    @property
    def multipliers(self) -> np.ndarray:
        """Floquet multipliers (eigenvalues of M), largest modulus first."""
        values = np.linalg.eigvals(self.monodromy)
        return values[np.argsort(-np.abs(values))]

    @property
    def doubling_margin(self) -> float:
        """det(I + M): > 0 with no real multiplier below −1 (for a stable orbit), 0 at a multiplier −1."""
        return doubling_margin(self.monodromy)


def doubling_margin(monodromy: np.ndarray) -> float:
    """det(I + M) = Π(1 + λ_i): changes sign when one real multiplier λ_i passes −1."""
    m = np.asarray(monodromy, dtype=float)
    return float(np.linalg.det(np.eye(m.shape[0]) + m))


def monodromy(flow: Flow, state: np.ndarray, scale: np.ndarray, step: float = FD_STEP) -> np.ndarray:
    """∂P/∂z at `state` by central differences, steps `step` × `scale` per component."""
    z = np.asarray(state, dtype=float)
    h = step * np.asarray(scale, dtype=float)
    columns = []
    for i in range(z.size):
        e = np.zeros_like(z)
        e[i] = h[i]
        columns.append((flow(z + e) - flow(z - e)) / (2.0 * h[i]))
    return np.column_stack(columns)


def periodic_orbit(
    flow: Flow,
    start: np.ndarray,
    scale: np.ndarray,
    tol: float = 1e-9,
    max_iterations: int = 30,
    step: float = FD_STEP,
) -> Orbit:
    """The fixed point of `flow` near `start` by Newton's method (Jacobian by `monodromy`).

    Converged when every component of P(z) − z is below tol × scale; the monodromy matrix is then
    computed once more at the converged state.
    """
    scale = np.asarray(scale, dtype=float)
    z = np.asarray(start, dtype=float).copy()
    for iteration in range(1, max_iterations + 1):
        defect = flow(z) - z
        residual = float(np.max(np.abs(defect) / scale))
        if not math.isfinite(residual):
            raise ShootingError(f"the flow is not finite from {z!r}")
        if residual < tol:
            m = monodromy(flow, z, scale, step)
            return Orbit(z, m, iteration - 1, residual)
        m = monodromy(flow, z, scale, step)
        z = z - np.linalg.solve(m - np.eye(z.size), defect)
    raise ShootingError(
        f"no periodic orbit within {max_iterations} Newton iterations (residual {residual:.3g} of scale)"
    )


@dataclass(frozen=True)
class Threshold:
    """Where a multiplier crosses −1 along a parameter, and the orbits bracketing it."""

    parameter: float
    below: Orbit  # the orbit at the bracket's end with det(I + M) > 0
    above: Orbit  # … and < 0
    bracket: tuple[float, float]  # final bracket of the parameter


def period_doubling_threshold(
    orbit_at: Callable[[float], Orbit], low: float, high: float, rtol: float = 1e-4
) -> Threshold:
    """The parameter in [low, high] where det(I + M) changes sign (a multiplier crosses −1).

    `orbit_at(p)` returns the periodic orbit at parameter p (its caller continues the orbit from
    the nearest one already found). Bisection on log p until the bracket is within rtol, the
    crossing then placed by linear interpolation of det(I + M) between the bracket's ends.
    """
    if not (0.0 < low < high):
        raise InputError(f"bracket [{low!r}, {high!r}] must satisfy 0 < low < high")
    lo_orbit, hi_orbit = orbit_at(low), orbit_at(high)
    f_lo, f_hi = lo_orbit.doubling_margin, hi_orbit.doubling_margin
    if not (f_lo > 0.0 > f_hi):
        raise InputError(
            f"no multiplier crosses −1 in [{low:g}, {high:g}]: det(I + M) = {f_lo:.3g} and {f_hi:.3g} "
            "(expected > 0 at low and < 0 at high)"
        )
    while high / low - 1.0 > rtol:
        mid = math.sqrt(low * high)
        orbit = orbit_at(mid)
        if orbit.doubling_margin > 0.0:
            low, lo_orbit, f_lo = mid, orbit, orbit.doubling_margin
        else:
            high, hi_orbit, f_hi = mid, orbit, orbit.doubling_margin
    crossing = low + (high - low) * f_lo / (f_lo - f_hi)
    return Threshold(crossing, lo_orbit, hi_orbit, (low, high))


# --- the rig's Poincaré map -----------------------------------------------------------------------


def rig_period_map(
    rig: object,
    band: Callable[[np.ndarray], np.ndarray],
    period: float,
    sample_rate: float,
    rtol: float,
    start_time: float = 0.0,
) -> Flow:
    """The rig's Poincaré map over one band period from `start_time`, with the project's integrator.

    The band is sampled at start_time + k / sample_rate (k = 1 … period·sample_rate, which must be
    a whole number of samples) and taken as linear between samples, as in every run; each call
    starts a fresh integrator at the given (x, ẋ), so the map is a deterministic function of it.
    """
    from .integrator import RigIntegrator

    count = period * sample_rate
    if not (math.isfinite(count) and count >= 1 and abs(count - round(count)) < 1e-9 * count):
        raise InputError(
            f"period {period!r} s is not a whole number of samples at {sample_rate!r} Hz "
            "(the section must fall on a sample)"
        )
    k = np.arange(1, round(count) + 1, dtype=float)
    samples = np.asarray(band(start_time + k / sample_rate), dtype=float)
    first = float(np.asarray(band(np.array([start_time])), dtype=float)[0])
    integrator = RigIntegrator(rig, first, sample_rate=sample_rate, rtol=rtol)  # type: ignore[arg-type]

    def flow(state: np.ndarray) -> np.ndarray:
        integrator.initial_displacement = float(state[0])
        integrator.initial_velocity = float(state[1])
        integrator.reset(first, time=start_time)
        end = integrator.advance(samples)
        return np.array([end.displacement[-1], end.velocity[-1]])

    return flow


def rig_scale(rig: object) -> np.ndarray:
    """State scale (m, m/s) of the rig for steps and tolerances: 1e-3 N/k and that × ω0."""
    length = 1e-3 * rig.normal_force / rig.stiffness  # type: ignore[attr-defined]
    return np.array([length, length * rig.angular_frequency])  # type: ignore[attr-defined]
