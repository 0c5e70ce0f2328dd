"""Recorder throughput: publisher at the rig's full output rate vs. messages in the bag.

    .venv/bin/python bench/bench_recorder.py --seconds 10 --rate 1000 [--workers N]

A separate publisher process publishes the six plant topics (displacement, velocity,
friction_coefficient, state, band_velocity, /clock) at --rate samples/s; the recorder (separate
process, real DDS) records them; the bag is then read back with rosbags and counted per topic.
The publisher is the tests' synthetic source, paced on the wall clock without flow control
(``python -m lubrig_testkit.synthetic publish --rate R``; lubrig_testkit is installed by
`make setup`), so what the recorder cannot keep up with is lost and counted here.
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

from lubrig_testkit.harness import DomainLease, Processes, ros_env

from lubrig_ros.bag import check_bag


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--workers", type=int, default=0)
    args = p.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_recorder_"))
    bag = tmp / "bag"
    samples = round(args.seconds * args.rate)
    with DomainLease() as domain:
        procs = Processes(ros_env(domain), tmp / "logs")
        try:
            rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--workers", str(args.workers))
            rec.wait_for_output("recording", timeout=60)
            t0 = time.perf_counter()
            pub = procs.run_module(
                "lubrig_testkit.synthetic", "publish", "--rate", str(args.rate), "--samples",
                str(samples), timeout=args.seconds * 3 + 60,
            )
            wall = time.perf_counter() - t0
            status = rec.stop(signal.SIGINT, timeout=60)
        finally:
            procs.stop_all()
    if pub.returncode != 0:
        print(pub.stdout, pub.stderr)
        return 1
    info = json.loads(pub.stdout.strip().splitlines()[-1])
    summary = check_bag(bag)
    counts = {t.name: t.count for t in summary.topics}
    print(f"recorder: {rec.output().splitlines()[0]}  (exit {status})")
    print(f"published {samples} samples at {args.rate:g} Hz in {info['elapsed']:.2f} s "
          f"(publisher wall incl. discovery {wall:.1f} s)")
    total_pub = total_bag = 0
    for topic, n in info["published"].items():
        got = counts.get(topic, 0)
        total_pub, total_bag = total_pub + n, total_bag + got
        print(f"  {topic:<30} published {n:>7}  in bag {got:>7}  lost {n - got:>5}")
    rate = total_pub / info["elapsed"]
    print(f"total: {total_bag} of {total_pub} messages recorded at {rate:.0f} msgs/s offered; "
          f"bag {sum(f.stat().st_size for f in bag.iterdir()) / 1e6:.2f} MB")
    shutil.rmtree(tmp)
    return 0 if total_bag == total_pub else 1


if __name__ == "__main__":
    sys.exit(main())
