"""Recorded realtime runs: every published sample in the bag exactly once, first samples included.

    .venv/bin/python bench/bench_realtime_recording.py [--runs 20] [--duration 5] [--hogs N]

Each run is `lubrig rig --mode realtime --case 1 --duration D --no-report` on its own ROS domain.
Per run it prints the recorder's accounting of <ns>/state_block (samples, missing, duplicates,
declared skips) beside an independent reader's (mcap + mcap_ros2, decoding the schemas stored in
the file): the sample indices it finds, whether they start at 0, run without an undeclared gap and
hold no index twice, and whether both agree; then how many runs of all held every sample once.
A benchmark: it prints, it does not assert (the tests assert the same rule on single runs).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lubrig_testkit.harness import BIN, DomainLease, ros_env
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

TOPIC = "/lubrig/state_block"


def indices_in_bag(bag: Path) -> tuple[list[int], int]:
    """Sample indices of segment 0 in the bag's state_block messages (log order), and declared skips."""
    (path,) = bag.glob("*.mcap")
    indices: list[int] = []
    skipped = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, _channel, _message, msg in reader.iter_decoded_messages(topics=[TOPIC]):
            first, n = int(msg.first_sample_index), len(msg.displacement)
            indices.extend(range(first, first + n))
            skipped += int(getattr(msg, "skipped", 0))
    return indices, skipped


def one_run(k: int, duration: float, tmp: Path) -> dict[str, object]:
    run = tmp / f"run{k}"
    with DomainLease() as domain:
        env = ros_env(domain)
        started = time.monotonic()
        res = subprocess.run(
            [
                str(BIN / "lubrig"),
                "rig",
                "--case",
                "1",
                "--mode",
                "realtime",
                "--duration",
                str(duration),
                "--run-dir",
                str(run),
                "--no-report",
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    account = json.loads((run / "bag" / "accounting.json").read_text())["streams"][TOPIC]
    indices, skipped = indices_in_bag(run / "bag")
    unique = sorted(set(indices))
    span = (unique[-1] + 1) if unique else 0
    return {
        "exit": res.returncode,
        "wall_s": time.monotonic() - started,
        "recorder": account,
        "reader_samples": len(indices),
        "reader_unique": len(unique),
        "reader_first": unique[0] if unique else None,
        "reader_holes": span - len(unique) - skipped,  # indices neither recorded nor declared skipped
        "reader_skipped": skipped,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--duration", type=float, default=5.0, help="wall seconds per run (default 5)")
    parser.add_argument("--hogs", type=int, default=0, help="CPU hogs beside the runs (default 0)")
    args = parser.parse_args()
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    good = 0
    try:
        print(f"load average at start {os.getloadavg()}, {args.hogs} CPU hog(s)")
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.runs):
                r = one_run(k, args.duration, Path(tmp))
                acc = r["recorder"]
                assert isinstance(acc, dict)
                once = (
                    r["reader_first"] == 0
                    and r["reader_samples"] == r["reader_unique"] == acc["samples"]
                    and r["reader_holes"] == 0
                    and acc["missing"] == 0
                    and acc["duplicates"] == 0
                    and r["reader_skipped"] == acc["skipped"]
                )
                good += once
                print(
                    f"run {k + 1:2d}: exit {r['exit']}, {r['wall_s']:.1f} s wall; recorder "
                    f"{acc['samples']} samples, {acc['missing']} missing, {acc['duplicates']} "
                    f"duplicates, {acc['skipped']} declared skipped; reader {r['reader_samples']} "
                    f"samples ({r['reader_unique']} distinct) from index {r['reader_first']}, "
                    f"{r['reader_holes']} undeclared holes, {r['reader_skipped']} declared "
                    f"-> {'every sample once' if once else 'NOT every sample once'}",
                    flush=True,
                )
        print(f"{good} of {args.runs} runs held every published sample exactly once (target: 20 of 20)")
        print(f"load average at end {os.getloadavg()}")
    finally:
        for hog in hogs:
            hog.kill()


if __name__ == "__main__":
    main()
