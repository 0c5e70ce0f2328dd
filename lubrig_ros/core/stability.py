"""Linear stability of the steady sliding equilibrium (Routh–Hurwitz on the linearized rig).

Linearizing m ẍ + c ẋ + k x = N μ(v_band − γ ẋ) about x0 = N μ(v_band)/k gives, in hyper-time,
x̃'' + (2ζ + ω0 γ N μ'(v_band)/k) x̃' + x̃ = 0 with the rig's velocity coupling γ
(RigParameters.velocity_factor: named convention or explicit), the same γ the integrator uses: the
equilibrium is stable exactly when that effective damping is positive.

The verdict needs only μ'(v_band) and so holds for every friction law; the zones need the law's
peak (and minimum): for a law without them the zone is None (friction_zone: ParameterError).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from .friction import friction_coefficient, friction_landmarks, friction_peak, friction_slope
from .params import RigParameters

ZONE_NAMES = {
    1: "zone 1 (rising friction, junction stretching: stable)",
    2: "zone 2 (falling friction: unstable unless damped enough)",
    3: "zone 3 (rising friction, viscous: stable)",
}


@dataclass(frozen=True)
class LinearStability:
    """Linear verdict at one band velocity."""

    band_velocity: float  # m/s
    zone: int | None  # 1, 2 or 3; None when the friction law has no peak (zones undefined)
    friction_coefficient: float
    friction_slope: float  # dμ/dv, s/m
    equilibrium_displacement: float  # x0, m
    effective_damping: float  # 2ζ + ω0 γ N μ'/k (hyper-time damping coefficient)
    critical_damping_ratio: float  # ζ_crit ≥ 0: stable iff ζ > ζ_crit
    stable: bool


def _coupling(rig: RigParameters) -> float:
    """ω0 γ N / k: multiplies μ' in the effective damping."""
    coupling: float = rig.angular_frequency * rig.velocity_factor * rig.friction.normal_force / rig.stiffness
    return coupling


def _effective(damping_ratio: float | np.ndarray, rig: RigParameters, slope: float | np.ndarray) -> Any:
    """Hyper-time damping coefficient 2ζ + ω0 γ N μ'/k of the linearized rig."""
    return 2.0 * damping_ratio + _coupling(rig) * slope


def _critical(rig: RigParameters, slope: float | np.ndarray) -> Any:
    """ζ_crit = max(0, −ω0 γ N μ'/(2k)) for dμ/dv = slope."""
    return np.maximum(0.0, -_coupling(rig) * slope / 2.0)


def equilibrium_displacement(band_velocity: np.typing.ArrayLike, rig: RigParameters) -> np.ndarray:
    """Static equilibrium x0 = μ(v_band) N / k in m."""
    mu = friction_coefficient(band_velocity, rig.friction)
    x0: np.ndarray = mu * rig.friction.normal_force / rig.stiffness
    return x0


def friction_zone(band_velocity: np.typing.ArrayLike, rig: RigParameters) -> np.ndarray:
    """Zone 1, 2 or 3 of |v_band| relative to the peak and minimum of μ (integer array).

    A law with a peak but no minimum has no zone 3; one without a peak has no zones
    (ParameterError naming the law and its parameters).
    """
    v = np.abs(np.asarray(band_velocity, dtype=float))
    peak = friction_peak(rig.friction)  # ParameterError saying why when the law has none
    minimum = friction_landmarks(rig.friction)[1]
    upper = math.inf if minimum is None else minimum.velocity
    return np.where(v < peak.velocity, 1, np.where(v < upper, 2, 3))


def critical_damping_ratio(band_velocity: np.typing.ArrayLike, rig: RigParameters) -> np.ndarray:
    """ζ_crit(v_band) = max(0, −ω0 γ N μ'/(2k)): damping above it stabilizes the equilibrium."""
    zeta_crit: np.ndarray = _critical(rig, friction_slope(band_velocity, rig.friction))
    return zeta_crit


def linear_stability(band_velocity: float, rig: RigParameters) -> LinearStability:
    """Routh–Hurwitz verdict for a constant band velocity (m/s)."""
    v = float(band_velocity)
    if not np.isfinite(v) or v <= 0.0:
        raise InputError(f"band_velocity={band_velocity!r} must be a finite velocity > 0 m/s")
    mu = float(friction_coefficient(v, rig.friction))
    slope = float(friction_slope(v, rig.friction))
    effective = float(_effective(rig.damping_ratio, rig, slope))
    has_zones = friction_landmarks(rig.friction)[0] is not None
    return LinearStability(
        band_velocity=v,
        zone=int(friction_zone(v, rig)) if has_zones else None,
        friction_coefficient=mu,
        friction_slope=slope,
        equilibrium_displacement=mu * rig.friction.normal_force / rig.stiffness,
        effective_damping=effective,
        critical_damping_ratio=float(_critical(rig, slope)),
        stable=bool(effective > 0.0),
    )


def unstable_intervals(
    damping_ratio: float,
    rig: RigParameters,
    v_min: float = 1e-15,
    v_max: float = 1e-2,
    points_per_decade: int = 400,
) -> list[tuple[float, float]]:
    """Band-velocity intervals [lo, hi] (m/s) where the equilibrium is unstable at this ζ.

    Edges are located on a log grid and then refined by bisection on the effective damping.
    """
    if not np.isfinite(damping_ratio) or damping_ratio < 0:
        raise InputError(f"damping_ratio={damping_ratio!r} must be a finite number >= 0")
    rig = replace(rig, damping_ratio=damping_ratio)
    decades = np.log10(v_max) - np.log10(v_min)
    v = np.logspace(np.log10(v_min), np.log10(v_max), int(decades * points_per_decade) + 1)

    def effective(velocity: float | np.ndarray) -> np.ndarray:
        value: np.ndarray = _effective(damping_ratio, rig, friction_slope(velocity, rig.friction))
        return value

    unstable = effective(v) <= 0.0

    def refine(lo: float, hi: float) -> float:
        f_lo = float(effective(lo))
        for _ in range(80):
            mid = np.sqrt(lo * hi)
            f_mid = float(effective(mid))
            if (f_mid <= 0.0) == (f_lo <= 0.0):
                lo, f_lo = mid, f_mid
            else:
                hi = mid
        return float(np.sqrt(lo * hi))

    intervals: list[tuple[float, float]] = []
    start: float | None = float(v[0]) if unstable[0] else None
    for i in range(1, v.size):
        if unstable[i] and not unstable[i - 1]:
            start = refine(v[i - 1], v[i])
        elif not unstable[i] and unstable[i - 1]:
            intervals.append((start if start is not None else float(v[0]), refine(v[i - 1], v[i])))
            start = None
    if start is not None:
        intervals.append((start, float(v[-1])))
    return intervals


def stability_map(band_velocities: np.ndarray, damping_ratios: np.ndarray, rig: RigParameters) -> np.ndarray:
    """Boolean grid [ζ, v_band]: True where the equilibrium is linearly stable."""
    slope = friction_slope(np.asarray(band_velocities, dtype=float), rig.friction)
    zeta = np.asarray(damping_ratios, dtype=float)[:, None]
    stable: np.ndarray = _effective(zeta, rig, slope[None, :]) > 0.0
    return stable
