"""Cost of the default tolerance: 20 s runs of the ten cases in every named convention.

    .venv/bin/python bench/rtol_cost.py [RTOL ...]

Prints, per rtol, the total simulate() time over the 30 runs, the slowest run, and the largest
pointwise displacement difference from an rtol 1e-13 reference relative to the range (with --check).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from lubrig_ros.core.params import CONVENTIONS
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate


def main(argv: list[str]) -> int:
    check = "--check" in argv
    tolerances = [float(a) for a in argv if a != "--check"] or [1e-8, 1e-12]
    configs = [
        load_case(n).with_overrides(convention=c, duration=20.0) for c in CONVENTIONS for n in range(1, 11)
    ]
    simulate(configs[0].with_overrides(duration=0.1))  # compile / load the kernels
    references = [simulate(c.with_overrides(rtol=1e-13)).displacement for c in configs] if check else []
    for rtol in tolerances:
        total, slowest, worst = 0.0, 0.0, 0.0
        for i, config in enumerate(configs):
            started = time.perf_counter()
            x = simulate(config.with_overrides(rtol=rtol)).displacement
            elapsed = time.perf_counter() - started
            total += elapsed
            slowest = max(slowest, elapsed)
            if check:
                worst = max(worst, float(np.max(np.abs(x - references[i])) / np.ptp(references[i])))
        extra = f", worst pointwise error / range {worst:.2g}" if check else ""
        print(f"rtol {rtol:g}: 30 runs of 20 s in {total:.2f} s (slowest {slowest:.2f} s){extra}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
