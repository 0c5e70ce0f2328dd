"""A rig-in-the-loop input sequence: does one tick's integration block the plant's output?

    .venv/bin/python bench/bench_rig_in_loop_sequence.py [--hold 2.0]

The plant runs in rig_in_loop mode; this process publishes std_msgs/Float64 band velocity at
1 kHz (wall clock), 1e-7 -> -1e-7 -> 1e-7 -> 5e-324 -> 1e-7 m/s, each held for --hold s (the
sequence that once froze the plant's output for 2.8-6 s; CHANGELOG.md), and receives the plant's RigState
on <ns>/state. Printed per held value: states received, the longest wall-clock pause between two
received states and the most states received in one 10 ms window (a burst after a freeze). Plus
`uptime` before and after.
"""

from __future__ import annotations

import argparse
import itertools
import subprocess
import tempfile
import threading
import time
from pathlib import Path

from lubrig_testkit.harness import DomainLease, Probe, Processes, ros_env
from std_msgs.msg import Float64

from lubrig_interfaces.msg import RigState
from lubrig_ros.nodes import common

SEQUENCE = (1e-7, -1e-7, 1e-7, 5e-324, 1e-7)


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hold", type=float, default=2.0, help="seconds each value is held")
    args = p.parse_args()
    ns = common.DEFAULT_NAMESPACE
    print(f"before: {_uptime()}")
    with DomainLease() as domain, tempfile.TemporaryDirectory() as tmp:
        probe, procs = Probe(domain), Processes(ros_env(domain), Path(tmp))
        try:
            state = f"{ns}/state"
            probe.subscribe(state, RigState)
            arrivals = probe.times[state]  # receive times (monotonic), appended by the probe
            procs.node("plant", mode="rig_in_loop", diagnostics_period=0.5)
            pub = probe.publisher(f"{ns}/band_velocity", Float64, common.STREAM_QOS)
            if not probe.wait_for(lambda: len(arrivals) > 200 and pub.get_subscription_count() > 0, 60):
                raise RuntimeError("plant did not start:\n" + procs.log("plant"))
            marks: list[float] = []

            def feed() -> None:
                msg, start, k = Float64(), time.perf_counter(), 0
                for value in SEQUENCE:
                    marks.append(time.monotonic())
                    msg.data = value
                    end = time.perf_counter() + args.hold
                    while time.perf_counter() < end:
                        k += 1
                        while time.perf_counter() < start + k * 1e-3:
                            time.sleep(0.0002)
                        pub.publish(msg)
                marks.append(time.monotonic())

            worker = threading.Thread(target=feed)
            worker.start()
            worker.join()
            time.sleep(0.5)
        finally:
            procs.stop_all()
            probe.close()
    print(f"after:  {_uptime()}")
    for value, t0, t1 in zip(SEQUENCE, marks, marks[1:], strict=False):
        got = [t for t in arrivals if t0 <= t < t1]
        pauses = [b - a for a, b in itertools.pairwise(got)]
        windows: dict[int, int] = {}
        for t in got:
            windows[int(t / 0.01)] = windows.get(int(t / 0.01), 0) + 1
        print(
            f"band {value:>9g} m/s for {t1 - t0:.2f} s: {len(got)} states, longest pause "
            f"{max(pauses, default=0.0) * 1e3:.1f} ms, most in 10 ms {max(windows.values(), default=0)}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
