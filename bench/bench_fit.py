"""`lubrig fit`'s speed: a five-parameter fit of 20 s of 1 kHz data (issue 23: under a minute).

The record: study case 7 (paper convention, band at 10 Hz) from the independent reference rig
(lubrig_testkit.measured: scipy LSODA) with ζ = 0.012, f0 = 10.3 Hz, G = 4.1e6 Pa, η_ref = 950 Pa·s
and γ = 1/ω0 of that f0, 1 % noise on x and μ. The fit starts from the study's defaults and frees
damping_ratio, natural_frequency, velocity_coupling, shear_modulus and reference_viscosity.
Prints the wall time of the fit (the reference integration is not counted), per worker count,
with each estimate's deviation from the truth in standard errors.

Run: .venv/bin/python bench/bench_fit.py [--workers 1 2] [--duration 20]
"""

from __future__ import annotations

import argparse
import math
import os

from lubrig_testkit.measured import noisy_record

from lubrig_ros.core.presets import load_case
from lubrig_ros.fit.data import checked
from lubrig_ros.fit.solve import fit

TRUTH = {
    "damping_ratio": 0.012,
    "natural_frequency": 10.3,
    "shear_modulus": 4.1e6,
    "reference_viscosity": 950.0,
}
FREE = ["damping_ratio", "natural_frequency", "velocity_coupling", "shear_modulus", "reference_viscosity"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--duration", type=float, default=20.0)
    args = parser.parse_args()
    config = load_case(7).with_overrides(duration=args.duration)
    data = checked(*noisy_record(config, TRUTH), "case 7 reference, 1 % noise")
    truth = {**TRUTH, "velocity_coupling": 1.0 / (2.0 * math.pi * TRUTH["natural_frequency"])}
    fit(data, config.with_overrides(duration=0.5), FREE[:1], max_evaluations=2)  # compile/load the kernels
    print(f"{data.time.size} samples, {len(FREE)} free parameters; load average {os.getloadavg()[0]:.2f}")
    for workers in args.workers:
        result = fit(data, config, FREE, workers=workers)
        print(
            f"workers {workers}: {result.wall_time:.1f} s wall, {result.evaluations} evaluations, "
            f"{result.jacobians} Jacobians, {result.segments} segments; {result.status}"
        )
        for name, value, error in zip(result.names, result.values, result.errors, strict=True):
            true = truth[name]
            print(
                f"  {name:22s} {value:.6g} ± {error:.2g} (truth {true:.6g}, {(value - true) / error:+.1f} SE)"
            )
        if result.undetermined:
            print(f"  undetermined: {result.undetermined}")
    print(f"load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
