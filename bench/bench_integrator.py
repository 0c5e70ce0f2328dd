"""Integrator speed: lubrig's Radau IIA kernel vs scipy solve_ivp(LSODA) on the same law in plain numpy.

Both integrate the same equation with the band velocity linear between 1 kHz samples; accuracy of
each is measured against a tight reference (scipy DOP853 at rtol 1e-13 for the non-stiff paper
convention, scipy Radau with analytic Jacobian at rtol 1e-11 for the stiff physical one).
Run: .venv/bin/python bench/bench_integrator.py [--duration 10] [--case 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

from lubrig_ros.core.friction import friction_slope
from lubrig_ros.core.params import FrictionParameters, RigParameters
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import integrator_for, simulate


def numpy_friction(v: float, p: FrictionParameters) -> float:
    """The friction law written directly in numpy (what a user without our kernel would write)."""
    sign = np.sign(v)
    v = np.abs(v)
    if v == 0.0:
        return 0.0
    u = p.critical_velocity / v
    lifetime = p.thermal_break_time * (-np.expm1(-u))
    ratio = 1.0 - u * np.exp(-u) / (-np.expm1(-u)) if u > 1e-3 else u / 2.0 - u * u / 12.0
    stretch = v * p.thermal_break_time * ratio
    tau = p.reference_activation_time * (v / p.reference_velocity) ** p.activation_exponent
    phi = lifetime / (lifetime + tau)
    eta = p.reference_viscosity * (v / p.reference_velocity) ** p.shear_thinning_exponent
    sigma = (
        p.shear_modulus * phi * stretch / p.interface_thickness
        + (1 - phi) * eta * v / p.interpenetration_thickness
    )
    return float(sign * p.contact_area / p.normal_force * sigma)


def scipy_run(
    rig: RigParameters, t_s: np.ndarray, v_s: np.ndarray, x0: float, method: str, rtol: float, jac: bool
):
    m, c, k, gamma = rig.mass, rig.damping, rig.stiffness, rig.velocity_factor
    normal = rig.friction.normal_force
    p = rig.friction

    def rhs(t, y):
        vb = np.interp(t, t_s, v_s)
        return [y[1], (normal * numpy_friction(vb - gamma * y[1], p) - c * y[1] - k * y[0]) / m]

    def jacobian(t, y):
        vb = np.interp(t, t_s, v_s)
        slope = float(friction_slope(vb - gamma * y[1], p))
        return [[0.0, 1.0], [-k / m, (-gamma * normal * slope - c) / m]]

    scale = 1e-2 * normal / k
    atol = [rtol * scale, rtol * scale * rig.angular_frequency]
    options = {"jac": jacobian} if jac else {}
    started = time.perf_counter()
    sol = solve_ivp(
        rhs, (t_s[0], t_s[-1]), [x0, 0.0], method=method, t_eval=t_s, rtol=rtol, atol=atol, **options
    )
    elapsed = time.perf_counter() - started
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol.y[0], elapsed, sol.nfev


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", type=int, default=1)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--convention", choices=("paper", "physical"), default="paper")
    parser.add_argument("--lsoda-rtol", type=float, default=1e-8)
    parser.add_argument("--rtol", type=float, default=1e-8, help="lubrig integrator tolerance")
    args = parser.parse_args()
    config = load_case(args.case).with_overrides(
        duration=args.duration, convention=args.convention, rtol=args.rtol
    )
    integ = integrator_for(config)
    x0 = integ.equilibrium_displacement * (1 + config.initial_perturbation)
    t_s = np.arange(config.samples + 1) / config.sample_rate
    v_s = config.band(t_s)

    simulate(config.with_overrides(duration=0.01))  # compile / load the numba cache
    repeats = 5
    started = time.perf_counter()
    for _ in range(repeats):
        ours = simulate(config)
    ours_time = (time.perf_counter() - started) / repeats

    stiff = args.convention == "physical"
    x_ref, ref_time, _ = scipy_run(
        config.rig, t_s, v_s, x0, "Radau" if stiff else "DOP853", 1e-11 if stiff else 1e-13, jac=stiff
    )
    span = np.ptp(x_ref)
    err_ours = np.max(np.abs(ours.displacement - x_ref)) / span
    print(f"case {args.case}, {args.convention} convention, {args.duration:g} s of rig time at 1 kHz output")
    print(f"  reference ({'Radau rtol 1e-11' if stiff else 'DOP853 rtol 1e-13'}): {ref_time:.2f} s")
    ours_label = f"lubrig Radau IIA (numba, rtol {config.rtol:g})"
    print(f"  {ours_label:42s} {ours_time * 1e3:8.2f} ms   max error / ptp(x) = {err_ours:.2e}")
    # LSODA at --lsoda-rtol, then tightened until it is as accurate as lubrig
    matched = None
    for n, rtol in enumerate((args.lsoda_rtol, 1e-9, 1e-10, 1e-11, 1e-12)):
        x_lsoda, lsoda_time, nfev = scipy_run(config.rig, t_s, v_s, x0, "LSODA", rtol, jac=False)
        err_lsoda = np.max(np.abs(x_lsoda - x_ref)) / span
        label = f"scipy LSODA (numpy law, rtol {rtol:g})"
        print(
            f"  {label:42s} {lsoda_time * 1e3:8.2f} ms   max error / ptp(x) = {err_lsoda:.2e}"
            f"  ({nfev} rhs)  cost ratio lubrig/LSODA = 1/{lsoda_time / ours_time:.1f}"
        )
        if err_lsoda <= err_ours:
            matched = (n, rtol, lsoda_time)
            break
    if matched is None:
        print("  LSODA did not reach lubrig's accuracy at rtol >= 1e-12")
    elif matched[0] == 0:
        print(
            f"  lubrig is LESS accurate than LSODA at rtol {matched[1]:g}: no equal-accuracy ratio;"
            " rerun with a tighter --rtol for lubrig"
        )
    else:
        print(
            f"  at equal accuracy (LSODA rtol {matched[1]:g}): lubrig costs 1/{matched[2] / ours_time:.1f}"
            " of LSODA (goal: at most 1/20)"
        )


if __name__ == "__main__":
    main()
