"""The machine's floor for a 1 kHz loop: a bare deadline loop's late wake-ups, and host steal.

    .venv/bin/python -m lubrig_testkit.wakeup [SECONDS] [--priority P] [--no-latency-request]

A loop that does nothing but sleep to absolute deadlines 1 ms apart (clock_nanosleep,
TIMER_ABSTIME, CLOCK_MONOTONIC, as cyclictest does), under SCHED_FIFO P where allowed and with the
CPU wake-up latency request of the plant's loop (/dev/cpu_dma_latency 0), counts wake-ups more than
one period late. No Python loop can wake on time more often than this one on the same machine at
the same time: it is what the plant's deadline misses are compared with (bench/bench_realtime.py
runs it beside the rig, one priority below the plant's loop). Beside it, the share of CPU time the
hypervisor gave to other guests ("steal", /proc/stat) in the same interval: on a VM a vCPU that
is not running cannot wake anything on time.

Prints one JSON object: ticks, late (> 1 period), late_half (> 0.5 period), worst_s, p99_s,
steal_share, fifo (whether SCHED_FIFO took), latency_request, and late_ticks: [due time on the
system clock (ns, as a realtime node's stamps), lateness (ns)] of every late tick (at most 10,000).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import sys
import time

PERIOD_NS = 1_000_000
CLOCK_MONOTONIC = 1
TIMER_ABSTIME = 1


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


def steal_and_total() -> tuple[int, int]:
    """(steal, all) jiffies of all CPUs from /proc/stat (0, 0 where it cannot be read)."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            fields = [int(v) for v in f.readline().split()[1:]]
    except (OSError, ValueError):
        return 0, 0
    steal = fields[7] if len(fields) > 7 else 0
    return steal, sum(fields[:8])


def measure(seconds: float, priority: int, latency_request: bool) -> dict[str, object]:
    """Run the bare loop for `seconds` (see the module docstring)."""
    fifo = False
    if priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            fifo = True
        except (PermissionError, OSError):
            pass
    held = None
    if latency_request:
        try:
            held = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
            os.write(held, (0).to_bytes(4, sys.byteorder))
        except OSError:
            held = None
    libc = ctypes.CDLL(None, use_errno=True)
    sleep = libc.clock_nanosleep
    ts = _Timespec()
    n = max(1, int(seconds * 1e9 / PERIOD_NS))
    lateness = [0] * n
    steal0, total0 = steal_and_total()
    to_system = time.time_ns() - time.monotonic_ns()
    due = time.monotonic_ns()
    for i in range(n):
        due += PERIOD_NS
        ts.tv_sec, ts.tv_nsec = divmod(due, 1_000_000_000)
        sleep(CLOCK_MONOTONIC, TIMER_ABSTIME, ctypes.byref(ts), None)
        lateness[i] = time.monotonic_ns() - due
    steal1, total1 = steal_and_total()
    start = due - n * PERIOD_NS + to_system
    late_ticks = [[start + (i + 1) * PERIOD_NS, v] for i, v in enumerate(lateness) if v > PERIOD_NS][:10_000]
    lateness.sort()
    return {
        "ticks": n,
        "late": sum(1 for v in lateness if v > PERIOD_NS),
        "late_half": sum(1 for v in lateness if v > PERIOD_NS // 2),
        "worst_s": lateness[-1] * 1e-9,
        "p99_s": lateness[min(n - 1, int(0.99 * n))] * 1e-9,
        "steal_share": (steal1 - steal0) / (total1 - total0) if total1 > total0 else None,
        "fifo": fifo,
        "latency_request": held is not None,
        "late_ticks": late_ticks,
    }


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("seconds", nargs="?", type=float, default=10.0, help="how long, s (default 10)")
    p.add_argument("--priority", type=int, default=80, help="SCHED_FIFO priority, 0: normal (default 80)")
    p.add_argument("--no-latency-request", dest="latency", action="store_false")
    args = p.parse_args(argv)
    if not args.seconds > 0:
        p.error(f"seconds {args.seconds}: expected > 0")
    print(json.dumps(measure(args.seconds, args.priority, args.latency)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
