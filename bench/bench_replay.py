"""Replay pacing on the wall clock: timing error at --rate 1 and 2, and the stop latency in a gap.

    .venv/bin/python bench/bench_replay.py [--messages 300] [--step-ms 5]

A bag of --messages Float64 messages --step-ms apart is replayed into a separate listener process
(the tests' synthetic listener) at --rate 1 and --rate 2; the figures are the largest deviation of
a message's receive time from its ideal offset (first message as origin) and the span of the whole
replay against the ideal span. Then a bag with a 100 s gap is replayed at --rate 0.01 and SIGINT is
sent inside the gap: the figure is the time from the signal to the exit. These were test asserts
once (errors < 50 ms, span within 7 %, stop < 1.5 s); on a shared machine they are figures.
The process harness is the tests' one (lubrig_testkit, installed by `make setup`).
"""

from __future__ import annotations

import argparse
import json
import signal
import struct
import tempfile
import time
from pathlib import Path

from lubrig_testkit.harness import DomainLease, Processes, ros_env, wait_until

from lubrig_ros.bag import BagWriter

TOPIC = "/lubrig/displacement"


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def _bag(path: Path, times_ns: list[int]) -> Path:
    w = BagWriter(path, run_config="a: 1\n")
    for k, t in enumerate(times_ns):
        w.write(TOPIC, "std_msgs/msg/Float64", t, _f64(k))
    w.close()
    return path


def pacing(procs: Processes, bag: Path, n: int, step_s: float, rate: float, out: Path) -> tuple[float, float]:
    """(max timing error s, span s) of one replay of bag at rate."""
    listener = procs.module(
        "lubrig_testkit.synthetic",
        "listen",
        "--topics",
        TOPIC,
        "--count",
        str(n),
        "--timeout",
        "120",
        "--output",
        str(out),
    )
    listener.wait_for_output("listening")
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", str(rate), "--wait-for-subscribers", "60"
    )
    if replay.wait(timeout=300) != 0 or listener.wait(timeout=300) != 0:
        raise RuntimeError(replay.log() + listener.log())
    recv = [t for _name, t, _v in json.loads(out.read_text())]
    if len(recv) != n:
        raise RuntimeError(f"{len(recv)} of {n} messages received")
    offsets = [(t - recv[0]) / 1e9 for t in recv]
    errors = [abs(o - k * step_s / rate) for k, o in enumerate(offsets)]
    return max(errors), offsets[-1]


def stop_latency(procs: Processes, bag: Path) -> float:
    """Seconds from SIGINT to exit while replay waits in a 10^4 s gap."""
    replay = procs.module(
        "lubrig_ros.nodes.replay", str(bag), "--rate", "0.01", "--wait-for-subscribers", "0"
    )
    wait_until(lambda: "replay:" in replay.output(), 60, "replay started", alive=(replay,))
    time.sleep(1.0)  # inside the gap (the first message goes out at once)
    sent = time.monotonic()
    replay.stop(signal.SIGINT, timeout=30)
    return time.monotonic() - sent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=300)
    parser.add_argument("--step-ms", type=float, default=5.0)
    args = parser.parse_args()
    step_ns = round(args.step_ms * 1e6)
    with tempfile.TemporaryDirectory() as tmp, DomainLease() as domain:
        tmp_path = Path(tmp)
        procs = Processes(ros_env(domain), tmp_path / "logs")
        try:
            bag = _bag(tmp_path / "bag", [5_000_000_000 + k * step_ns for k in range(args.messages)])
            ideal = (args.messages - 1) * step_ns / 1e9
            print(
                f"replay of {args.messages} messages {args.step_ms:g} ms apart ({ideal:.3f} s of log time):"
            )
            for rate in (1.0, 2.0):
                error, span = pacing(
                    procs, bag, args.messages, step_ns / 1e9, rate, tmp_path / f"got{rate:g}.json"
                )
                print(
                    f"  --rate {rate:g}: span {span:.3f} s (ideal {ideal / rate:.3f} s), "
                    f"max timing error {error * 1e3:.1f} ms"
                )
            gap = _bag(tmp_path / "gap", [1_000_000_000, 101_000_000_000])
            print(f"  SIGINT inside a 10^4 s wait (--rate 0.01): exit after {stop_latency(procs, gap):.2f} s")
        finally:
            procs.stop_all()


if __name__ == "__main__":
    main()
