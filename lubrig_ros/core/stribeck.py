"""A Stribeck-type friction law with a viscous term: the worked example of a second law.

    μ(v) = tanh(v / v_r) · [μ_c + (μ_s − μ_c) · exp(−(|v| / v_s)^δ)] + μ_v · v

* μ_s (static_coefficient) and μ_c (kinetic_coefficient): friction at the start of sliding and
  the Coulomb level it falls to; v_s (stribeck_velocity, m/s) and δ (stribeck_exponent) how fast;
* μ_v (viscous_coefficient, s/m): the viscous rise at high velocity;
* v_r (regularization_velocity, m/s): replaces the discontinuous sign(v) by tanh(v / v_r), so μ is
  odd, smooth, and has the finite slope μ_s / v_r + μ_v at v = 0 (the integrator needs a finite,
  if steep, slope; the junction law has an infinite one there and is handled the same way).

dμ/dv = sech²(v/v_r)/v_r · S(|v|) + tanh(|v|/v_r) · S'(|v|) + μ_v with S the bracket above and
S'(a) = −(μ_s − μ_c) δ (a/v_s)^δ exp(−(a/v_s)^δ) / a; even in v. For |v| ≪ v_s, v_r the slope is
μ_s/v_r + μ_v − (1 + δ)(μ_s − μ_c)(|v|/v_s)^δ / v_r: continuous at 0 for every δ > 0 (approached
like |v|^δ).

Defaults are chosen for this rig's range 1e-12 … 1e-5 m/s to resemble the junction law of the
study (docs/model.md): μ_s = 0.16 and μ_c = 0.006 (the junction law's peak ≈ 0.161 and minimum
≈ 0.0065), a decay spread over decades (δ = 0.5, v_s = 2e-9 m/s), μ_v = 1400 s/m so that
μ(1e-5 m/s) ≈ 0.02 as in the junction law, and v_r = 1e-12 m/s. With them (measured:
`python -c "from lubrig_ros.core.friction import friction_landmarks as f; from
lubrig_ros.core.stribeck import StribeckParameters as P; print(f(P()))"`) μ has its peak
0.153 at 3.25e-12 m/s (junction law: 0.161 at 4.08e-12 m/s) and its minimum 0.00623 at
1.32e-7 m/s (junction law: 0.00649 at 1.35e-7 m/s), so the study's band velocities
1e-7 … 1e-6 m/s lie on both sides of the minimum, as with the study's law.

Landmarks: found from the slope's sign on a log grid (core.friction_laws.KernelLaw); a law with
μ_s ≤ μ_c has no falling branch (no peak, no minimum) and with μ_v = 0 no minimum: the zones are
then undefined (None in summaries and flags, ParameterError from friction_peak/friction_zone).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from .friction_laws import KernelLaw, law_kernel, register_law
from .schema import NORMAL_FORCE, FieldSpec, field_table
from .validation import ParameterError, _check_finite, _check_positive

__all__ = ["Stribeck", "StribeckParameters", "stribeck_kernel"]


@dataclass(frozen=True)
class StribeckParameters:
    """Parameters of the Stribeck law (SI; fields in this order are its kernel's p).

    `ranges` are a rig's physical ranges (core/schema.py FieldSpec), which every run
    configuration is checked against; the dataclass itself asks only for values the formula
    can take (the linear stability analysis explores beyond a rig's ranges).
    """

    law: ClassVar[str] = "stribeck"
    ranges: ClassVar[dict[str, FieldSpec]] = field_table(
        FieldSpec("static_coefficient", "1", 0.0, 10.0, "static friction coefficient", "μ_s"),
        FieldSpec("kinetic_coefficient", "1", 0.0, 10.0, "kinetic (Coulomb) friction coefficient", "μ_c"),
        FieldSpec("stribeck_velocity", "m/s", 1e-15, 1.0, "Stribeck velocity", "v_s"),
        FieldSpec("stribeck_exponent", "1", 0.0, 10.0, "Stribeck exponent", "δ", low_open=True),
        FieldSpec("viscous_coefficient", "s/m", 0.0, 1e12, "viscous coefficient", "μ_v"),
        FieldSpec("regularization_velocity", "m/s", 1e-18, 1e-3, "regularization velocity near v = 0", "v_r"),
        NORMAL_FORCE,
    )

    static_coefficient: float = 0.16  # μ_s, ≥ 0
    kinetic_coefficient: float = 0.006  # μ_c, ≥ 0
    stribeck_velocity: float = 2e-9  # v_s, m/s, > 0
    stribeck_exponent: float = 0.5  # δ, in (0, 10]
    viscous_coefficient: float = 1400.0  # μ_v, s/m, ≥ 0
    regularization_velocity: float = 1e-12  # v_r, m/s, > 0
    normal_force: float = 1e-3  # N, N, > 0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("static_coefficient", "kinetic_coefficient", "viscous_coefficient"):
                number = _check_finite(f.name, value)
                if number < 0.0:
                    raise ParameterError(f"{f.name}={value!r} must be >= 0")
            elif f.name == "stribeck_exponent":
                number = _check_finite(f.name, value)
                if not 0.0 < number <= 10.0:
                    raise ParameterError(f"{f.name}={value!r} is outside the valid range (0, 10]")
            else:
                number = _check_positive(f.name, value)
            object.__setattr__(self, f.name, float(number))


@law_kernel
def stribeck_kernel(v: float, p: np.ndarray) -> tuple[float, float]:
    """μ(v) and dμ/dv for one velocity; p = the StribeckParameters fields as a float64 array."""
    mu_s, mu_c, v_s, delta, mu_v, v_r = p[0], p[1], p[2], p[3], p[4], p[5]
    if v == 0.0:
        return 0.0, mu_s / v_r + mu_v
    a = abs(v)
    x = a / v_r
    th = math.tanh(x)
    e2 = math.exp(-2.0 * x)
    sech2 = 4.0 * e2 / ((1.0 + e2) * (1.0 + e2))  # 1 − tanh², without its cancellation
    r = math.exp(delta * math.log(a / v_s))  # (a / v_s)^δ
    decay = math.exp(-r)
    bracket = mu_c + (mu_s - mu_c) * decay
    dbracket = -(mu_s - mu_c) * decay * delta * r / a
    mu = th * bracket
    if v < 0.0:
        mu = -mu
    return mu + mu_v * v, sech2 / v_r * bracket + th * dbracket + mu_v


class Stribeck(KernelLaw):
    """The Stribeck law: kernel above, landmarks by the generic slope scan."""

    name = "stribeck"
    parameters = StribeckParameters
    kernel = stribeck_kernel

    def describe(self, params: StribeckParameters) -> str:
        """The parameters that decide whether μ falls (peak) and rises again (minimum)."""
        return (
            f"static_coefficient={params.static_coefficient}, "
            f"kinetic_coefficient={params.kinetic_coefficient}, "
            f"viscous_coefficient={params.viscous_coefficient}"
        )


LAW = register_law(Stribeck())
