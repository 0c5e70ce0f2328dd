"""Recorder in realtime: share of the published RigState samples recorded, and the exact loss.

    .venv/bin/python bench/bench_recorder.py --seconds 30 --rate 1000 [--analysis] [--hog]

A separate publisher process (the tests' synthetic source, ``python -m lubrig_testkit.synthetic
publish --rate R``; lubrig_testkit is installed by `make setup`) publishes what the plant publishes
per sample in realtime mode: lubrig_interfaces/RigState on /lubrig/state and std_msgs/Float64 on
/lubrig/band_velocity, paced on the wall clock with no flow control, so what the recorder cannot
keep up with is lost. The recorder (separate process, real DDS, default topic selection) records
them; its accounting (sample_index per stream, app/recording/accounting.py) gives the samples recorded and
missing, cross-checked against the bag read back with rosbags.

--analysis: the analysis node runs beside it (realtime, reading /lubrig/state).
--hog: one CPU hog (``python3 -c 'while True: pass'``) runs for the whole measurement.
--scalars: the source also publishes the three optional Float64 scalar topics.
Prints `uptime` before and after, and the exit status of the recorder (1 = it reported a gap).
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lubrig_testkit.harness import DomainLease, Processes, ros_env

from lubrig_ros.bag import check_bag


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--workers", type=int, default=0)
    p.add_argument("--analysis", action="store_true", help="run the analysis node beside it")
    p.add_argument("--hog", action="store_true", help="one CPU hog during the measurement")
    p.add_argument("--scalars", action="store_true", help="also the Float64 scalar topics")
    args = p.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_recorder_"))
    bag = tmp / "bag"
    samples = round(args.seconds * args.rate)
    print(f"before: {_uptime()}")
    hog = None
    with DomainLease() as domain:
        procs = Processes(ros_env(domain), tmp / "logs")
        try:
            rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--workers", str(args.workers))
            rec.wait_for_output("recording", timeout=180)
            if args.analysis:
                procs.script("analysis", "--ros-args", "-p", "case:=1", "-p", "publish_period:=0.2")
            if args.hog:
                hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
            t0 = time.perf_counter()
            pub = procs.run_module(
                "lubrig_testkit.synthetic",
                "publish",
                "--rate",
                str(args.rate),
                "--samples",
                str(samples),
                *(["--scalars"] if args.scalars else []),
                "--wait-subscribers",
                "120",
                # after matching, let discovery finish on the recorder's side too, as a recorded
                # realtime `lubrig rig` does (belt_drive's start_delay 1.5 s): at 0.5 s a quiet-
                # machine run lost its first 571 samples while the analysis node was starting
                "--settle",
                "2",
                timeout=args.seconds * 4 + 180,
            )
            wall = time.perf_counter() - t0
            status = rec.stop(signal.SIGINT, timeout=120)
        finally:
            if hog is not None:
                hog.kill()
                hog.wait()
            procs.stop_all()
    print(f"after:  {_uptime()}")
    if pub.returncode != 0:
        print(pub.stdout, pub.stderr)
        return 1
    info = json.loads(pub.stdout.strip().splitlines()[-1])
    accounting = json.loads((bag / "accounting.json").read_text())
    counts = {t.name: t.count for t in check_bag(bag).topics}
    print(f"recorder: {rec.output().splitlines()[0]}  (exit {status})")
    print(
        f"published {samples} samples at {args.rate:g} Hz in {info['elapsed']:.2f} s "
        f"(publisher wall incl. discovery {wall:.1f} s); analysis {'on' if args.analysis else 'off'}, "
        f"hog {'on' if args.hog else 'off'}"
    )
    for topic, n in info["published"].items():
        got = counts.get(topic, 0)
        print(f"  {topic:<30} published {n:>7}  in bag {got:>7}  lost {n - got:>5}")
    state = accounting["streams"].get("/lubrig/state", {"samples": 0, "missing": 0, "gaps": []})
    published = info["published"]["/lubrig/state"]
    tail = published - (state["segments"]["0"]["last_index"] + 1 if state.get("segments") else 0)
    print(
        f"state: {state['samples']} of {published} samples recorded = "
        f"{100 * state['samples'] / published:.3f} %; recorder accounting: {state['missing']} missing "
        f"in {len(state['gaps'])} gaps, {max(tail, 0)} after the last recorded sample"
    )
    for line in accounting["problems"]:
        print(f"  recorder: {line}")
    shutil.rmtree(tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
