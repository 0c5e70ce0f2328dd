"""Benchmark of the nodes over real DDS: realtime deadline misses, latency, what a probe receives.

    .venv/bin/python bench/bench_realtime.py [--duration 60] [--priority 0]

Realtime: plant + belt_drive (realtime, 1 kHz) + analysis for --duration s of wall time; the
figures are the plant's own diagnostics (deadline misses: ticks finished more than one period
after their deadline; latency: band message receive time → state publish time inside the plant).
--priority sets realtime_priority (SCHED_FIFO) of plant and belt_drive: the probe's count shows
what the rest of the machine still gets. Sim throughput: bench/bench_sim_rate.py.
Runs on its own ROS_DOMAIN_ID (leased like a test's), discovery on localhost; the process
harness is the tests' one (lubrig_testkit, installed by `make setup`).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from lubrig_testkit.harness import DomainLease, Probe, Processes, ros_env

from lubrig_interfaces.msg import RigState
from lubrig_ros.nodes import common


def _status(array: DiagnosticArray, name: str) -> dict[str, str]:
    for status in array.status:
        if status.name == name:
            return {kv.key: kv.value for kv in status.values}
    return {}


def bench_realtime(duration: float, tmp: Path, priority: int = 0) -> dict[str, str]:
    lease = DomainLease()
    probe, procs = Probe(lease.domain), Processes(ros_env(lease.domain), tmp / "realtime")
    try:
        probe.subscribe("/diagnostics", DiagnosticArray)
        procs.node("plant", mode="realtime", realtime_priority=priority)
        procs.node("belt_drive", mode="realtime", realtime_priority=priority)
        procs.node("analysis")
        timing = f"{common.DEFAULT_NAMESPACE}/state"
        probe.subscribe(timing, RigState)
        if not probe.wait_for(lambda: probe.messages[timing], 30):
            raise RuntimeError("plant did not start:\n" + procs.log("plant"))

        def plant_timing() -> dict[str, str]:
            for array in reversed(probe.messages["/diagnostics"]):
                values = _status(array, "/lubrig/plant: timing")
                if values:
                    return values
            return {}

        def analysis_up() -> bool:
            return any(
                status.name.startswith("/lubrig/analysis:")
                for array in probe.messages["/diagnostics"]
                for status in array.status
            )

        # steady state: the window opens once every node runs (analysis start-up costs CPU)
        if not probe.wait_for(analysis_up, 60):
            raise RuntimeError("analysis did not start:\n" + procs.log("analysis"))
        probe.messages["/diagnostics"].clear()
        probe.wait_for(lambda: plant_timing(), 5)
        first = plant_timing()
        probe.messages[timing].clear()
        time.sleep(duration)
        probe.messages["/diagnostics"].clear()
        probe.wait_for(lambda: plant_timing(), 5)
        values = plant_timing()
        values["window_samples"] = str(int(values["samples"]) - int(first["samples"]))
        values["window_misses"] = str(int(values["deadline_misses"]) - int(first["deadline_misses"]))
        values["probe_state_messages"] = str(len(probe.messages[timing]))
        return values
    finally:
        procs.stop_all()
        probe.close()
        lease.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="realtime run, s (default 60)")
    parser.add_argument("--priority", type=int, default=0,
                        help="realtime_priority of plant and belt_drive (default 0, the nodes' default)")
    args = parser.parse_args()
    os.environ["RCUTILS_LOGGING_BUFFERED_STREAM"] = "0"
    with tempfile.TemporaryDirectory() as tmp:
        values = bench_realtime(args.duration, Path(tmp), args.priority)
        print(f"realtime 1 kHz, {args.duration:g} s wall, plant + belt_drive + analysis:")
        samples = int(values.get("samples", "0"))
        misses = int(values.get("deadline_misses", "0"))
        w_samples, w_misses = int(values["window_samples"]), int(values["window_misses"])
        print(
            f"  steady window: plant ticks {w_samples}, deadline misses {w_misses}"
            f" ({100 * w_misses / max(w_samples, 1):.3f} %)   goal < 0.1 %"
        )
        print(
            f"  whole run incl. start-up: ticks {samples}, misses {misses}"
            f" ({100 * misses / max(samples, 1):.3f} %)"
        )
        print(
            f"  max lateness of a tick start (whole run) "
            f"{1e3 * float(values.get('max_lateness_s', 'nan')):.2f} ms"
        )
        print(
            f"  band->state latency in the plant: p50 {1e3 * float(values.get('latency_p50_s', 'nan')):.3f}"
            f" ms, p99 {1e3 * float(values.get('latency_p99_s', 'nan')):.3f} ms"
            f" ({values.get('latency_samples')} samples)"
        )
        print(f"  state messages seen by a probe process: {values.get('probe_state_messages')}")


if __name__ == "__main__":
    main()
