"""An independent reference solution of the rig, for checking the project's integrator.

Written from /work/shared/model/lubricated-rig-model.md (sections 1 and 2), not from lubrig_ros:
the friction law in plain Python (complex arithmetic, so that dμ/dv comes from a complex step, a
derivative owing nothing to the project's analytic slope), the equation of motion
m ẍ + c ẋ + k x = N μ(v_band − γ ẋ) with the band linear between samples, integrated by scipy's
LSODA (a different method, step control and Newton from the project's Radau IIA kernel).

scipy's Radau is not used: on stick-slip it converges to the spurious zone-2 root of the stage
equations (docs/integrator.md) and ends half the displacement range off.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class ReferenceRig:
    """The study's rig and friction parameters (model document), SI units."""

    shear_modulus: float = 3.9e6
    interface_thickness: float = 4.25e-9
    interpenetration_thickness: float = 1e-10
    yield_distance: float = 1.6e-9
    thermal_break_time: float = 1000.0
    reference_activation_time: float = 18.0
    reference_velocity: float = 1e-10
    activation_exponent: float = -0.41
    reference_viscosity: float = 900.0
    shear_thinning_exponent: float = -0.62
    contact_area: float = 2.83e-10
    normal_force: float = 1e-3
    mass: float = 0.1
    natural_frequency: float = 10.0
    damping_ratio: float = 0.01

    @property
    def omega0(self) -> float:
        return 2.0 * math.pi * self.natural_frequency

    @property
    def stiffness(self) -> float:
        return self.mass * self.omega0**2

    @property
    def damping(self) -> float:
        return 2.0 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)

    def _mu_positive(self, v: complex) -> complex:
        """μ for Re v > 0; Taylor / Bernoulli series where 1 − e^−u and s(v) cancel (u < 0.1)."""
        tau0 = self.thermal_break_time
        u = (self.yield_distance / tau0) / v
        if abs(u) < 0.1:
            nested = 1 - u / 8 * (1 - u / 9)
            for n in (7, 6, 5, 4, 3, 2):
                nested = 1 - u / n * nested
            one_minus_e = u * nested  # 1 − e^−u to u^9 / 10!
            # [1 − (1+u) e^−u] / (1 − e^−u) = 1 − u / (e^u − 1) = 1 − Σ B_n u^n / n!
            ratio = u / 2 - u**2 / 12 + u**4 / 720 - u**6 / 30240 + u**8 / 1209600 - u**10 / 47900160
        else:
            one_minus_e = 1 - cmath.exp(-u)
            ratio = 1 - u * cmath.exp(-u) / one_minus_e
        bonded_lifetime = tau0 * one_minus_e
        stretch = v * tau0 * ratio
        log_v = cmath.log(v / self.reference_velocity)
        tau = self.reference_activation_time * cmath.exp(self.activation_exponent * log_v)
        phi = bonded_lifetime / (bonded_lifetime + tau)
        eta = self.reference_viscosity * cmath.exp(self.shear_thinning_exponent * log_v)
        sigma_el = self.shear_modulus * phi * stretch / self.interface_thickness
        sigma_visc = (1 - phi) * eta * v / self.interpenetration_thickness
        return self.contact_area / self.normal_force * (sigma_el + sigma_visc)

    def mu(self, v: float) -> float:
        """μ(v), odd, μ(0) = 0."""
        if v == 0.0:
            return 0.0
        return math.copysign(self._mu_positive(complex(abs(v), 0.0)).real, v)

    def slope(self, v: float) -> float:
        """dμ/dv by a complex step (exact to rounding, no cancellation); 1e300 at v = 0."""
        a = abs(v)
        if a == 0.0:
            return 1e300
        step = a * 1e-30
        return self._mu_positive(complex(a, step)).imag / step


def reference_displacement(
    time: np.ndarray,
    band: np.ndarray,
    x0: float,
    gamma: float,
    rig: ReferenceRig | None = None,
    rtol: float = 1e-12,
) -> np.ndarray:
    """x at every sample time of a run starting at (x0, ẋ = 0) (reference_state's x)."""
    return reference_state(time, band, x0, gamma, rig, rtol)[0]


def reference_state(
    time: np.ndarray,
    band: np.ndarray,
    x0: float,
    gamma: float,
    rig: ReferenceRig | None = None,
    rtol: float = 1e-12,
) -> tuple[np.ndarray, np.ndarray]:
    """(x, ẋ) at every sample time of a run starting at (x0, ẋ = 0), band linear between samples.

    LSODA at `rtol` with an absolute tolerance 1e-3 × rtol of the rig's length and velocity scales
    (1e-2 N/k and ω0 times it): at rtol 1e-12, 20 s of physical-convention stick-slip agree with
    rtol 1e-11 and with a 1000× looser atol within 4e-6 of the displacement range.
    """
    rig = rig or ReferenceRig()
    m, c, k, n = rig.mass, rig.damping, rig.stiffness, rig.normal_force

    def rhs(t: float, y: np.ndarray) -> list[float]:
        vb = float(np.interp(t, time, band))
        return [y[1], (n * rig.mu(vb - gamma * y[1]) - c * y[1] - k * y[0]) / m]

    def jacobian(t: float, y: np.ndarray) -> list[list[float]]:
        vb = float(np.interp(t, time, band))
        return [[0.0, 1.0], [-k / m, (-gamma * n * rig.slope(vb - gamma * y[1]) - c) / m]]

    length = 1e-2 * n / k
    atol = [1e-3 * rtol * length, 1e-3 * rtol * length * rig.omega0]
    # steps of at most one sample period: the band has a kink at every sample, and a step across
    # several of them can send LSODA's step control into a crawl (case 6, physical, 20 s: stuck
    # near t = 2.4236 s at about 3e-12 s per step on this machine kind, while 19 s ran in 1.6 s;
    # host-dependent, through the last bits of libm). With the bound: 20 s in 2.5 s of CPU.
    solution = solve_ivp(
        rhs,
        (time[0], time[-1]),
        [x0, 0.0],
        method="LSODA",
        t_eval=time,
        rtol=rtol,
        atol=atol,
        jac=jacobian,
        max_step=float(time[1] - time[0]),
    )
    if not solution.success:
        raise RuntimeError(f"reference integration failed: {solution.message}")
    return np.asarray(solution.y[0]), np.asarray(solution.y[1])
