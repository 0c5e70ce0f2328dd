"""Cost and accuracy of the integrator's tolerance.

    .venv/bin/python bench/rtol_cost.py [RTOL ...] [--check]
    .venv/bin/python bench/rtol_cost.py --reference [RTOL ...]

Default mode: per rtol, the total simulate() time over 20 s runs of the ten cases in every named
convention (30 runs) and the slowest run; with --check also the largest pointwise displacement
difference from the kernel's own rtol 1e-13 run, relative to the range.

--reference: the choice of the default rtol. For a sliding case (study case 7, paper convention)
and a stick-slip case (case 6, physical convention), 20 s each, the largest pointwise displacement
error relative to the range against an independent reference (lubrig_testkit.reference_rig:
the model document's equations, scipy LSODA at rtol 1e-12) and the time of one run (best of 3),
for rtol 1e-6 … 1e-12 unless given.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from lubrig_ros.core.params import CONVENTIONS
from lubrig_ros.core.presets import RunConfig, load_case
from lubrig_ros.core.run import simulate

#: The cases of --reference: (name, case, convention).
REFERENCE_CASES = (("sliding", 7, "paper"), ("stick-slip", 6, "physical"))


def _timed(config: RunConfig, repeat: int = 1) -> tuple[np.ndarray, float]:
    best = np.inf
    for _ in range(repeat):
        started = time.perf_counter()
        x = simulate(config).displacement
        best = min(best, time.perf_counter() - started)
    return x, best


def against_reference(tolerances: list[float]) -> None:
    """Error against the independent reference and cost per rtol, for each REFERENCE_CASES."""
    from lubrig_testkit.reference_rig import reference_displacement

    for label, number, convention in REFERENCE_CASES:
        config = load_case(number).with_overrides(convention=convention, duration=20.0)
        run = simulate(config)  # also compiles / loads the kernel
        started = time.perf_counter()
        reference = reference_displacement(
            run.time, run.band_velocity, float(run.displacement[0]), config.rig.velocity_factor
        )
        print(f"{label} (case {number}, {convention}): reference in {time.perf_counter() - started:.1f} s")
        for rtol in tolerances:
            x, elapsed = _timed(config.with_overrides(rtol=rtol), repeat=3)
            error = float(np.max(np.abs(x - reference)) / np.ptp(reference))
            print(f"  rtol {rtol:g}: {elapsed * 1e3:7.1f} ms, max error / range {error:.2g}")


def over_all_cases(tolerances: list[float], check: bool) -> None:
    """Total and slowest time of the 30 runs per rtol (and the error against rtol 1e-13)."""
    configs = [
        load_case(n).with_overrides(convention=c, duration=20.0) for c in CONVENTIONS for n in range(1, 11)
    ]
    simulate(configs[0].with_overrides(duration=0.1))  # compile / load the kernels
    references = [simulate(c.with_overrides(rtol=1e-13)).displacement for c in configs] if check else []
    for rtol in tolerances:
        total, slowest, worst = 0.0, 0.0, 0.0
        for i, config in enumerate(configs):
            x, elapsed = _timed(config.with_overrides(rtol=rtol))
            total += elapsed
            slowest = max(slowest, elapsed)
            if check:
                worst = max(worst, float(np.max(np.abs(x - references[i])) / np.ptp(references[i])))
        extra = f", worst pointwise error / range {worst:.2g}" if check else ""
        print(f"rtol {rtol:g}: 30 runs of 20 s in {total:.2f} s (slowest {slowest:.2f} s){extra}")


def main(argv: list[str]) -> int:
    flags = {a for a in argv if a.startswith("--")}
    tolerances = [float(a) for a in argv if not a.startswith("--")]
    if "--reference" in flags:
        against_reference(tolerances or [10.0**-n for n in range(6, 13)])
    else:
        over_all_cases(tolerances or [1e-8, 1e-12], "--check" in flags)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
