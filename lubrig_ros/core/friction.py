"""Friction law μ(v) of the boundary-lubricated interface and its analytic slope dμ/dv.

The law combines bonded junctions (elastic stress, stretched until thermal break or yield) and
free junctions (shear-thinning viscous stress); see docs/model.md. The scalar kernels are compiled
with numba so that the integrator can call them; the public functions are vectorized over numpy
arrays. Evaluation is stable over 1e-15 … 1e-2 m/s: the small-u cancellations are replaced by
series, and large u only underflows exp(−u) to zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.optimize import brentq

from .params import FrictionParameters

# Below this u = v0/v the closed forms cancel catastrophically: use series instead.
_SERIES_U = 0.1


@njit(cache=True)
def _bernoulli_ratio(u: float) -> float:
    """B(u) = u / (e^u − 1), B(0) = 1."""
    if u < _SERIES_U:
        u2 = u * u
        return 1.0 - 0.5 * u + u2 / 12.0 - u2 * u2 / 720.0 + u2 * u2 * u2 / 30240.0
    e = math.exp(-u)
    return u * e / (-math.expm1(-u))


@njit(cache=True)
def _stretch_ratio(u: float) -> float:
    """r(u) = [1 − (1+u)e^−u] / (1 − e^−u) = 1 − B(u); s = v τ0 r(u)."""
    if u < _SERIES_U:
        u2 = u * u
        return u / 2.0 - u2 / 12.0 + u2 * u2 / 720.0 - u2 * u2 * u2 / 30240.0
    return 1.0 - _bernoulli_ratio(u)


@njit(cache=True)
def _stretch_slope_ratio(u: float) -> float:
    """q(u) = ds/dv / τ0 = 1 − u² e^−u / (1 − e^−u)²."""
    if u < _SERIES_U:
        u2 = u * u
        u4 = u2 * u2
        return u2 / 12.0 - u4 / 240.0 + u4 * u2 / 6048.0 - u4 * u4 / 172800.0
    e = math.exp(-u)
    m = -math.expm1(-u)
    return 1.0 - u * u * e / (m * m)


@njit(cache=True)
def mu_and_slope(v: float, p: np.ndarray) -> tuple[float, float]:
    """μ(v) and dμ/dv for one velocity; p is FrictionParameters.as_array() as float64 array.

    μ is odd and dμ/dv even; at v = 0 the slope is +inf (μ ∝ |v|^(1+k2) there).
    """
    if v == 0.0:
        return 0.0, math.inf
    sign = 1.0
    if v < 0.0:
        sign = -1.0
        v = -v
    g_mod, thick, d_pen, l_star, tau0 = p[0], p[1], p[2], p[3], p[4]
    tau_ref, v_ref, k1, eta_ref, k2 = p[5], p[6], p[7], p[8], p[9]
    area, normal = p[10], p[11]
    u = (l_star / tau0) / v
    lifetime = tau0 * (-math.expm1(-u))  # <t_b>
    stretch = v * tau0 * _stretch_ratio(u)  # s(v)
    log_ratio = math.log(v / v_ref)  # one log, two exp: cheaper than two powers
    tau = tau_ref * math.exp(k1 * log_ratio)  # τ(v)
    phi = lifetime / (lifetime + tau)  # bonded fraction
    eta = eta_ref * math.exp(k2 * log_ratio)
    scale = area / normal
    elastic = g_mod / thick
    mu = scale * (elastic * phi * stretch + (1.0 - phi) * eta * v / d_pen)
    dphi = phi * (1.0 - phi) * (-_bernoulli_ratio(u) - k1) / v
    dstretch = tau0 * _stretch_slope_ratio(u)
    dmu = scale * (
        elastic * (dphi * stretch + phi * dstretch)
        + (1.0 + k2) * (1.0 - phi) * eta / d_pen
        - dphi * eta * v / d_pen
    )
    return sign * mu, dmu


@njit(cache=True)
def _mu_and_slope_array(v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mu = np.empty(v.size)
    dmu = np.empty(v.size)
    flat = v.ravel()
    for i in range(flat.size):
        mu[i], dmu[i] = mu_and_slope(flat[i], p)
    return mu, dmu


def _params_array(params: FrictionParameters | None) -> np.ndarray:
    return np.asarray((params or FrictionParameters()).as_array(), dtype=np.float64)


def _evaluate(
    velocity: np.typing.ArrayLike, params: FrictionParameters | None
) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(velocity, dtype=np.float64)
    if np.isnan(v).any():
        raise ValueError("velocity contains NaN; expected finite sliding velocities in m/s")
    mu, dmu = _mu_and_slope_array(np.ascontiguousarray(v).ravel(), _params_array(params))
    return mu.reshape(v.shape), dmu.reshape(v.shape)


def friction_coefficient(
    velocity: np.typing.ArrayLike, params: FrictionParameters | None = None
) -> np.ndarray:
    """μ at sliding velocity v (m/s), odd in v; returns an array of v's shape."""
    return _evaluate(velocity, params)[0]


def friction_slope(
    velocity: np.typing.ArrayLike, params: FrictionParameters | None = None
) -> np.ndarray:
    """Analytic dμ/dv in s/m at sliding velocity v (m/s), even in v."""
    return _evaluate(velocity, params)[1]


@dataclass(frozen=True)
class CurveLandmark:
    """A stationary point of μ(v): where and how large."""

    velocity: float  # m/s
    mu: float


def _stationary_point(params: FrictionParameters, low: float, high: float) -> CurveLandmark:
    p = _params_array(params)

    def slope(log_v: float) -> float:
        return mu_and_slope(10.0**log_v, p)[1]

    log_v = brentq(slope, math.log10(low), math.log10(high), xtol=1e-14, rtol=1e-14)
    v = 10.0**log_v
    return CurveLandmark(velocity=v, mu=float(mu_and_slope(v, p)[0]))


def friction_peak(params: FrictionParameters | None = None) -> CurveLandmark:
    """Maximum of μ: end of zone 1 (rising, stable) and start of zone 2 (falling)."""
    params = params or FrictionParameters()
    v0 = params.critical_velocity
    return _stationary_point(params, 1e-2 * v0, 1e2 * v0)


def friction_minimum(params: FrictionParameters | None = None) -> CurveLandmark:
    """Minimum of μ: end of zone 2 and start of zone 3 (rising again, viscous)."""
    params = params or FrictionParameters()
    peak = friction_peak(params)
    return _stationary_point(params, 10.0 * peak.velocity, 1e-2)
