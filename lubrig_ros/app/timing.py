"""Timing for the real-time loops (no ROS): absolute-deadline pacing and a latency histogram."""

from __future__ import annotations

import time

import numpy as np


class DeadlineLoop:
    """Absolute-deadline periodic loop: sleep most of the period, spin the last few 100 µs."""

    SPIN_S = 0.0003

    def __init__(self, period: float) -> None:
        self.period = period
        self.start = time.perf_counter()
        self.ticks = 0

    def deadline(self, k: int) -> float:
        """perf_counter time of tick k."""
        return self.start + k * self.period

    def wait(self, k: int) -> float:
        """Block until tick k is due; return how late (s) we are for it (≥ 0)."""
        due = self.deadline(k)
        while True:
            now = time.perf_counter()
            remaining = due - now
            if remaining <= 0.0:
                return -remaining
            if remaining > self.SPIN_S:
                time.sleep(remaining - self.SPIN_S)
            else:
                time.sleep(0)


class LatencyHistogram:
    """Latencies in fixed 10 µs bins up to 50 ms (plus an overflow bin).

    Adding is O(1) and a percentile costs one pass over 5,000 bins, whatever the run length: a
    list of every sample made each diagnostics report hold the GIL for ~11 ms after 200 s at 1 kHz,
    long enough to make the real-time loop miss ~11 deadlines.
    """

    BIN_S = 1e-5
    BINS = 5000

    def __init__(self) -> None:
        self.counts = np.zeros(self.BINS + 1, dtype=np.int64)
        self.count = 0

    def add(self, seconds: float) -> None:
        """Record one latency (negative values count as 0)."""
        self.counts[min(max(int(seconds / self.BIN_S), 0), self.BINS)] += 1
        self.count += 1

    def percentiles(self, qs: tuple[float, ...] = (50.0, 99.0)) -> list[float]:
        """Upper bin edges at the given percentiles, s (0.0 each when empty)."""
        if self.count == 0:
            return [0.0 for _ in qs]
        cumulative = np.cumsum(self.counts)
        return [
            float((np.searchsorted(cumulative, q / 100.0 * self.count) + 1) * self.BIN_S) for q in qs
        ]
