"""Friction coefficient μ(v), its analytic slope dμ/dv and its landmarks, for any friction law.

The law is the one the parameter set belongs to (core.friction_laws): FrictionParameters (the
default, junction kinetics: core.junction; see docs/model.md) or another registered law's
parameters (e.g. core.stribeck.StribeckParameters). The public functions are vectorized over numpy
arrays; the scalar kernels are compiled with numba and reach the integrator through core.kernels.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from .friction_laws import CurveLandmark, FrictionLaw, law_for
from .params import FrictionParameters, ParameterError

__all__ = [
    "CurveLandmark",
    "friction_coefficient",
    "friction_landmarks",
    "friction_law",
    "friction_minimum",
    "friction_peak",
    "friction_slope",
    "stick_velocity",
    "stick_velocity_or_none",
]


def friction_law(params: Any | None = None) -> FrictionLaw:
    """The law of a parameter set (None: the default junction-kinetics parameters)."""
    return law_for(params if params is not None else FrictionParameters())


def _evaluate(velocity: np.typing.ArrayLike, params: Any | None) -> tuple[np.ndarray, np.ndarray]:
    params = params if params is not None else FrictionParameters()
    v = np.asarray(velocity, dtype=np.float64)
    if not np.isfinite(v).all():
        bad = v[~np.isfinite(v)].flat[0]
        what = "NaN" if np.isnan(bad) else repr(float(bad))
        raise InputError(f"velocity contains {what}; expected finite sliding velocities in m/s")
    mu, dmu = law_for(params).evaluate(np.ascontiguousarray(v).ravel(), params)
    return mu.reshape(v.shape), dmu.reshape(v.shape)


def friction_coefficient(velocity: np.typing.ArrayLike, params: Any | None = None) -> np.ndarray:
    """μ at sliding velocity v (m/s), odd in v; returns an array of v's shape.

    Every finite double is a valid v (0 and subnormals included); ±inf and NaN raise ValueError.
    """
    return _evaluate(velocity, params)[0]


def friction_slope(velocity: np.typing.ArrayLike, params: Any | None = None) -> np.ndarray:
    """Analytic dμ/dv in s/m at sliding velocity v (m/s), even in v.

    Finite at every finite v ≠ 0; a law whose slope is unbounded at 0 (the junction law:
    dμ/dv ∝ |v|^k2 there) gives +inf at exactly v = 0.
    """
    return _evaluate(velocity, params)[1]


@functools.lru_cache(maxsize=64)
def _landmarks(params: Any) -> tuple[CurveLandmark | None, CurveLandmark | None]:
    law = law_for(params)
    peak = law.peak(params)
    return peak, (law.minimum(params) if peak is not None else None)


def friction_landmarks(params: Any | None = None) -> tuple[CurveLandmark | None, CurveLandmark | None]:
    """(peak, minimum) of μ for v > 0; each None where the law has none with these parameters.

    Cached per parameter set (frozen, hashable): the stability verdict asks for them often.
    """
    return _landmarks(params if params is not None else FrictionParameters())


def _missing(params: Any, what: str, low: str, high: str) -> ParameterError:
    law = law_for(params)
    return ParameterError(
        f"the {law.name} friction law has no {what} (no stationary point between {low} and {high}) "
        f"with these parameters ({law.describe(params)}): its zones are undefined"
    )


def friction_peak(params: Any | None = None) -> CurveLandmark:
    """Maximum of μ: end of zone 1 (rising, stable) and start of zone 2 (falling).

    ParameterError when the law has no peak with these parameters (see friction_landmarks).
    """
    params = params if params is not None else FrictionParameters()
    peak = friction_landmarks(params)[0]
    if peak is None:
        if isinstance(params, FrictionParameters):
            v0 = params.critical_velocity
            raise _missing(params, "friction peak", f"{1e-2 * v0:.3g}", f"{1e2 * v0:.3g} m/s")
        raise _missing(params, "friction peak", "its rising and", "falling branch")
    return peak


def friction_minimum(params: Any | None = None) -> CurveLandmark:
    """Minimum of μ: end of zone 2 and start of zone 3 (rising again, viscous).

    ParameterError when the law has no minimum (or no peak) with these parameters.
    """
    params = params if params is not None else FrictionParameters()
    peak = friction_peak(params)
    minimum = friction_landmarks(params)[1]
    if minimum is None:
        raise _missing(params, "friction minimum", f"{10.0 * peak.velocity:.3g}", "1e-2 m/s")
    return minimum


def stick_velocity(params: Any | None = None) -> float:
    """|v_rel| (m/s) below which the interface sticks: the velocity of the friction peak.

    Below it μ rises with velocity (zone 1, junction stretching), so the interface acts as static
    friction. One definition for the run summaries and the online stick flags. ParameterError
    when the law has no peak (see stick_velocity_or_none).
    """
    return friction_peak(params).velocity


def stick_velocity_or_none(params: Any | None = None) -> float | None:
    """stick_velocity, or None when the law has no friction peak with these parameters."""
    peak = friction_landmarks(params)[0]
    return None if peak is None else peak.velocity
