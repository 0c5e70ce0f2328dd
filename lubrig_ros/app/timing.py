"""Timing for the real-time loops (no ROS): absolute-deadline sleeps and a latency histogram.

`DeadlineLoop` sleeps until each tick's absolute due time with clock_nanosleep(CLOCK_MONOTONIC,
TIMER_ABSTIME) — the clock of time.monotonic / time.perf_counter on Linux — and never spins: a
late wake-up is not followed by a second, shorter sleep that could oversleep again, and the
thread holds no CPU (nor the GIL: ctypes releases it) while it waits. The loop thread's timer
slack is set to 1 µs (prctl PR_SET_TIMERSLACK; Linux's default, 50 µs, is added to every
wake-up of a normal thread). Where clock_nanosleep is not available the loop falls back to
time.sleep of the remaining time (still no spinning).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import time

import numpy as np

_CLOCK_MONOTONIC = 1
_TIMER_ABSTIME = 1
_PR_SET_TIMERSLACK = 29
_EINTR = 4


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


def _libc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    except OSError:
        return None


_LIBC = _libc()
_NANOSLEEP = getattr(_LIBC, "clock_nanosleep", None) if os.name == "posix" else None


def sleep_until(due: float) -> None:
    """Sleep until time.monotonic() >= due (s), with one absolute-time sleep; return at once if past."""
    if _NANOSLEEP is None:
        remaining = due - time.monotonic()
        if remaining > 0.0:
            time.sleep(remaining)
        return
    frac, whole = math.modf(due)
    spec = _Timespec(int(whole), int(frac * 1e9))
    while _NANOSLEEP(_CLOCK_MONOTONIC, _TIMER_ABSTIME, ctypes.byref(spec), None) == _EINTR:
        pass  # a signal woke us early: sleep on to the same absolute time


def tight_timer_slack() -> bool:
    """Set the calling thread's timer slack to 1 ns..1 µs; True where the kernel took it."""
    if _LIBC is None or not hasattr(_LIBC, "prctl"):
        return False
    return int(_LIBC.prctl(_PR_SET_TIMERSLACK, 1000, 0, 0, 0)) == 0


class DeadlineLoop:
    """Ticks at absolute due times start + k · period (time.monotonic clock, s)."""

    def __init__(self, period: float, start: float | None = None) -> None:
        self.period = period
        self.start = time.monotonic() if start is None else start

    def deadline(self, k: int) -> float:
        """time.monotonic() time at which tick k is due."""
        return self.start + k * self.period

    def wait(self, k: int) -> float:
        """Sleep until tick k is due; return how late (s, >= 0) it is now."""
        due = self.deadline(k)
        sleep_until(due)
        return max(0.0, time.monotonic() - due)

    def due_index(self, now: float | None = None) -> int:
        """The newest tick index whose due time has passed at `now` (default: now)."""
        now = time.monotonic() if now is None else now
        return max(0, math.floor((now - self.start) / self.period))


class LatencyHistogram:
    """Latencies in fixed 10 µs bins up to 50 ms (plus an overflow bin).

    Adding is O(1) and a percentile costs one pass over 5,000 bins whatever the run length, so
    the memory and the cost of a diagnostics report stay flat over a run.
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
        return [float((np.searchsorted(cumulative, q / 100.0 * self.count) + 1) * self.BIN_S) for q in qs]
