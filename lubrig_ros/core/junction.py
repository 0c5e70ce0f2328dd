"""The junction-kinetics friction law (the study's, the default): compiled kernel, landmarks.

The law combines bonded junctions (elastic stress, stretched until thermal break or yield) and
free junctions (shear-thinning viscous stress); see docs/model.md. Parameters: core.params
.FrictionParameters (its fields, in order, are the kernel's p). The closed forms cancel
catastrophically for small u = v0/v and are replaced by series there; large u only underflows
exp(−u) to zero, so evaluation is stable over 1e-15 … 1e-2 m/s.

The helpers below are compiled into the kernel (inlined by numba), so they must stay in this file:
numba's on-disk cache of a function is keyed on its own source file only (see core.kernels).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .friction_laws import CurveLandmark, KernelLaw, register_law
from .kernels import law_kernel
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


@law_kernel
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
