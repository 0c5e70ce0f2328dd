"""Friction law μ(v) of the boundary-lubricated interface and its analytic slope dμ/dv.

The law combines bonded junctions (elastic stress, stretched until thermal break or yield) and
free junctions (shear-thinning viscous stress); see docs/model.md. The scalar kernel is compiled
with numba (kernels.py) so that the integrator can call it; the public functions are vectorized over numpy
arrays. Evaluation is stable over 1e-15 … 1e-2 m/s: the small-u cancellations are replaced by
series, and large u only underflows exp(−u) to zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .kernels import _mu_and_slope_array, mu_and_slope
from .params import FrictionParameters, ParameterError


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

    a, b = math.log10(low), math.log10(high)
    if not slope(a) * slope(b) < 0.0:
        raise ParameterError(
            f"the friction law has no stationary point between {low:.3g} and {high:.3g} m/s with "
            f"these parameters (activation_exponent={params.activation_exponent}, "
            f"shear_thinning_exponent={params.shear_thinning_exponent}, "
            f"critical velocity {params.critical_velocity:.3g} m/s): its zones are undefined"
        )
    log_v = brentq(slope, a, b, xtol=1e-14, rtol=1e-14)
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


def stick_velocity(params: FrictionParameters | None = None) -> float:
    """|v_rel| (m/s) below which the interface sticks: the velocity of the friction peak.

    Below it μ rises with velocity (zone 1, junction stretching), so the interface acts as static
    friction. One definition for the run summaries and the online stick flags.
    """
    return friction_peak(params).velocity
