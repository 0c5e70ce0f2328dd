"""Process start-up: fresh `python -c 'import …; simulate 0.1 s'`, numba cache cleared (cold) or kept (warm).

Also reports whether the warm process loaded the compiled stepper from the cache (it must not
recompile). Run: .venv/bin/python bench/bench_startup.py [--repeat 3] [--law junction_kinetics|stribeck]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "lubrig_ros"

CHILD = """
import json, sys, time
t0 = time.perf_counter()
from lubrig_ros.core.presets import from_mapping
from lubrig_ros.core.run import simulate
from lubrig_ros.core.friction import friction_law
from lubrig_ros.core import kernels
config = from_mapping({"rig": {"friction": {"law": sys.argv[1]}}, "simulation": {"duration": 0.1}})
simulate(config)
stepper = kernels.specialize(friction_law(config.rig.friction).kernel)[0]
print(json.dumps({"seconds": time.perf_counter() - t0,
                  "stepper_from_cache": sum(stepper.stats.cache_hits.values()) > 0}))
"""


def clear_cache() -> None:
    for pattern in ("*.nbi", "*.nbc"):
        for path in PACKAGE.rglob(pattern):
            path.unlink()


def run(law: str) -> tuple[float, float, bool]:
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, law], capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    child = json.loads(done.stdout.strip().splitlines()[-1])
    return wall, child["seconds"], child["stepper_from_cache"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--law", default="junction_kinetics")
    args = parser.parse_args()
    for label in ("cold", "warm"):
        for _ in range(args.repeat):
            if label == "cold":
                clear_cache()
            wall, inside, cached = run(args.law)
            print(
                f"{label}: process {wall:6.2f} s (import + simulate {inside:6.2f} s), "
                f"stepper from cache: {cached}"
            )


if __name__ == "__main__":
    main()
