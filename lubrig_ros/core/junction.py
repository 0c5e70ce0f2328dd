"""The junction-kinetics friction law (the study's, the default): compiled kernel, landmarks.

The law combines bonded junctions (elastic stress, stretched until thermal break or yield) and
free junctions (shear-thinning viscous stress); see docs/model.md. Parameters: core.params
.FrictionParameters (its fields, in order, are the kernel's p). The closed forms cancel
catastrophically for small u = v0/v and are replaced by series there; large u only underflows
exp(−u) to zero. At the ends of the double range (u above 746 or below 1e-100: v below ~2e-15 or
above ~1e88 m/s with the study's parameters) u², v/v_ref, v τ0 or dφ/dv · η would over- or
underflow, and the same law is evaluated in a rearranged form without them
(_scaled_mu_and_slope), so μ and dμ/dv are finite and accurate for every finite v ≠ 0; at v = 0,
μ = 0 and dμ/dv = +inf (unbounded, ∝ |v|^k2).

The helpers below are compiled into the kernel (inlined by numba), so they must stay in this file:
numba's on-disk cache of a function is keyed on its own source file only (see core.kernels).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .friction_laws import CurveLandmark, KernelLaw, law_kernel, register_law
from .params import FrictionParameters

# Below this u = v0/v the closed forms cancel catastrophically: use series instead.
_SERIES_U = 0.1
# Above this u, e^-u is 0 in double precision (it underflows below 4.9e-324 from u ≈ 745.1):
# B(u) = 0, r(u) = 1 and q(u) = 1 exactly, and u itself may be too large to square or be infinite.
_UNDERFLOW_U = 746.0
# Outside [_SMALL_U, _UNDERFLOW_U] (v above ~1e88 m/s or below ~2e-15 m/s for the study's
# parameters) μ and dμ/dv come from _scaled_mu_and_slope: the same law in overflow-free form.
_SMALL_U = 1e-100
_MIN_NORMAL = 2.2250738585072014e-308


@njit(cache=True)
def _bernoulli_ratio(u: float) -> float:
    """B(u) = u / (e^u − 1), B(0) = 1, B(∞) = 0."""
    if u < _SERIES_U:
        u2 = u * u
        u4 = u2 * u2
        return 1.0 - 0.5 * u + u2 / 12.0 - u4 / 720.0 + u4 * u2 / 30240.0 - u4 * u4 / 1209600.0
    if u > _UNDERFLOW_U:
        return 0.0
    e = math.exp(-u)
    return u * e / (-math.expm1(-u))


@njit(cache=True)
def _stretch_ratio(u: float) -> float:
    """r(u) = [1 − (1+u)e^−u] / (1 − e^−u) = 1 − B(u); s = v τ0 r(u)."""
    if u < _SERIES_U:
        u2 = u * u
        u4 = u2 * u2
        return u / 2.0 - u2 / 12.0 + u4 / 720.0 - u4 * u2 / 30240.0 + u4 * u4 / 1209600.0
    return 1.0 - _bernoulli_ratio(u)


@njit(cache=True)
def _stretch_slope_ratio(u: float) -> float:
    """q(u) = ds/dv / τ0 = 1 − u² e^−u / (1 − e^−u)², q(∞) = 1."""
    if u < _SERIES_U:
        u2 = u * u
        u4 = u2 * u2
        return u2 / 12.0 - u4 / 240.0 + u4 * u2 / 6048.0 - u4 * u4 / 172800.0 + u4 * u4 * u2 / 5322240.0
    if u > _UNDERFLOW_U:
        return 1.0
    e = math.exp(-u)
    m = -math.expm1(-u)
    return 1.0 - u * u * e / (m * m)


@njit(cache=True)
def _log_ratio(v: float, v_ref: float) -> float:
    """log(v / v_ref), also where the quotient over- or underflows (|v| beyond ~1e298 or ~1e-318)."""
    ratio = v / v_ref
    if _MIN_NORMAL <= ratio <= 1.7976931348623157e308:
        return math.log(ratio)
    return math.log(v) - math.log(v_ref)


@njit(cache=True)
def _scaled_mu_and_slope(v: float, p: np.ndarray) -> tuple[float, float]:
    """μ(v) and dμ/dv for v > 0, written so that no intermediate over- or underflows.

    The same law as mu_and_slope, rearranged: powers as exponentials of log(v / v_ref), the bonded
    fraction φ and 1 − φ as logistic functions of log(τ / <t_b>), s/v = τ0 r(u), and dφ/dv as
    v dφ/dv. Finite wherever the law's values are (every v > 0 for the study's parameters).
    """
    g_mod, thick, d_pen, l_star, tau0 = p[0], p[1], p[2], p[3], p[4]
    tau_ref, v_ref, k1, eta_ref, k2 = p[5], p[6], p[7], p[8], p[9]
    area, normal = p[10], p[11]
    u = (l_star / tau0) / v  # may overflow to inf (v subnormal) or be subnormal (v near 1e308)
    log_ratio = _log_ratio(v, v_ref)
    lifetime_ratio = -math.expm1(-u)  # <t_b> / τ0
    if lifetime_ratio >= _MIN_NORMAL:
        log_lifetime = math.log(tau0 * lifetime_ratio)
    else:  # u below the normal range: 1 − e^−u = u to double precision
        log_lifetime = math.log(l_star) - math.log(v)
    z = math.log(tau_ref) + k1 * log_ratio - log_lifetime  # log(τ / <t_b>)
    phi = 1.0 / (1.0 + math.exp(z))
    free = 1.0 / (1.0 + math.exp(-z))  # 1 − φ without its cancellation
    ratio = _stretch_ratio(u)
    stretch = l_star * (ratio / u) if u < 1.0 and u >= _MIN_NORMAL else v * tau0 * ratio
    if u < _MIN_NORMAL:
        stretch = 0.5 * l_star  # s → l*/2 as u → 0
    eta_v = eta_ref * v_ref * math.exp((1.0 + k2) * log_ratio)  # η v
    scale = area / normal
    elastic = g_mod / thick
    mu = scale * (elastic * phi * stretch + free * eta_v / d_pen)
    v_dphi = phi * free * (-_bernoulli_ratio(u) - k1)  # v dφ/dv
    viscous = (1.0 + k2) * free - v_dphi
    viscous_slope = 0.0 if viscous == 0.0 else eta_ref * math.exp(k2 * log_ratio) / d_pen * viscous
    dmu = scale * (elastic * tau0 * (v_dphi * ratio + phi * _stretch_slope_ratio(u)) + viscous_slope)
    return mu, dmu


@law_kernel
def mu_and_slope(v: float, p: np.ndarray) -> tuple[float, float]:
    """μ(v) and dμ/dv for one velocity; p is the law's pack(params): FrictionParameters' fields in order.

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
    if not _SMALL_U <= u <= _UNDERFLOW_U:
        mu, dmu = _scaled_mu_and_slope(v, p)
        return sign * mu, dmu
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


class JunctionKinetics(KernelLaw):
    """The study's law. Landmarks bracketed around v0 = l*/τ0 (peak) and above it (minimum)."""

    name = "junction_kinetics"
    parameters = FrictionParameters
    kernel = mu_and_slope

    def peak(self, params: FrictionParameters) -> CurveLandmark | None:
        """Maximum of μ between 1e-2 v0 and 1e2 v0 (None when the slope does not change sign)."""
        v0 = params.critical_velocity
        return self.landmark(params, 1e-2 * v0, 1e2 * v0)

    def minimum(self, params: FrictionParameters) -> CurveLandmark | None:
        """Minimum of μ between 10 × the peak velocity and 1e-2 m/s."""
        peak = self.peak(params)
        return None if peak is None else self.landmark(params, 10.0 * peak.velocity, 1e-2)

    def describe(self, params: FrictionParameters) -> str:
        """The parameters that decide whether μ has a peak and a minimum."""
        return (
            f"activation_exponent={params.activation_exponent}, "
            f"shear_thinning_exponent={params.shear_thinning_exponent}, "
            f"critical velocity {params.critical_velocity:.3g} m/s"
        )


LAW = register_law(JunctionKinetics())
